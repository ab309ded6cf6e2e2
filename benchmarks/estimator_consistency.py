"""Monte Carlo consistency of PegEstimator and ContactEstimator: the normalised estimation error
squared (NEES) of the hole's x, y and the peg's contact force, and of the table's height and the
wrist force, averaged over seeded runs, against its two-sided 95 % chi-square interval.

The plant's run (scenarios/peg_estimation.yaml without the estimator; the estimator does not act
on the loop) is recorded once through the master; then PegEKF (deltafmi.physics.estimation) is
replayed on it ``--runs`` times in this process, each with its own seeded encoder noise on y and
qw (the noise the filter assumes, ``--noise``, unless told otherwise), from ``--start`` to
``--stop`` s (the first touch of the chamfer is at ~1.015 s; starting shortly before it saves
the free approach, the filter starting there at rest as it does at t = 0), its kernels compiled
as its FMU runs them (the Python ones give the same bits). For a consistent filter the mean NEES
over R runs of a d-dimensional error is chi-square(d R) / R: within
[chi2.ppf(0.025, d R), chi2.ppf(0.975, d R)] / R at 95 %. Printed at several instants and
averaged over the phases of tests/models/test_peg_estimator_consistency.py (sliding on the
chamfer 1.05-1.2 s, the impacts 1.0-1.05 s and 1.2-1.3 s, the bore to 1.5 s, after it and
whole; "sliding": the chamfer and the bore to 1.5 s for the hole, to the end for the force), for the
hole's x, y (d = 2), the hole with its tilt (d = 4) and the force (d = 3): for the defaults with
the settings given (``--set name=value``, PegEKFSettings names), for the baseline, the previous
defaults (the wrench a random walk at 30 N/s and 2 N m/s per sqrt(Hz) throughout, model-error
accelerations 0.01 m/s^2 and 0.5 rad/s^2 per sqrt(Hz), no law error considered, the hole
constant), for the last release's wrench (a random walk, 1 N/s and 0.05 N m/s per sqrt(Hz)
between manoeuvres, no rate), and for the defaults without each of their noise models in turn.
First, what the wrench's noise levels rest on: the plant's contact force and moment by phase,
as a random walk over one sample (rms of the change per sample / sqrt(T)), as an integrated
random walk over tau = 20, 50 and 100 ms (rms of the second difference over tau, sqrt(3/2) / tau^1.5:
a rate that is a random walk of that density gives it), and the rms of its ramps (least-squares
slopes); the contact law's error at the plant's own state and hole (against the plant's wrench);
and the process model's one-step error on the plant's own states (what acceleration_std and
angular_acceleration_std stand for), the wrench held over the sample or at its mid-period value.
By 0.1 s in the bore, besides the NEES, how often the contact law at the estimate (its state and
hole) has fewer active contact points than the plant, or as many, and the hole's NEES over those
samples.

ContactEstimator (--estimator contact): first what its noise levels rest on (the plant's force
rates by phase, as a random walk and as an integrated random walk over 20, 50 and 100 ms, and its
ramps; the contact law's residual; the process model's one-step error on the plant's states, the
force held over the step or at its mid-period value as the filter with the force's rate holds it);
then scenarios/contact_estimation.yaml recorded once without the estimator, ContactEKF
replayed from the start to the end (the press at rest), noise y_std (1e-5 rad); the truth is the
plane's force on the tool (normal_force + friction_force; the estimator knows the payload) and
the plant's surface height; printed for the scenario's settings, its force as the last release's
random walk (no rate), the previous settings, and without the rest level, the manoeuvre detector
or its hold: the NEES of the force, its normal component and the surface by phase, where the rest
level is on, and the impact's samples before the detector first fires (the detector's delay, which
no walk at the press's levels covers) apart from the rest of its 0.1 s; ``--set`` takes
ContactEKFSettings names. The plant's statistics include its wrist acceleration at rest (the rest
level's zero-acceleration pseudo-measurement). On data from the filter's own model (a random-walk force, no model error) tests/physics/test_contact_estimator_consistency.py
asserts the force's NEES, on the real plant tests/models/test_contact_estimator_scenario_consistency.py.

Usage: python benchmarks/estimator_consistency.py [--estimator peg|contact] [--runs 16] [--noise RAD]
       [--start 0.9] [--stop 2.2] [--set NAME=VALUE ...] [--variants 9] (contact: 6 variants)
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
from deltafmi.physics.estimation.peg_contact import linearization_parts  # noqa: E402
from deltafmi.physics.estimation.peg_ekf import PegEKF  # noqa: E402
from deltafmi.physics.estimation.contact_ekf import ContactEKF  # noqa: E402


def replay(d: dict, c: "PegEstimator", settings, noise: float, seed: int, start: float,  # noqa: F821
           stop: float) -> tuple:
    """(times, hole x-y NEES, force NEES, reopened, hole error norm, hole NEES, tilt error, manoeuvre
    flag, the law's active contacts at the estimate less the plant's) of one seeded run."""
    readout, ekf, t = Readout(noise, 0.0, seed), None, d["time"]
    rows = []
    for k in range(int(round(start / 1e-3)), int(round(stop / 1e-3)) + 1):
        i = int(np.searchsorted(t, k * 1e-3 + 1e-9)) - 1  # the row at the sample instant
        read = [readout.read(float(v), k, j) for j, v in enumerate(np.r_[d["y"][i], d["qw"][i]])]
        if ekf is None:
            ekf = PegEKF(c.robot_params(), c._wrist, c._mount, c._hole, c._peg, c._law, settings, read[:3],
                         read[3:], functions=c.native_functions)
        est = ekf.step(read[:3], read[3:], d["u"][i], d["tau"][i])
        eh, ef = est.hole - d["hole"][i], est.force - d["force"][i]
        rows.append((t[i], eh[:2] @ np.linalg.solve(ekf.P[18:20, 18:20], eh[:2]),
                     ef @ np.linalg.solve(ekf.P[12:15, 12:15], ef), np.linalg.norm(eh[:2]),
                     eh @ np.linalg.solve(ekf.P[18:22, 18:22], eh), np.abs(eh[2:]).max(), float(ekf.manoeuvre),
                     law_contacts(c, ekf.x[:12], est.hole) - d["active"][i]))
    a = np.array(rows)
    return a[:, 0], a[:, 1], a[:, 2], ekf.reopened, a[:, 3], a[:, 4], a[:, 5], a[:, 6], a[:, 7]


def law_contacts(c: "PegEstimator", s: np.ndarray, h: np.ndarray) -> float:  # noqa: F821
    """The contact law's active contact points at the reduced state s with the hole h."""
    return linearization_parts(c.native_functions.contact_linearization(
        c._hole, c._peg, c._law, c._wrist, c._mount, np.asarray(s, float).tolist(), np.asarray(h, float).tolist(),
        True))[2]


def monte_carlo(d: dict, c: "PegEstimator", settings, args) -> None:
    H, F, H4, reopened, E, A, M, K = [], [], [], [], [], [], [], []
    began = time.perf_counter()
    for r in range(args.runs):
        t, h, f, n, e, h4, a, m, k = replay(d, c, settings, args.noise, 1000 + r, args.start, args.stop)
        M.append(m)
        K.append(k)
        E.append(e[-1])
        A.append(a[-1])
        H.append(h)
        F.append(f)
        H4.append(h4)
        reopened.append(n)
    H, F, H4, R = np.array(H), np.array(F), np.array(H4), args.runs
    print(f"  {R} runs in {time.perf_counter() - began:.0f} s; hole covariance reopened in {np.count_nonzero(reopened)} "
          f"runs; hole error at the end: x-y median {np.median(E) * 1e6:.1f} um, largest {np.max(E) * 1e6:.1f} um, "
          f"tilt median {np.median(A) * 1e3:.2f} mrad, largest {np.max(A) * 1e3:.2f} mrad")
    chamfer, bore = (t >= 1.05) & (t < 1.2), (t >= 1.3) & (t < 1.5005)
    phases = {"chamfer": chamfer, "impacts": ((t >= 1.0) & (t < 1.05)) | ((t >= 1.2) & (t < 1.3)),
              "bore to 1.5 s": bore, "bore after 1.5 s": t >= 1.5005, "bore from 1.3 s": t >= 1.3}
    for name, nees, dof in (("hole x, y", H, 2), ("hole, tilt", H4, 4), ("force", F, 3)):
        lo, hi = chi2.ppf(0.025, dof * R) / R, chi2.ppf(0.975, dof * R) / R
        at = [(q, nees[:, np.argmin(np.abs(t - q))].mean()) for q in (1.1, 1.2, 1.4, 1.8, args.stop) if q <= args.stop]
        sliding = chamfer | (t >= 1.3) if name == "force" else chamfer | bore
        means = {p: nees[:, m].mean() if np.any(m) else float("nan") for p, m in phases.items()}
        if name == "force":
            means["largest (an instant's mean)"] = nees.mean(axis=0).max()
        print(f"  {name:10} mean NEES " + ", ".join(f"t={q:.1f} s: {v:.3g}" for q, v in at)
              + f"; sliding {nees[:, sliding].mean():.3g}; " + ", ".join(f"{p} {v:.3g}" for p, v in means.items())
              + f"; 95 % interval for dof {dof}: [{lo:.3f}, {hi:.3f}]")
    for lo, hi in ((1.3, 1.4), (1.4, 1.5), (1.5, 1.6), (1.6, 1.7), (1.7, 1.8), (1.8, 1.9), (1.9, 2.05), (2.05, args.stop)):
        if hi <= args.stop + 1e-9:
            m = (t >= lo) & (t < hi + 0.5e-3)
            fewer, same = np.array(K)[:, m] < 0, np.array(K)[:, m] == 0
            windows = (f"{lo:.2f}-{hi:.2f} s: hole {H4[:, m].mean():.3g}, force {F[:, m].mean():.3g}; the law at the "
                       f"estimate with fewer contacts than the plant {100 * fewer.mean():.0f} % of the samples (hole "
                       f"{H4[:, m][fewer].mean() if fewer.any() else np.nan:.3g}), as many "
                       f"{100 * same.mean():.0f} % ({H4[:, m][same].mean() if same.any() else np.nan:.3g})")
            print(f"  by 0.1 s in the bore, {windows}")
    M = np.array(M)
    print("  manoeuvre flagged at " + ", ".join(f"{100 * M[:, m].mean():.1f} %" + f" of the {p} samples"
                                              for p, m in phases.items() if p != "bore from 1.3 s"))


def walk_levels(X: np.ndarray, t: np.ndarray, lo: float, hi: float, T: float = 1e-3) -> tuple:
    """X's (samples T apart) levels over [lo, hi], rms over the axes: as a random walk over one sample
    (rms change / sqrt(T)), as an integrated random walk over 20, 50 and 100 ms (rms second
    difference over tau, sqrt(3/2) / tau^1.5; nan where the phase is too short), and the rms of its
    least-squares slope."""
    X = X[(t >= lo) & (t <= hi)]
    walk = float(np.sqrt(np.mean(np.diff(X, axis=0) ** 2) / T))
    integrated = []
    for n in (20, 50, 100):
        second = X[2 * n:] - 2.0 * X[n:-n] + X[:-2 * n] if len(X) > 2 * n else np.full((1, 3), np.nan)
        integrated.append(float(np.sqrt(1.5 * np.mean(second ** 2) / (n * T) ** 3)))
    slope = np.polyfit(np.arange(len(X)) * T, X, 1)[0]
    return walk, integrated, float(np.sqrt(np.mean(slope ** 2)))


def force_rates(d: dict) -> None:
    """The plant's contact force and moment by phase, as the wrench's noise models read them."""
    t = d["time"]
    on_grid = np.abs(t / 1e-3 - np.round(t / 1e-3)) < 1e-6
    t, F, M = t[on_grid], d["force"][on_grid], d["moment"][on_grid]
    print("the plant's contact force (N) and moment (N m), rms over the axes: as a random walk over one sample "
          "(/s per sqrt(Hz)); as an integrated random walk over 20, 50, 100 ms (/s^2 per sqrt(Hz)); its ramp (/s):")
    for name, lo, hi in (("impact (1.0-1.05 s)", 1.0, 1.05), ("chamfer slide (1.05-1.12 s)", 1.05, 1.12),
                         ("chamfer (1.05-1.2 s)", 1.05, 1.2), ("bore (1.3-1.5 s)", 1.3, 1.5),
                         ("bore (from 1.35 s)", 1.35, t[-1])):
        text = []
        for label, X in (("force", F), ("moment", M)):
            walk, integrated, ramp = walk_levels(X, t, lo, hi)
            text.append(f"{label}: walk {walk:.3g}, integrated {' / '.join(f'{v:.3g}' for v in integrated)}, "
                        f"ramp {ramp:.3g}")
        print(f"  {name:28} " + "; ".join(text))


def model_error(d: dict, c: "PegEstimator") -> None:  # noqa: F821
    """The PegEstimator's process model's one-step error on the plant's own states (what
    acceleration_std and angular_acceleration_std stand for): from the plant's reduced state at
    each sample, its torques and its wrench held over the period (as the filter holds them) or at
    their mid-period value, one prediction (the filter's kernel), its velocities against the
    plant's at the next sample, over sqrt(T): rms by phase, per axis."""
    st, T = c._settings, 1e-3
    t = d["time"]
    on = np.abs(t / T - np.round(t / T)) < 1e-6
    t, s, W = t[on], d["s"][on], np.hstack([d["force"], d["moment"]])[on]
    u, tau = d["u"][on], d["tau"][on]
    errors = {"held": [], "mid-period": []}
    for k in range(len(t) - 1):
        for label, wrench in (("held", W[k]), ("mid-period", 0.5 * (W[k] + W[k + 1]))):
            out = np.asarray(c.native_functions.prediction(c.robot_params(), c._wrist, c._mount, s[k].tolist(),
                                                           u[k].tolist(), tau[k].tolist(), wrench.tolist(),
                                                           float(st.pole), T, int(st.substeps), 0, 0), float)
            errors[label].append((out[6:12] - s[k + 1, 6:12]) / np.sqrt(T))
    law = []
    for k in np.nonzero((t >= 1.3) & (d["active"][on] > 0))[0]:
        values = np.asarray(c.native_functions.contact_linearization(
            c._hole, c._peg, c._law, c._wrist, c._mount, s[k].tolist(), d["hole"][on][k].tolist(), True), float)
        law.append(np.abs(values[:6] - W[k]))
    law = np.array(law)
    print(f"the contact law at the plant's state and hole against the plant's wrench, in the bore (from 1.3 s, "
          f"{len(law)} samples in contact): largest error {law[:, :3].max():.2g} N, {law[:, 3:].max():.2g} N m")
    print(f"the process model's one-step velocity error / sqrt(T) on the plant's states, rms per axis: plate "
          f"(m/s^2 per sqrt(Hz); acceleration_std {st.acceleration_std:g}), wrist joints (rad/s^2 per sqrt(Hz); "
          f"angular_acceleration_std {st.angular_acceleration_std:g}), the wrench held over the period / at its "
          f"mid-period value:")
    for name, lo, hi in (("free (0.9-1.0 s)", 0.9, 1.0), ("impact (1.0-1.05 s)", 1.0, 1.05),
                         ("chamfer (1.05-1.2 s)", 1.05, 1.2), ("fall, wall (1.2-1.3 s)", 1.2, 1.3),
                         ("bore (1.3-1.5 s)", 1.3, 1.5), ("bore (from 1.5 s)", 1.5, t[-1])):
        m = (t[:-1] >= lo) & (t[:-1] < hi)
        text = []
        for label, values in errors.items():
            rms = np.sqrt(np.mean(np.array(values)[m] ** 2, axis=0))
            text.append(f"{label}: plate {' '.join(f'{v:.2g}' for v in rms[:3])}, wrist "
                        f"{' '.join(f'{v:.2g}' for v in rms[3:])}")
        print(f"  {name:24} " + "; ".join(text))


#: the ContactEstimator's settings before they were derived from the plant (contact_estimation.yaml
#: then): the force a random walk at 100 N/s per sqrt(Hz) throughout, model-error accelerations
#: 0.05 m/s^2 per sqrt(Hz), the contact law's noise 5 N, applied above 10 N for 10 samples
CONTACT_BEFORE = dict(acceleration_std=0.05, force_rate_std=100.0, steady_force_rate_std=0.0, contact_model_std=5.0,
                      contact_threshold=10.0, contact_samples=10, manoeuvre_hold=0)
#: the last release's force: a random walk, 0.3 N/s per sqrt(Hz) between manoeuvres, without its rate
CONTACT_WALK = dict(steady_force_rate_std=0.3, force_acceleration_std=0.0, force_ramp_std=0.0)
#: no rest level: the steady walks at rest too, and no zero-acceleration pseudo-measurement
NO_REST = dict(rest_force_rate_std=0.0, rest_acceleration_std=0.0)
SETTLE = 0.1  # s after the touch: the impact's transient, left out of "in contact"


def contact_statistics(d: dict, kernels) -> None:
    """What the ContactEstimator's noise levels rest on: the plant's normal-force rate by phase (rms
    of the change per sample / sqrt(T), and the largest change per sample, whose 0.5-1 times is
    the walk's change per sample by Bar-Shalom, Li, Kirubarajan 2001, section 6.3.3), the contact
    law's residual, and the process model's one-step error on the plant's own states."""
    from deltafmi.physics.delta.kinematics import inverse_kinematics

    c = contact_component()
    t = d["time"]
    on = np.abs(t / 1e-3 - np.round(t / 1e-3)) < 1e-6
    t, F, mode = t[on], d["force"][on], d["mode"][on]
    touch = float(t[np.argmax(mode > 0)])
    rest = float(t[np.nonzero(np.abs(np.diff(F[:, 2])) > 1e-6)[0][-1] + 1])
    phases = {"free": (0.0, touch - 1e-3), f"impact ({SETTLE} s)": (touch - 1e-3, touch + SETTLE),
              "press, ramp": (touch + SETTLE, rest - 0.6), "press, settling": (rest - 0.6, rest), "at rest": (rest, t[-1])}
    print(f"the plant (touch {touch:.3f} s, the force constant from {rest:.3f} s): normal force rate rms (N/s per "
          f"sqrt(Hz)), largest change per sample (N) and its 0.5-1 times over sqrt(T) (the walk it asks for); "
          f"as an integrated random walk over 20, 50, 100 ms (N/s^2 per sqrt(Hz)); its ramp (N/s); "
          f"tangential force largest {np.abs(F[:, :2]).max():.3g} N")
    for name, (lo, hi) in phases.items():
        m = (t[1:] > lo) & (t[1:] <= hi)
        step = np.abs(np.diff(F[:, 2]))[m]
        _, integrated, ramp = walk_levels(F[:, 2:], t, lo, hi)
        print(f"  {name:17} rate {np.sqrt(np.mean(step ** 2) / 1e-3):.3g}, largest change {step.max():.3g} N: walk "
              f"{0.5 * step.max() / np.sqrt(1e-3):.3g}-{step.max() / np.sqrt(1e-3):.3g}; integrated "
              f"{' / '.join(f'{v:.3g}' for v in integrated)}, ramp {ramp:.3g}")
    ramps = (touch + SETTLE, rest + 0.1)  # the press's ramp and its end: the rate's change the walk must allow
    _, integrated, _ = walk_levels(F[:, 2:], t, *ramps)
    print(f"  the ramp's end ({ramps[0]:.2f}-{ramps[1]:.2f} s): integrated {' / '.join(f'{v:.3g}' for v in integrated)}")
    fn, gap, zd = d["fn"][on], d["gap"][on], d["zd"][on]
    acceleration = np.linalg.norm(np.diff(zd, axis=0), axis=1)[t[1:] > rest] / 1e-3
    print(f"  at rest: the wrist's acceleration rms {np.sqrt(np.mean(acceleration ** 2)):.2g}, largest "
          f"{acceleration.max():.2g} m/s^2 (the rest's pseudo-measurement of zero)")
    st = c._settings
    law = fn - (st.contact_stiffness * -gap + st.contact_damping * -zd[:, 2])
    for value, name in ((2, "CONTACT"), (1, "COLLISION")):
        m = mode == value
        print(f"  contact law k (-gap) + c (-gap') against the plant's force in {name} ({m.sum()} samples): "
              f"largest residual {np.abs(law[m]).max():.3g} N")
    p, z, u = c.robot_params(), d["z"][on], d["u"][on]
    # one prediction from the plant's state with its torque held and its force held at the start (the
    # force a random walk) or at its mid-period value (the force with its rate: ContactEKF's f + r T/2)
    errors = {"force held": [], "force at mid-period": []}
    for k in range(len(t) - 1):
        q = inverse_kinematics(p, z[k])
        v = np.asarray(kernels.kinematics(p, q, np.zeros(9)))[57:].reshape(9, 3) @ zd[k]
        for label, force in (("force held", F[k]), ("force at mid-period", 0.5 * (F[k] + F[k + 1]))):
            out = np.asarray(kernels.predict(p, q, v, list(u[k]), list(force), 1e-3, st.pole, st.substeps))
            kin = np.asarray(kernels.kinematics(p, out[:9], out[9:18]))
            Jv = kin[3:30].reshape(3, 3, 3).transpose(1, 0, 2).reshape(3, 9) / 3.0
            errors[label].append(np.abs(Jv @ out[9:18] - zd[k + 1]).max())
    for label, values in errors.items():
        values = np.array(values) / np.sqrt(1e-3)  # the velocity's error over sqrt(T): m/s^2 per sqrt(Hz)
        for name, (lo, hi) in phases.items():
            m = (t[:-1] >= lo) & (t[:-1] < hi)
            print(f"  process model's one-step velocity error / sqrt(T), {label}, {name:17}: rms "
                  f"{np.sqrt(np.mean(values[m] ** 2)):.2g}, largest {values[m].max():.2g} m/s^2 per sqrt(Hz)")


def contact_replay(d: dict, c: "ContactEstimator", settings, kernels, noise: float, seed: int) -> tuple:
    """(times, force NEES, surface NEES, manoeuvres) of one seeded run from the first sample."""
    readout, ekf, t = Readout(noise, 0.0, seed), None, d["time"]
    rows = []
    for k in range(1, int(round(t[-1] / 1e-3)) + 1):
        i = int(np.searchsorted(t, k * 1e-3 + 1e-9)) - 1
        y = [readout.read(float(v), k, j) for j, v in enumerate(d["y"][i])]
        if ekf is None:
            ekf = ContactEKF(c.robot_params(), settings, y, kernels=kernels)
        est = ekf.step(y, d["u"][i])
        ef, es = est.force - d["force"][i], est.surface_height - d["surface"][i]
        rows.append((t[i], ef @ np.linalg.solve(ekf.P[18:21, 18:21], ef), es * es / ekf.P[21, 21],
                     ef[2] ** 2 / ekf.P[20, 20], float(ekf.resting), float(ekf.manoeuvre)))
    a = np.array(rows)
    return a[:, 0], a[:, 1], a[:, 2], ekf.manoeuvres, a[:, 3], a[:, 4], ekf.rate_restarts, a[:, 5]


def contact_monte_carlo(args) -> None:
    from deltafmi.builder.codegen import use_compiled_functions
    from deltafmi.models.contact_estimator import ContactEstimator

    compiled = use_compiled_functions(ContactEstimator)
    c = contact_component()
    kernels = c.native_functions  # compiled if a C compiler is there: the same numbers, faster
    noise = args.noise or c._settings.y_std
    with tempfile.TemporaryDirectory() as tmp:
        d = contact_truth(Path(tmp))
    contact_statistics(d, kernels)
    on = np.abs(d["time"] / 1e-3 - np.round(d["time"] / 1e-3)) < 1e-6
    rest = float(d["time"][on][np.nonzero(np.abs(np.diff(d["force"][on][:, 2])) > 1e-6)[0][-1] + 1])
    touch = float(d["time"][np.argmax(d["mode"] > 0)])
    integers = {"contact_samples", "substeps", "manoeuvre_samples", "manoeuvre_hold"}
    changes = {k: int(v) if k in integers else float(v) for k, v in (s.split("=", 1) for s in args.set)}
    now = replace(c._settings, **changes)
    variants = [("now (contact_estimation.yaml's settings, with --set)", now),
                ("without the rest level (the steady walks at rest, no zero acceleration)", replace(now, **NO_REST)),
                ("the last release's force: a random walk (0.3 N/s per sqrt(Hz) between manoeuvres), no rate",
                 replace(now, **CONTACT_WALK, **NO_REST)),
                ("before: the previous settings (a 100 N/s walk throughout, 0.05 m/s^2, the law 5 N from 10 N)",
                 replace(now, **{**CONTACT_WALK, **CONTACT_BEFORE, **NO_REST})),
                ("without the manoeuvre detector (the steady level throughout, in every direction)",
                 replace(now, force_rate_std=now.steady_force_rate_std, steady_force_rate_std=0.0)),
                ("the detector without its hold (the fast walk only while the innovations say so)",
                 replace(now, manoeuvre_hold=0))]
    R = args.runs
    print(f"ContactEstimator: {R} runs from the start (touch {touch:.3f} s), noise {noise:g} rad, "
          f"{'compiled' if compiled else 'Python'} kernels; settings changed: {args.set or 'none'}")
    for label, settings in variants[:args.variants]:
        began = time.perf_counter()
        runs = [contact_replay(d, c, settings, kernels, noise, 1000 + r) for r in range(R)]
        t = runs[0][0]
        F, S, N = np.array([r[1] for r in runs]), np.array([r[2] for r in runs]), np.array([r[4] for r in runs])
        resting = np.array([r[5] for r in runs])
        phases = {f"in contact (from {SETTLE} s after the touch)": t >= touch + SETTLE, "free": t < touch,
                  f"impact ({SETTLE} s)": (t >= touch) & (t < touch + SETTLE),
                  "press, ramp": (t >= touch + SETTLE) & (t < rest), "at rest": t >= rest}
        first = [float(r[0][(r[0] > touch) & (r[5] > 0)][0]) if np.any((r[0] > touch) & (r[5] > 0)) else np.nan
                 for r in runs]
        first = f"{np.nanmedian(first):.3f} s" if not np.all(np.isnan(first)) else "never"
        print(f"{label}: {time.perf_counter() - began:.0f} s, manoeuvres detected per run "
              f"{np.mean([r[3] for r in runs]):.1f}, rate restarts by the law per run "
              f"{np.mean([r[6] for r in runs]):.1f}; at rest the rest level on at "
              f"{100 * resting[:, t >= rest].mean():.0f} % of the samples, first at {first} (median), free "
              f"{100 * resting[:, t < touch].mean():.0f} %")
        # the impact's samples before the detector first flags it (no walk at the press's levels predicts
        # the jump; they are the detector's delay), and the rest of the impact's 0.1 s after it
        flagged = [r[0][(r[0] >= touch) & (r[0] < touch + SETTLE) & (r[7] > 0)] for r in runs]
        fired = np.array([f[0] if len(f) else touch + SETTLE for f in flagged])
        impact = (t >= touch) & (t < touch + SETTLE)
        before, after = np.array([impact & (t < f) for f in fired]), np.array([impact & (t >= f) for f in fired])
        if not after.any():
            print("  the impact: no manoeuvre detected in its 0.1 s")
        else:
            print(f"  the impact: the detector fires {1e3 * np.median(fired - touch):.0f} ms after the touch (median; "
                  f"{1e3 * (fired - touch).min():.0f}-{1e3 * (fired - touch).max():.0f}); force NEES over those samples "
                  f"{F[before].mean():.3g} (largest {F[before].max():.3g}), over the impact's rest "
                  f"{F[after].mean():.3g} (largest {F[after].max():.3g})")
        for name, nees, dof in (("force", F, 3), ("normal", N, 1), ("surface", S, 1)):
            lo, hi = chi2.ppf(0.025, dof * R) / R, chi2.ppf(0.975, dof * R) / R
            print(f"  {name:8} mean NEES " + ", ".join(f"{p}: {nees[:, m].mean():.3g}" for p, m in phases.items())
                  + f", at the end {nees[:, -1].mean():.3g}; 95 % interval for dof {dof}: [{lo:.3f}, {hi:.3f}]")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--estimator", choices=("peg", "contact"), default="peg")
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--noise", type=float, default=None, help="encoder noise (rad; default the y_std assumed)")
    parser.add_argument("--start", type=float, default=0.9)
    parser.add_argument("--stop", type=float, default=2.2)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    parser.add_argument("--variants", type=int, default=9, help="how many of the settings variants to run (peg)")
    args = parser.parse_args()
    if args.estimator == "contact":
        contact_monte_carlo(args)
        return
    from deltafmi.builder.codegen import use_compiled_functions
    from deltafmi.models.peg_estimator import PegEstimator

    if not use_compiled_functions(PegEstimator):
        raise SystemExit("PegEstimator: its functions could not be compiled (no C compiler?)")
    c = component()
    args.noise = args.noise or c._settings.y_std
    with tempfile.TemporaryDirectory() as tmp:
        d = peg_truth(Path(tmp), args.stop)
    integers = {"contact_iterations", "jacobian_columns", "reject_samples", "contact_samples", "substeps",
                "manoeuvre_samples"}
    no_rate = dict(force_acceleration_std=0.0, moment_acceleration_std=0.0, force_ramp_std=0.0, moment_ramp_std=0.0)
    changes = {k: int(v) if k in integers else float(v) for k, v in (s.split("=", 1) for s in args.set)}
    force_rates(d)
    model_error(d, c)
    now = replace(c._settings, **changes)
    baseline = replace(now, acceleration_std=0.01, angular_acceleration_std=0.5, steady_force_rate_std=0.0,
                       steady_moment_rate_std=0.0, law_hole_std=0.0, law_tilt_std=0.0, hole_drift_std=0.0,
                       tilt_drift_std=0.0, **no_rate)
    variants = [("now (defaults, with --set)", now),
                ("the last release's wrench: a random walk, 1 N/s and 0.05 N m/s per sqrt(Hz) between manoeuvres",
                 replace(now, steady_force_rate_std=1.0, steady_moment_rate_std=0.05, **no_rate)),
                ("baseline: the previous defaults", baseline),
                ("without the manoeuvre detector (the wrench at 30 N/s, 2 N m/s throughout)",
                 replace(now, steady_force_rate_std=0.0, steady_moment_rate_std=0.0)),
                ("without the rate's restart at a manoeuvre", replace(now, force_ramp_std=0.0, moment_ramp_std=0.0)),
                ("without the law's considered offset", replace(now, law_hole_std=0.0, law_tilt_std=0.0)),
                ("without the hole's random walk", replace(now, hole_drift_std=0.0, tilt_drift_std=0.0)),
                ("with the previous model-error accelerations (0.01, 0.5)",
                 replace(now, acceleration_std=0.01, angular_acceleration_std=0.5)),
                ("with the last release's plate model error (1e-4 m/s^2 per sqrt(Hz))",
                 replace(now, acceleration_std=1e-4))]
    for label, settings in variants[:args.variants]:
        print(label)
        monte_carlo(d, c, settings, args)


if __name__ == "__main__":
    main()
