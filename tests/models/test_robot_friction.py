"""Coulomb friction of the robot's tool on the table (DeltaRobotContact: mu_s, mu_k, viscous), through
the real FMU and fmpy's CVODE, against closed forms.

The robot is made weightless (g = 0, servo torques 0) and rests its tool on the table pressed by
the wrist force f = (0, 0, -N); at T_PUSH the f input gains a sideways push F along x (an input
event). At the centre the wrist inertia is diag(m_x, m_x, m_z) (three-fold symmetry), so the push
does not load the normal spring: the normal force stays N. Statics and the slip's ODE then give

* F < mu_s N: the tool sticks, its tangential displacement 0 and the friction force -F;
* F > mu_s N: it slips, m_x v' = F - mu_k N - c v with m_x the wrist's apparent mass along x (the
  servo-coordinate model's 1 / (x^T Lambda^-1 x), tests/delta_reference.py, independent of the
  DAE): v = (F - mu_k N) / c (1 - exp(-c t / m_x)), the friction force -(mu_k N + c v);
* the push removed at speed v0: m_x v' = -mu_k N - c v stops it after (m_x / c) ln(1 + c v0 / (mu_k N)),
  and it sticks again (0 is inside the cone).

contact_friction.yaml (contact_slide with friction): the breakaway at mu_s fn, the slide at
constant speed resisted by mu_k fn + c v, which the impedance spring supplies (the lag).
"""
from __future__ import annotations

from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from deltafmi.physics import delta as d
from deltafmi.physics.delta import contact_kernels as ck
from deltafmi.physics.friction import SLIP_POSITIVE, STICK, FrictionParams
from deltafmi.physics.friction.law import slip_force, slip_force_direction
from test_robot_contact import run, scenario_variant, wrist_inertia_along
from test_robot_contact_kernels import plane_system

ROOT = Path(__file__).resolve().parents[2]
N, MU_S, MU_K = 40.0, 0.5, 0.4
T_PUSH, STOP = 0.5, 0.62  # s: the normal transient of the first touch has decayed by exp(-28) at T_PUSH
OUTPUTS = ["friction_mode", "mode", "friction_force[1]", "friction_force[2]", "fn", "z[1]", "z[2]", "z[3]",
           "zd[1]", "zd[2]"]


@pytest.fixture(scope="module")
def plant(build_fmu_from_src):
    return build_fmu_from_src("delta_robot_contact.py")


def press(plant: Path, push: float, viscous: float = 0.0, release: float | None = None, **start) -> np.ndarray:
    """The weightless robot pressed on the table with N, pushed along x by ``push`` from T_PUSH
    (to ``release``), from touching at rest (tip at the surface height)."""
    times = [(0.0, 0.0), (T_PUSH, 0.0), (T_PUSH, push)]
    if release is not None:
        times += [(release, push), (release, 0.0)]
    times.append((STOP, times[-1][1]))
    signals = np.array([(t, fx, 0.0, -N, 0.0, 0.0, 0.0) for t, fx in times],
                       dtype=[("time", float)] + [(f"{name}[{k}]", float) for name in "fu" for k in (1, 2, 3)])
    return fmpy.simulate_fmu(str(plant), fmi_type="ModelExchange", stop_time=STOP, output_interval=1e-3,
                             relative_tolerance=1e-12, input=signals, output=OUTPUTS,
                             start_values={"g": 0.0, "z0[3]": -1.05, "mu_s": MU_S, "mu_k": MU_K, "viscous": viscous,
                                           **start})


def test_plant_declares_friction_and_keeps_two_indicators(plant):
    assert validate_fmu(str(plant)) == []
    md = fmpy.read_model_description(str(plant))
    assert md.numberOfEventIndicators == 2  # the friction indicator is CONTACT's unused second one
    params = {v.name: v for v in md.modelVariables}
    assert {"friction_mode", "friction_force[3]"} <= set(params)
    assert [float(params[n].start) for n in ("mu_s", "mu_k", "viscous")] == [0.0, 0.0, 0.0]  # frictionless by default


def test_tool_sticks_below_the_static_limit(plant):
    F = 0.95 * MU_S * N
    r = press(plant, F)
    after = r["time"] >= T_PUSH  # from the sample before the push on
    pushed = r["time"] > T_PUSH
    assert np.all(r["friction_mode"][after] == STICK) and np.all(r["mode"][after] == 2)
    # the stick constraint is anchored where the tool stuck: its drift is the integrator's
    # (rtol 1e-10 on ~1 m coordinates), nothing of the push's size (a slip would move it by > 1e-4 m)
    assert np.max(np.abs(r["z[1]"][after] - r["z[1]"][after][0])) < 1e-9
    assert np.max(np.abs(r["z[2]"][after])) < 1e-9
    # statics: the plane holds the push exactly, and the normal force is the press (measured
    # 2e-14 and 1e-12: round-off and the decayed touch transient)
    np.testing.assert_allclose(r["friction_force[1]"][pushed], -F, rtol=1e-6)
    np.testing.assert_allclose(r["fn"][after], N, rtol=1e-6)


@pytest.mark.parametrize("c", [0.0, 30.0])
def test_tool_slips_above_the_static_limit_with_the_apparent_mass_and_sticks_again(plant, c):
    F, release = 1.05 * MU_S * N, 0.55
    r = press(plant, F, viscous=c, release=release)
    t, v, mode = r["time"], r["zd[1]"], r["friction_mode"]
    z = [r[f"z[{k}]"][np.flatnonzero(t >= T_PUSH)[0]] for k in (1, 2, 3)]
    m_x = wrist_inertia_along(d.RL5, z, (1.0, 0.0, 0.0))
    slip = (t > T_PUSH) & (t < release)
    assert np.all(mode[slip] == SLIP_POSITIVE)
    early = slip & (t <= T_PUSH + 0.02)
    tau = t[early] - T_PUSH
    drive = F - MU_K * N
    expected = drive * tau / m_x if c == 0.0 else drive / c * -np.expm1(-c * tau / m_x)
    # the closed form holds at the centre: off it (x < 0.15 mm after 20 ms) the wrist inertia
    # couples x to the normal spring, so fn (and with it the kinetic force) drifts by O(x / 1 m):
    # measured 5.8e-5 in fn and 4.9e-5 in v at 20 ms; CVODE at rtol 1e-12 adds ~1e-8. Bound 2e-4.
    np.testing.assert_allclose(v[early], expected, rtol=2e-4)
    # the slip law (magnitudes: off the centre the slip turns by ~1e-5 rad towards y)
    force = np.hypot(r["friction_force[1]"], r["friction_force[2]"])[slip]
    np.testing.assert_allclose(force, MU_K * r["fn"][slip] + c * np.hypot(v, r["zd[2]"])[slip], rtol=1e-12)
    assert np.all(r["friction_force[1]"][slip] < 0.0)
    np.testing.assert_allclose(r["fn"][early], N, rtol=2e-4)  # the coupling above
    # released at v0, kinetic friction (and the viscous term) stop it; then it sticks
    v0 = v[np.flatnonzero(t >= release)[0]]
    stop = t[np.flatnonzero((t > release) & (mode == STICK))[0]]
    expected_stop = m_x * v0 / (MU_K * N) if c == 0.0 else m_x / c * np.log1p(c * v0 / (MU_K * N))
    assert stop - release == pytest.approx(expected_stop, rel=1e-3)  # measured 8.5e-5 (the coupling)
    held = t > stop
    assert np.all(mode[held] == STICK) and np.max(np.abs(v[held])) < 1e-9


def test_kinetic_above_static_is_refused(plant, capfd):
    with pytest.raises(Exception):
        fmpy.simulate_fmu(str(plant), fmi_type="ModelExchange", stop_time=0.01,
                          start_values={"mu_s": 0.3, "mu_k": 0.4})
    assert "friction: the kinetic coefficient mu_k = 0.4 exceeds the static mu_s = 0.3" in "".join(capfd.readouterr())


def test_slide_under_impedance_control_needs_the_kinetic_force(tmp_path):
    """contact_friction.yaml: K = 5000 N/m along x, mu_s = 0.35, mu_k = 0.3, c = 20 N s/m. The stuck
    tool breaks away when the spring's pull reaches mu_s fn; sliding at the reference's 20 mm/s
    the plane resists with mu_k fn + c v, which the spring supplies: lag = (mu_k fn + c v) / K."""
    c = run(scenario_variant("contact_friction", tmp_path, stop=6.0))
    t, mode, fn = c["time"], c["plant.friction_mode"], c["plant.fn"]
    ft, v = c["plant.friction_force[1]"], c["plant.zd[1]"]
    K, mu_s, mu_k, visc = 5000.0, 0.35, 0.3, 20.0
    first_slip = np.flatnonzero(mode == SLIP_POSITIVE)[0]
    assert mode[first_slip - 1] == STICK and np.all(mode[first_slip:] == SLIP_POSITIVE)
    # the controller's torques are held for 1 ms, so the pull on the stuck tool rises in steps of
    # ~0.08 N: it breaks away at the communication point where the held pull jumps out of the
    # static cone (the rows there: before the jump inside, after it outside, then SLIP)
    at_breakaway = np.flatnonzero((t == t[first_slip]) & (mode == STICK))
    inside, outside = at_breakaway[0], at_breakaway[-1]
    assert -ft[inside] < mu_s * fn[inside] < -ft[outside] < mu_s * fn[outside] + 0.1
    assert t[first_slip] == pytest.approx(round(t[first_slip], 3), abs=1e-9)
    cruise = (t > 5.0) & (t < 6.0)
    np.testing.assert_allclose(v[cruise], 0.02, rtol=1e-4)  # the breakaway transient: 1.6e-5 left at 5 s
    np.testing.assert_allclose(-ft[cruise], mu_k * fn[cruise] + visc * v[cruise], rtol=1e-9)
    lag = c["trajectory.r[1]"][cruise] - c["plant.z[1]"][cruise]
    np.testing.assert_allclose(K * lag, mu_k * fn[cruise] + visc * v[cruise], rtol=1e-4)


# --- the kernels: the stick constraint's multiplier and the slip law ----------------------------

def frictional(rng, mode: int):
    """The tool pressed 1 mm into a tilted plane, moving along it, in CONTACT with ``mode``."""
    system, x = plane_system(rng)
    system.friction = FrictionParams(0.5, 0.4, 10.0)
    system.modes[:] = 2
    system.friction_mode, system.axis, system.anchor = mode, (0.6, -0.8), (0.003, -0.002)
    return system, x


@pytest.mark.parametrize("mode", [STICK, SLIP_POSITIVE])
def test_friction_kernels_keep_the_stick_constraint_and_the_slip_law(mode):
    system, x = frictional(np.random.default_rng(mode), mode)
    p, state, u, f = system.params, system.kernel_state(), system.model.u, system.model.f
    h, hdot, lam, vdot, _, _, (lt1, lt2, vt1, vt2) = ck.plane_evaluation(p, state, x, u, f)
    q, v = x[:9], x[9:]
    T = np.array(system.tangents)  # rows t1, t2
    # tangential acceleration from numpy kinematics: Jv v' + mean_i R_i (d/dt dpsi_i/dq) v_i
    bias = sum(r @ d.arm_bias(p, q[3 * i:3 * i + 3], v[3 * i:3 * i + 3]) for i, r in enumerate(d.ARM_ROTATIONS)) / 3.0
    acc = T @ (d.virtual_jacobian(p, q) @ np.array(vdot) + bias)
    speed, position = T @ d.virtual_jacobian(p, q) @ v, T @ d.wrist_position(p, q)
    np.testing.assert_allclose([vt1, vt2], speed, rtol=1e-12, atol=1e-15)
    if mode == STICK:  # s'' + 2 p s' + p^2 (s - anchor) = 0 with the robot's pole
        pole = system.model.pole
        residual = acc + 2.0 * pole * speed + pole ** 2 * (position - np.array(system.anchor))
        assert np.max(np.abs(residual)) < 1e-9 * np.max(np.abs(acc))
    else:  # the slip law of deltafmi.physics.friction.law
        e = slip_force_direction(speed, np.array(system.axis))
        np.testing.assert_allclose([lt1, lt2], slip_force(lam, speed, e, system.friction), rtol=1e-12)
