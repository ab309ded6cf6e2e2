"""The sampled impedance loop on a contact that blocks the tip within one sample (docs/assembly.md,
section 5): the force part of the held torque goes without the half-sample lead, and the blocked
loop's step-to-step root is 1 - mu, mu = (n^T M_d^-1 n) / (n^T Lambda^-1 n) along the blocked
direction n (Lambda the robot's natural inertia at the tip). Checked against the independent
numpy plant of test_assembly_control with a viscous wall on the tip's axial motion (the
regularised friction of a wedged peg at creep speed is such a damper, mu_f f_n / v_eps)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from deltafmi.physics import wrist as W
from deltafmi.physics.assembly import AssemblySettings, gains, initial_state, sample
from deltafmi.physics.assembly.program import make_program

from test_assembly_control import PLANT, T, law_for, measure

WALL = 2.0e5          # N s/m: c T / m ~ 14 for the tip's 14.6 kg axial natural mass: blocked within a sample
AXIS = np.array([0.0, 0.0, 1.0])


def _axial_mobility(x: np.ndarray) -> float:
    """n^T Lambda^-1 n for an axial force at the tip: the plant's tip acceleration per newton, at rest."""
    rest = x.copy()
    rest[12:] = 0.0

    def tip_acceleration(f):
        xd = PLANT.derivative(rest, (0.0,) * 3, (0.0,) * 3, f)
        eps = 1e-7  # the tip's velocity is linear in the rates: differentiate the position along them
        return (PLANT.tip(rest + eps * np.concatenate((xd[12:], np.zeros(12)))) - PLANT.tip(rest)) / eps
    return float(AXIS @ (tip_acceleration(tuple(AXIS)) - tip_acceleration((0.0, 0.0, 0.0))))


TIP0 = np.array([0.0, 0.0, -1.18])


def _blocked_loop(mass_axial: float, n: int) -> np.ndarray:
    """The axial wall force at n samples of the loop pushing the tip (reference 1 cm below it) into
    the viscous wall, from rest."""
    law, wrist = law_for(gains((5.0, 5.0, mass_axial), (300.0, 300.0, 1500.0), (0.02,) * 3, (1.0,) * 3), tilt=(0.0, 0.0))
    tip0 = TIP0
    x = PLANT.start(tip0, (0.0, 0.0, 0.0))
    settings = AssemblySettings(T, True, False)
    state = initial_state(tuple(tip0))
    program = make_program((0.0, 0.0, -1.2), (0.0, 0.0))
    r = tuple(tip0 - 0.01 * AXIS)
    forces = []

    def wall(s):
        v = (PLANT.tip(s + 1e-7 * np.concatenate((s[12:], np.zeros(12)))) - PLANT.tip(s)) / 1e-7
        return tuple(-WALL * (AXIS @ v) * AXIS)
    for k in range(n):
        f = wall(x)
        R = W.tool_rotation(x[9:12])
        ft = tuple(R.T @ np.asarray(f)) + (0.0, 0.0, 0.0)
        state = sample(law, wrist, settings, program, state, k * T, *measure(x), ft, r, (0.0,) * 3, (0.0,) * 3,
                       (0.0,) * 3, (0.0,) * 3, (0.0,) * 3)
        x = solve_ivp(lambda t, s: PLANT.derivative(s, state.u, state.tau, wall(s)), (0.0, T), x, method="RK45",
                      rtol=1e-7, atol=1e-10).y[:, -1]
        forces.append(f[2])
    return np.array(forces)


def test_a_blocked_tip_rings_at_one_minus_mu_from_sample_to_sample():
    # M_d chosen for mu = 1.8 against the tip's axial natural mass: between the 1.5 the half-sample
    # lead on the force would allow and the 2 the law allows without it
    mobility = _axial_mobility(PLANT.start(TIP0, (0.0, 0.0, 0.0)))
    mass = 1.0 / (1.8 * mobility)
    forces = _blocked_loop(mass, 32)
    # the alternating part (binomial second difference) shrinks by |1 - mu| per sample, sign flipping
    alt = forces[:-2] - 2.0 * forces[1:-1] + forces[2:]
    ratios = alt[11:28] / alt[10:27]
    print(f"natural axial mass {1 / mobility:.3f} kg, M_d {mass:.3f} kg: predicted root -0.8, "
          f"measured ratios median {np.median(ratios):.4f}, from {ratios.min():.4f} to {ratios.max():.4f}")
    assert np.all(ratios < 0.0)
    assert np.median(ratios) == pytest.approx(-0.8, abs=0.03)
    assert abs(alt[28]) < abs(alt[10])
