"""Cost of one evaluation of the delta feedback-linearising controller.

Prints the median time (us) of one full controller evaluation (forward kinematics + Jc +
gravity + reduced inertia + PID) of ``deltafmi.physics.delta.control.DeltaController``, beside
a straightforward numpy transcription of the seed's algorithm (dense 6x6 Newton with
np.linalg.solve, Jc from a 6x6 solve, gravity from the 9x9 solve, My from the reordered 9x9 M)
measured in the same run, and the ratio. Both are driven through the same 1 kHz sequence of
servo samples along a circle, so the Newton warm starts are realistic.

    /work/venv/bin/python benchmarks/controller.py [--fmu path/to/DeltaController.fmu]
"""

from __future__ import annotations

import argparse
import statistics
import timeit
from typing import Optional

import numpy as np

from deltafmi.physics.delta import control as dc
from deltafmi.physics.delta.params import ARM_ROTATIONS, RL5, DeltaParams
from deltafmi.physics.delta.trajectory import CirclePath

SAMPLE = 1e-3


# --------------------------------------------------------------------------------------------
# baseline: the seed's algorithm transcribed with numpy, no structure exploited
# --------------------------------------------------------------------------------------------
class SeedNumpyController:
    """The seed's inner loop written the obvious way with numpy (the speed baseline).

    Same law as ``DeltaController(coriolis=False, zoh_lead=False)``: u = My Jc^-1 a + tau_g, with
    My = T^T M T (the exact reduced inertia; the seed's M11 - M12 hx^-1 hy costs the same).
    """

    IY = [0, 3, 6]                     # servo angles in q
    IX = [1, 2, 4, 5, 7, 8]            # unmeasured angles in q

    def __init__(self, p: DeltaParams, pole: float = 7.0) -> None:
        self.p = p
        self.kI, self.kP, self.kD = pole ** 3, 3 * pole ** 2, 3 * pole
        self.integral = np.zeros(3)
        self.x: Optional[np.ndarray] = None
        mpa = (p.mp + p.payload) / 3.0
        self.a = p.J1 + p.Jm + (p.m2 + mpa) * p.l1 ** 2
        self.b = (p.m2 / 2 + mpa) * p.l1 * p.l2
        self.beta = (p.m2 / 3 + mpa) * p.l2 ** 2
        self.g1 = p.g * (p.m1 * p.r1 + (p.m2 + mpa) * p.l1)
        self.g2 = p.g * (p.m2 / 2 + mpa) * p.l2
        self.B = np.zeros((9, 3))
        self.B[self.IY, [0, 1, 2]] = 1.0

    def psi(self, qi: np.ndarray) -> np.ndarray:
        p = self.p
        return np.array([p.l2 * np.sin(qi[1]) * np.sin(qi[2]),
                         p.l0 - p.l3 + p.l1 * np.cos(qi[0]) + p.l2 * np.cos(qi[1]),
                         p.l1 * np.sin(qi[0]) + p.l2 * np.sin(qi[1]) * np.cos(qi[2])])

    def dpsi(self, qi: np.ndarray) -> np.ndarray:
        p = self.p
        s1, c1, s2, c2, s3, c3 = (np.sin(qi[0]), np.cos(qi[0]), np.sin(qi[1]), np.cos(qi[1]),
                                  np.sin(qi[2]), np.cos(qi[2]))
        return np.array([[0.0, p.l2 * c2 * s3, p.l2 * s2 * c3],
                         [-p.l1 * s1, -p.l2 * s2, 0.0],
                         [p.l1 * c1, p.l2 * c2 * c3, -p.l2 * s2 * s3]])

    def h(self, q: np.ndarray) -> np.ndarray:
        R1, R2, R3 = ARM_ROTATIONS
        p1 = self.psi(q[0:3])
        return np.concatenate([p1 - R2 @ self.psi(q[3:6]), p1 - R3 @ self.psi(q[6:9])])

    def H(self, q: np.ndarray) -> np.ndarray:
        R1, R2, R3 = ARM_ROTATIONS
        j1 = self.dpsi(q[0:3])
        H = np.zeros((6, 9))
        H[0:3, 0:3] = j1
        H[3:6, 0:3] = j1
        H[0:3, 3:6] = -R2 @ self.dpsi(q[3:6])
        H[3:6, 6:9] = -R3 @ self.dpsi(q[6:9])
        return H

    def mass_gravity(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        M = np.zeros((9, 9))
        G = np.zeros(9)
        for i in range(3):
            q1, q2, q3 = q[3 * i:3 * i + 3]
            s1, c1, s2, c2, s3, c3 = (np.sin(q1), np.cos(q1), np.sin(q2), np.cos(q2),
                                      np.sin(q3), np.cos(q3))
            m12 = self.b * (s1 * s2 + c1 * c2 * c3)
            m13 = -self.b * c1 * s2 * s3
            M[3 * i:3 * i + 3, 3 * i:3 * i + 3] = [[self.a, m12, m13], [m12, self.beta, 0.0],
                                                   [m13, 0.0, self.beta * s2 * s2]]
            G[3 * i:3 * i + 3] = [self.g1 * c1, self.g2 * c2 * c3, -self.g2 * s2 * s3]
        return M, G

    def step(self, y, yd, r, rd, rdd) -> np.ndarray:
        y = np.asarray(y, dtype=float)
        q = np.zeros(9)
        q[self.IY] = y
        if self.x is None:
            q[self.IX] = dc.forward_kinematics_closed(self.p, y)[1]
        else:
            q[self.IX] = self.x
        # 1. forward kinematics: Newton on h(x, y) = 0
        for _ in range(10):
            hq = self.h(q)
            if np.max(np.abs(hq)) <= 1e-12:
                break
            Hq = self.H(q)
            q[self.IX] -= np.linalg.solve(Hq[:, self.IX], hq)
        Hq = self.H(q)
        hx, hy = Hq[:, self.IX], Hq[:, self.IY]
        z = (ARM_ROTATIONS[0] @ self.psi(q[0:3]) + ARM_ROTATIONS[1] @ self.psi(q[3:6])
             + ARM_ROTATIONS[2] @ self.psi(q[6:9])) / 3.0
        # 2. control Jacobian Jc = dPsi/dx dg/dy + dPsi/dy
        dgdy = -np.linalg.solve(hx, hy)
        j1 = self.dpsi(q[0:3])
        Jc = j1[:, 1:3] @ dgdy[0:2, :]
        Jc[:, 0] += j1[:, 0]
        zd = Jc @ np.asarray(yd, dtype=float)
        xd = dgdy @ np.asarray(yd, dtype=float)
        # 3. gravity: [B H^T][tau; lambda] = G
        M, G = self.mass_gravity(q)
        tau_g = np.linalg.solve(np.hstack([self.B, Hq.T]), G)[:3]
        # 4. reduced inertia My = T^T M T in (y, x) order
        order = self.IY + self.IX
        Mr = M[np.ix_(order, order)]
        T = np.vstack([np.eye(3), dgdy])
        My = T.T @ Mr @ T
        # 5. PID in wrist coordinates
        e = np.asarray(r, dtype=float) - z
        self.integral = np.clip(self.integral + SAMPLE * e, -1.0 / self.kI, 1.0 / self.kI)
        acc = (self.kI * self.integral + self.kP * e + self.kD * (np.asarray(rd) - zd)
               + np.asarray(rdd))
        u = My @ np.linalg.solve(Jc, acc) + tau_g
        self.x = q[self.IX] + SAMPLE * xd
        return u


# --------------------------------------------------------------------------------------------
# measurement
# --------------------------------------------------------------------------------------------
def circle_samples(p: DeltaParams, n: int) -> list[tuple]:
    """n consecutive 1 kHz samples (y, yd, r, rd, rdd) along a ramped 0.15 m / 1 s circle,
    taken after the ramp-in so the robot moves at full speed (the worst case for warm starts)."""
    path = CirclePath((0.0, 0.0, -1.0), 0.15, 1.0, ramp_time=0.5)
    out = []
    for k in range(n):
        t = 0.6 + k * SAMPLE
        r, rd, rdd = path.evaluate(t)
        # measured state slightly off the reference, as in closed loop
        y, _ = dc.inverse_kinematics_servo(p, r + np.array([1e-4, -2e-4, 1e-4]))
        yd = np.linalg.solve(dc.control_jacobian(p, y), rd)
        out.append((y.tolist(), yd.tolist(), r, rd, rdd))
    return out


def time_per_call(make, samples, repeat: int = 25) -> float:
    """Median over ``repeat`` runs of the mean time (us) of one step through ``samples``."""
    def run():
        ctl = make()
        for s in samples:
            ctl.step(*s)
    times = timeit.repeat(run, number=1, repeat=repeat)
    return statistics.median(times) / len(samples) * 1e6


def fmu_cost_per_sample(fmu_path: Optional[str], samples=None) -> Optional[float]:
    """LEAD: cost per sample through the DeltaController FMU (fmpy, Co-Simulation).

    Median us per sample of set inputs / doStep(1 ms) / get u through fmpy's FMU2Slave, or None
    (skipped) when no FMU path is given.
    """
    if not fmu_path:
        return None
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(fmu_path)
    refs = {v.name: v.valueReference for v in md.modelVariables}
    names = [f"{n}[{i}]" for n in ("y", "yd", "r", "rd", "rdd") for i in (1, 2, 3)]
    vr_in = [refs[n] for n in names]
    vr_u = [refs[f"u[{i}]"] for i in (1, 2, 3)]
    unzip = extract(fmu_path)
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    samples = samples or circle_samples(RL5, 200)
    fmu.setReal(vr_in, [float(v) for part in samples[0] for v in part])
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    t = [0.0]

    def run():
        for s in samples:
            fmu.setReal(vr_in, [float(v) for part in s for v in part])
            fmu.doStep(t[0], SAMPLE)
            t[0] += SAMPLE
            fmu.getReal(vr_u)
    times = timeit.repeat(run, number=1, repeat=15)
    fmu.terminate()
    fmu.freeInstance()
    return statistics.median(times) / len(samples) * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmu", default=None, help="DeltaController.fmu for the per-sample cost")
    ap.add_argument("--samples", type=int, default=200)
    args = ap.parse_args()
    p = RL5
    samples = circle_samples(p, args.samples)

    # same law, same samples: check the two agree before timing them
    fast = dc.DeltaController(p, coriolis=False, zoh_lead=False)
    base = SeedNumpyController(p)
    diff = max(float(np.max(np.abs(fast.step(*s) - base.step(*s)))) for s in samples)

    rows = [
        ("baseline: numpy transcription of the seed", lambda: SeedNumpyController(p)),
        ("DeltaController, seed law (no velocity terms, no lead)",
         lambda: dc.DeltaController(p, coriolis=False, zoh_lead=False)),
        ("DeltaController, default (Newton FK, exact ID, lead)", lambda: dc.DeltaController(p)),
        ("DeltaController, closed-form FK", lambda: dc.DeltaController(p, fk="closed")),
    ]
    times = [time_per_call(make, samples) for _, make in rows]
    iters = []
    ctl = dc.DeltaController(p)
    for s in samples:
        ctl.step(*s)
        iters.append(ctl.last.iterations)
    print(f"one controller evaluation, median of 25 runs x {len(samples)} samples "
          f"(1 kHz circle r = 0.15 m, T = 1 s)")
    print(f"  max |u_fast - u_baseline| over the samples: {diff:.2e} N m")
    print(f"  Newton iterations per sample (default): mean {np.mean(iters):.2f}, "
          f"max {max(iters)}")
    for (name, _), t in zip(rows, times):
        print(f"  {name:54s} {t:8.1f} us   x{times[0] / t:5.1f} vs baseline")
    cost = fmu_cost_per_sample(args.fmu, samples)
    if cost is None:
        print("  FMU cost per sample: skipped (pass --fmu path/to/DeltaController.fmu)")
    else:
        print(f"  FMU cost per sample (fmpy CS set/doStep/get): {cost:8.1f} us")


if __name__ == "__main__":
    main()
