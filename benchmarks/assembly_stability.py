"""Sampled-data stability of the impedance loop on a stiff contact: the figures of docs/assembly.md,
section 5 (no timing; the numbers do not depend on the machine).

1. The wedge variant of scenarios/peg_in_hole.yaml (hole tilted 3 degrees, mu 0.5, the wrist held
   stiffly: rot_stiffness 500 N m/rad, inertia 0.05 kg m^2) is run through its FMUs to the
   instants listed, recording the plant's 24 states. At each, the sampled closed loop is
   linearised: the plant over one sample period by the matrix exponential of its Jacobian
   (zero-order hold, exact for the linear model; Jacobians by central differences of
   deltafmi.physics.peg.plant.state_derivative), the controller's sample
   (deltafmi.physics.assembly.sampling) by central differences; the state of the sampled map is
   the plant's, the law's previous motion torques (the lead's memory) and the previous tip (the
   push bound's). Its eigenvalue of largest modulus is printed for the held torque as main had it
   (the half-sample lead 1.5 u_k - 0.5 u_k-1 on the whole torque) and as it is now (the lead on
   the motion part only).
2. The robot's natural inertia at the tip there (Lambda, 6x6, from the plant's response to a unit
   tip force and couple) and mu = n^T M_d^-1 n / n^T Lambda^-1 n for a force blocked along the hole
   axis and sideways at the tip: the blocked loop's root 1 - mu.
3. One axis (the natural mass m, the law's force gain g = mu - 1, its spring and damper, a contact
   spring k with damper c, zero-order hold, the lead on the force or not): the largest root over
   the contact stiffnesses the shipped scenarios use (one rim point's 2e5 N/m up to a flat face's
   32 points) and the friction's regularised damping (mu_f f_n / v_eps, up to 0.5 * 60 N / 1 mm/s).

Usage: python benchmarks/assembly_stability.py [--at 3.5 5 9.5]
"""
from __future__ import annotations

import argparse
import math
from typing import Sequence

import numpy as np
import yaml
from scipy.linalg import expm

import deltafmi
from deltafmi.models import AssemblyController, DeltaWristPeg
from deltafmi.physics.assembly import sampling
from deltafmi.physics.delta_wrist.dynamics import state_derivative as wrist_derivative
from deltafmi.physics.peg import plant as peg_plant
from deltafmi.shipped import SCENARIOS_DIR

WEDGE = {"plant.mu": 0.5, "plant.hole_tilt": [0.0524, 0.0], "controller.rot_stiffness": [500.0] * 3,
         "controller.inertia": [0.05] * 3}
STATES = ([f"plant.q[{j}]" for j in range(1, 10)] + [f"plant.q_w[{j}]" for j in range(1, 4)]
          + [f"plant.v[{j}]" for j in range(1, 10)] + [f"plant.v_w[{j}]" for j in range(1, 4)])
ZERO = (0.0, 0.0, 0.0)


def _components(overrides: dict):
    """The scenario's plant and controller as Python components, initialised."""
    spec = yaml.safe_load((SCENARIOS_DIR / "peg_in_hole.yaml").read_text())["components"]
    plant, controller = DeltaWristPeg(), AssemblyController()
    for component, key in ((plant, "plant"), (controller, "controller")):
        component.setup()
        values = dict(spec[key]["parameters"])
        values.update({k.split(".", 1)[1]: v for k, v in overrides.items() if k.startswith(key + ".")})
        for name, value in values.items():
            if isinstance(value, (list, tuple)):
                getattr(component, name)[:] = value
            else:
                setattr(component, name, value)
    plant.initialize(0.0)
    controller.initialize(0.0)
    return plant, controller


def _jacobian(f, x0: np.ndarray, h: np.ndarray) -> np.ndarray:
    columns = []
    for j in range(len(x0)):
        e = np.zeros(len(x0))
        e[j] = h[j]
        columns.append((np.asarray(f(x0 + e)) - np.asarray(f(x0 - e))) / (2.0 * h[j]))
    return np.column_stack(columns)


class SampledLoop:
    """The closed loop's pieces at one state: plant derivative, sensor, controller sample."""

    def __init__(self, plant, controller) -> None:
        self.plant, self.controller = plant, controller
        self.args = (plant._plant, plant._wrist, plant._mount)
        self.scene = (plant._hole, plant._peg, plant._contact)

    def derivative(self, x: np.ndarray, w: np.ndarray) -> np.ndarray:
        return np.array(peg_plant.state_derivative(*self.args, x, tuple(w[:3]), tuple(w[3:]), ZERO, ZERO,
                                                   self.plant.pole, *self.scene))

    def torques(self, x: np.ndarray, tip_previous: np.ndarray, k: int, sensed: bool = True) -> np.ndarray:
        """The law's (u, tau) at x without any lead; ``sensed`` False: the F/T sensor read as zero."""
        out = peg_plant.plant_outputs(*self.args, x, ZERO, ZERO, ZERO, ZERO, self.plant.pole, *self.scene)
        y, yd, qw, qwd, ft = out[0], out[1], out[2], out[3], out[-5]
        if not sensed:
            ft = (0.0,) * 6
        c = self.controller
        tip = tuple(tip_previous)
        state = sampling.initial_state(tip)._replace(start=tip, start_rotation=(1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0))
        settings = c._settings._replace(zoh_lead=False)
        st = sampling.sample(c._law, c._wrist, settings, c._program, state, k * settings.sample_period, y, yd, qw,
                             qwd, ft, tuple(c.r), ZERO, ZERO, ZERO, ZERO, ZERO)
        return np.array(st.u + st.tau + st.tip)

    def map(self, x: np.ndarray, tip_previous: np.ndarray, k: int) -> dict:
        """The sampled map's Jacobian pieces at (x, tip_previous)."""
        T = self.controller._settings.sample_period
        w0 = self.torques(x, tip_previous, k)[:6]
        hx = np.r_[np.full(12, 1e-8), np.full(12, 1e-6)]
        A = _jacobian(lambda s: self.derivative(s, w0), x, hx)
        B = _jacobian(lambda w: self.derivative(x, w), w0, np.full(6, 1e-4))
        n = len(x)
        block = np.zeros((n + 6, n + 6))
        block[:n, :n], block[:n, n:] = A * T, B * T
        E = expm(block)
        hl = np.r_[np.full(12, 1e-7), np.full(12, 1e-5)]
        G = _jacobian(lambda s: self.torques(s, tip_previous, k), x, hl)          # total law, and the tip
        Gt = _jacobian(lambda tp: self.torques(x, tp, k), tip_previous, np.full(3, 1e-7))
        H = _jacobian(lambda s: self.torques(s, tip_previous, k, False)[:6], x, hl)  # motion part
        Ht = _jacobian(lambda tp: self.torques(x, tp, k, False)[:6], tip_previous, np.full(3, 1e-7))
        return dict(Ad=E[:n, :n], Bd=E[:n, n:], G=G[:6], Gt=Gt[:6], tip=G[6:], tip_t=Gt[6:], H=H, Ht=Ht)

    @staticmethod
    def closed_loop(p: dict, lead_on: str) -> np.ndarray:
        """The sampled map's matrix, state (x, the lead's memory (6), the previous tip (3)), for the
        lead 1.5 a_k - 0.5 a_k-1 on ``lead_on``: "total" (main), "motion" (now) or "none"."""
        G, Gt = p["G"], p["Gt"]
        H, Ht = {"total": (G, Gt), "motion": (p["H"], p["Ht"]), "none": (0 * G, 0 * Gt)}[lead_on]
        Ad, Bd = p["Ad"], p["Bd"]
        n = Ad.shape[0]
        M = np.zeros((n + 9, n + 9))
        M[:n, :n] = Ad + Bd @ (G + 0.5 * H)
        M[:n, n:n + 6] = -0.5 * Bd
        M[:n, n + 6:] = Bd @ (Gt + 0.5 * Ht)
        M[n:n + 6, :n], M[n:n + 6, n + 6:] = H, Ht
        M[n + 6:, :n], M[n + 6:, n + 6:] = p["tip"], p["tip_t"]
        return M

    def mobility(self, x: np.ndarray) -> np.ndarray:
        """Lambda^-1 at the tip (world): (tip acceleration, angular acceleration) per unit tip force
        and couple, at x with the rates zeroed (Lambda^-1 depends on the pose only)."""
        rest = np.array(x, float)
        rest[12:] = 0.0

        def response(f: Sequence[float], m: Sequence[float]) -> np.ndarray:
            xd = np.array(wrist_derivative(*self.args, rest, ZERO, ZERO, tuple(f), tuple(m), self.plant.pole))
            moved = rest.copy()
            moved[12:] = xd[12:]
            _, _, v_tip, omega = peg_plant.tool_pose(*self.args, moved)
            return np.r_[v_tip, omega]
        base = response(ZERO, ZERO)
        W = np.column_stack([response(e[:3], e[3:]) - base for e in np.eye(6)])
        return 0.5 * (W + W.T)


def one_axis_root(m: float, g: float, K: float, D: float, k: float, c: float, T: float,
                  lead_on_force: bool) -> tuple[float, float]:
    """Largest root modulus, and largest among the roots of negative real part (the modes that
    alternate from sample to sample), of one axis: mass m on a contact (k, c), the law's torque
    g F_sensed - (1 + g)(K x + D v) held over T (F_sensed = -(k x + c v)); the lead 1.5/-0.5 on
    the whole torque or on the spring-damper part only."""
    A = np.array([[0.0, 1.0], [-k / m, -c / m]])
    E = expm(np.block([[A * T, np.array([[0.0], [T / m]])], [np.zeros((1, 3))]]))
    Ad, Bd = E[:2, :2], E[:2, 2:]
    force = -g * np.array([[k, c]])
    motion = -(1.0 + g) * np.array([[K, D]])
    led = force + motion if lead_on_force else motion
    M = np.zeros((3, 3))
    M[:2, :2] = Ad + Bd @ (force + motion + 0.5 * led)
    M[:2, 2:] = -0.5 * Bd
    M[2:, :2] = led
    roots = np.linalg.eigvals(M)
    alternating = roots[roots.real < 0.0]
    return float(np.abs(roots).max()), float(np.abs(alternating).max()) if len(alternating) else 0.0


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--at", type=float, nargs="+", default=[3.5, 5.0, 9.5], help="instants to linearise at (s)")
    args = parser.parse_args(argv)
    stop = max(args.at)
    res = deltafmi.simulate("peg_in_hole", stop=stop, parameters=WEDGE,
                            record=STATES + ["plant.depth", "plant.max_normal_force", "controller.tip_est[*]"])
    t = np.asarray(res["time"])
    plant, controller = _components(WEDGE)
    loop = SampledLoop(plant, controller)
    T = controller._settings.sample_period
    print("1. the wedge's sampled loop linearised (largest root modulus; < 1 stable; a negative real root "
          "alternates from sample to sample)")
    print(f"{'t (s)':>6} {'depth (mm)':>10} {'max f_n (N)':>11} {'lead on all (main)':>19} {'lead on motion':>15}"
          f" {'no lead':>8}")
    x = None
    for at in args.at:
        i = int(np.searchsorted(t, at - 1e-9))
        x = np.array([res[name][i] for name in STATES])
        tip_previous = np.array([res[f"controller.tip_est[{j}]"][i - 1] for j in (1, 2, 3)])
        pieces = loop.map(x, tip_previous, int(round(t[i] / T)))
        roots = {}
        for lead_on in ("total", "motion", "none"):
            ev = np.linalg.eigvals(SampledLoop.closed_loop(pieces, lead_on))
            top = ev[np.argmax(np.abs(ev))]
            alternating = ev[np.argmin(ev.real)]
            roots[lead_on] = f"{abs(top):.4f} ({alternating.real:+.3f})"
        print(f"{t[i]:6.2f} {res['plant.depth'][i] * 1e3:10.2f} {res['plant.max_normal_force'][i]:11.1f} "
              f"{roots['total']:>19} {roots['motion']:>15} {roots['none']:>8}")
    print("   (in brackets: the most negative real root, the step-to-step mode)")

    W = loop.mobility(x)
    tilt = WEDGE["plant.hole_tilt"][0]
    axis = np.array([0.0, -math.sin(tilt), math.cos(tilt)])
    masses = np.asarray(controller.mass, float)
    axial = np.r_[axis, ZERO]
    lateral = np.r_[1.0, 0.0, 0.0, ZERO]
    m_axial, m_lateral = 1.0 / (axial @ W @ axial), 1.0 / (lateral @ W @ lateral)
    mu_axial, mu_lateral = m_axial / masses[2], m_lateral / masses[0]
    print(f"\n2. natural inertia at the tip (wedge pose, the controller's model): along the hole axis "
          f"{m_axial:.2f} kg, sideways {m_lateral:.3f} kg")
    print(f"   M_d = {masses.tolist()} kg: mu axial {mu_axial:.3f} (blocked root {1 - mu_axial:+.3f}), "
          f"sideways {mu_lateral:.4f} (root {1 - mu_lateral:+.4f})")
    print("   stable when blocked: 0 < mu < 2 with the force held as computed; mu < 1.5 with the lead on it")

    print("\n3. one axis, largest root over the shipped contacts: n = 1..32 penalty points in parallel "
          "(k = n 2e5 N/m, c = n 50 N s/m) plus a friction damper c_f = 0..3e4 N s/m (0.5 x 60 N / 1 mm/s)")
    point_k, point_c = float(plant.contact_stiffness), float(plant.contact_damping)
    K_ax = float(controller.stiffness[2])
    for label, m, mu, K, M in (("axial", m_axial, mu_axial, K_ax, masses[2]),
                               ("sideways", m_lateral, mu_lateral, float(controller.stiffness[0]), masses[0])):
        D = 2.0 * math.sqrt(K * M)
        for lead_on_force in (True, False):
            worst, worst_alternating = (0.0, 0, 0.0), (0.0, 0, 0.0)
            for n in (0, 1, 2, 4, 8, 16, 32):
                for c_f in (0.0, 300.0, 1e3, 3e3, 1e4, 3e4):
                    root, alternating = one_axis_root(m, mu - 1.0, K, D, n * point_k, n * point_c + c_f, T,
                                                      lead_on_force)
                    worst = max(worst, (root, n, c_f))
                    worst_alternating = max(worst_alternating, (alternating, n, c_f))
            print(f"   {label:8} m {m:7.3f} kg, mu {mu:.3f}, lead on the force {str(lead_on_force):5}: largest root "
                  f"{worst[0]:.4f}, largest alternating root {worst_alternating[0]:.4f} (n = {worst_alternating[1]}, "
                  f"c_f = {worst_alternating[2]:g} N s/m)")
    print("   one axis blocked by a damper alone (k = 0; c 3e4 N s/m, and 1e7: rigid within a sample), the "
          "alternating root against mu (the tip's axial natural mass; M_d from mu):")
    for mu in (0.5, 1.0, 1.25, 1.465, 1.5, 1.75, 1.9, 2.0, 2.1):
        M = m_axial / mu
        D = 2.0 * math.sqrt(K_ax * M)
        cells = [one_axis_root(m_axial, mu - 1.0, K_ax, D, 0.0, c, T, lead)[1]
                 for c in (3e4, 1e7) for lead in (True, False)]
        print(f"     mu {mu:5.3f} (M_d {M:6.2f} kg): c 3e4: lead on the force {cells[0]:.4f}, held as computed "
              f"{cells[1]:.4f};  rigid: {cells[2]:.4f}, {cells[3]:.4f}")

if __name__ == "__main__":
    main()
