"""Monte Carlo consistency of PegEstimator and ContactEstimator: the normalised estimation error
squared (NEES) of the hole's x, y and the peg's contact force, and of the table's height and the
wrist force, averaged over seeded runs, against its two-sided 95 % chi-square interval.

The plant's run (scenarios/peg_estimation.yaml without the estimator; the estimator does not act
on the loop) is recorded once through the master; then PegEKF (deltafmi.physics.estimation) is
replayed on it ``--runs`` times in this process, each with its own seeded encoder noise on y and
qw (the noise the filter assumes, ``--noise``, unless told otherwise), from ``--start`` to
``--stop`` s (the first touch of the chamfer is at ~1.015 s; starting shortly before it saves
the free approach, the filter starting there at rest as it does at t = 0). For a consistent
filter the mean NEES over R runs of a d-dimensional error is chi-square(d R) / R: within
[chi2.ppf(0.025, d R), chi2.ppf(0.975, d R)] / R at 95 %. Printed at several instants and
averaged over the bore, for the settings given (``--set name=value``, PegEKFSettings names) and
for the baseline: the extended filter's single linearisation of the contact law and the whole
process Jacobian every sample (contact_iterations 1, jacobian_columns 18); and with the hole's
random walk set (hole_drift_std, tilt_drift_std; off by default).

ContactEstimator (--estimator contact): scenarios/contact_estimation.yaml recorded once without
the estimator, ContactEKF replayed from 0.2 s before the touch to the end (the press at rest),
noise y_std (1e-5 rad); the truth is the plane's force on the tool (normal_force +
friction_force; the estimator knows the payload) and the plant's surface height; ``--set``
takes ContactEKFSettings names. On data from the filter's own model (a random-walk force, no
model error) tests/physics/test_contact_estimator_consistency.py asserts the force's NEES.

Usage: python benchmarks/estimator_consistency.py [--estimator peg|contact] [--runs 50] [--noise RAD]
       [--start 0.9] [--stop 1.6]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.stats import chi2

sys.path.insert(0, str(Path(__file__).resolve().parent))
from assembly_realtime import component, contact_component, contact_truth, peg_truth  # noqa: E402

from deltafmi.physics.delta.tactile import Readout  # noqa: E402
from deltafmi.physics.estimation.peg_ekf import PegEKF  # noqa: E402
from deltafmi.physics.estimation.contact_ekf import ContactEKF  # noqa: E402


def replay(d: dict, c: "PegEstimator", settings, noise: float, seed: int, start: float, stop: float) -> tuple:
    """(times, hole NEES, force NEES, reopened, hole error norm) of one seeded run."""
    readout, ekf, t = Readout(noise, 0.0, seed), None, d["time"]
    rows = []
    for k in range(int(round(start / 1e-3)), int(round(stop / 1e-3)) + 1):
        i = int(np.searchsorted(t, k * 1e-3 + 1e-9)) - 1  # the row at the sample instant
        read = [readout.read(float(v), k, j) for j, v in enumerate(np.r_[d["y"][i], d["qw"][i]])]
        if ekf is None:
            ekf = PegEKF(c.robot_params(), c._wrist, c._mount, c._hole, c._peg, c._law, settings, read[:3],
                         read[3:])
        est = ekf.step(read[:3], read[3:], d["u"][i], d["tau"][i])
        eh, ef = est.hole[:2] - d["hole"][i][:2], est.force - d["force"][i]
        rows.append((t[i], eh @ np.linalg.solve(ekf.P[18:20, 18:20], eh), ef @ np.linalg.solve(ekf.P[12:15, 12:15], ef),
                     np.linalg.norm(eh)))
    a = np.array(rows)
    return a[:, 0], a[:, 1], a[:, 2], ekf.reopened, a[:, 3]


def monte_carlo(d: dict, c: "PegEstimator", settings, args) -> None:
    H, F, reopened, E = [], [], [], []
    began = time.perf_counter()
    for r in range(args.runs):
        t, h, f, n, e = replay(d, c, settings, args.noise, 1000 + r, args.start, args.stop)
        E.append(e[-1])
        H.append(h)
        F.append(f)
        reopened.append(n)
    H, F, R = np.array(H), np.array(F), args.runs
    print(f"  {R} runs in {time.perf_counter() - began:.0f} s; hole covariance reopened in {np.count_nonzero(reopened)} "
          f"runs; hole error at the end: median {np.median(E) * 1e6:.1f} um, largest {np.max(E) * 1e6:.1f} um")
    for name, nees, dof in (("hole x, y", H, 2), ("force", F, 3)):
        lo, hi = chi2.ppf(0.025, dof * R) / R, chi2.ppf(0.975, dof * R) / R
        at = [(q, nees[:, np.argmin(np.abs(t - q))].mean()) for q in (1.1, 1.2, 1.4, args.stop) if q <= args.stop]
        bore = nees[:, t > 1.3].mean() if np.any(t > 1.3) else float("nan")
        print(f"  {name:10} mean NEES " + ", ".join(f"t={q:.1f} s: {v:.3g}" for q, v in at)
              + f"; over the bore {bore:.3g}; 95 % interval for dof {dof}: [{lo:.3f}, {hi:.3f}]")


def contact_replay(d: dict, c: "ContactEstimator", settings, noise: float, seed: int, start: float) -> tuple:
    readout, ekf, t = Readout(noise, 0.0, seed), None, d["time"]
    rows = []
    for k in range(int(round(start / 1e-3)), int(round(t[-1] / 1e-3)) + 1):
        i = int(np.searchsorted(t, k * 1e-3 + 1e-9)) - 1
        y = [readout.read(float(v), k, j) for j, v in enumerate(d["y"][i])]
        if ekf is None:
            ekf = ContactEKF(c.robot_params(), settings, y)
        est = ekf.step(y, d["u"][i])
        ef, es = est.force - d["force"][i], est.surface_height - d["surface"][i]
        rows.append((t[i], ef @ np.linalg.solve(ekf.P[18:21, 18:21], ef), es * es / ekf.P[21, 21]))
    a = np.array(rows)
    return a[:, 0], a[:, 1], a[:, 2]


def contact_monte_carlo(args) -> None:
    c = contact_component()
    noise = args.noise or c._settings.y_std
    with tempfile.TemporaryDirectory() as tmp:
        d = contact_truth(Path(tmp))
    touch = float(d["time"][np.argmax(d["mode"] > 0)])
    settings = replace(c._settings, **{k: float(v) for k, v in (s.split("=", 1) for s in args.set)})
    F, S = [], []
    began = time.perf_counter()
    for r in range(args.runs):
        t, f, s = contact_replay(d, c, settings, noise, 1000 + r, touch - 0.2)
        F.append(f)
        S.append(s)
    F, S, R = np.array(F), np.array(S), args.runs
    print(f"ContactEstimator: {R} runs from {touch - 0.2:.3f} s (touch {touch:.3f} s), noise {noise:g} rad, "
          f"{time.perf_counter() - began:.0f} s; settings changed: {args.set or 'none'}")
    phases = {"free": t < touch, "impact (0.3 s)": (t >= touch) & (t < touch + 0.3), "pressing": t >= touch + 0.3,
              "last second": t > t[-1] - 1.0}
    for name, nees, dof in (("force", F, 3), ("surface", S, 1)):
        lo, hi = chi2.ppf(0.025, dof * R) / R, chi2.ppf(0.975, dof * R) / R
        print(f"  {name:8} mean NEES " + ", ".join(f"{p}: {nees[:, m].mean():.3g}" for p, m in phases.items())
              + f", at the end {nees[:, -1].mean():.3g}; 95 % interval for dof {dof}: [{lo:.3f}, {hi:.3f}]")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--estimator", choices=("peg", "contact"), default="peg")
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--noise", type=float, default=None, help="encoder noise (rad; default the y_std assumed)")
    parser.add_argument("--start", type=float, default=0.9)
    parser.add_argument("--stop", type=float, default=1.6)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    args = parser.parse_args()
    if args.estimator == "contact":
        contact_monte_carlo(args)
        return
    c = component()
    args.noise = args.noise or c._settings.y_std
    with tempfile.TemporaryDirectory() as tmp:
        d = peg_truth(Path(tmp), args.stop)
    integers = {"contact_iterations", "jacobian_columns", "reject_samples", "contact_samples", "substeps"}
    changes = {k: int(v) if k in integers else float(v) for k, v in (s.split("=", 1) for s in args.set)}
    baseline = replace(c._settings, contact_iterations=1, jacobian_columns=18)
    drift = replace(c._settings, hole_drift_std=3e-3, tilt_drift_std=3e-2)
    for label, settings in (("baseline: the extended filter (one linearisation of the law, full Jacobian)", baseline),
                            ("now (defaults, with --set)", replace(c._settings, **changes)),
                            ("with the hole's random walk 3e-3 m, 3e-2 rad per sqrt(s)", drift)):
        print(label)
        monte_carlo(d, c, settings, args)


if __name__ == "__main__":
    main()
