"""Consistency of the contact estimator on its shipped scenario's real plant (ContactEstimator over
deltafmi.physics.estimation.ContactEKF): the normalised estimation error squared (NEES) of the
wrist force and of the table's height over seeded Monte Carlo runs against its chi-square interval.

The plant is the real one: scenarios/contact_estimation.yaml run by the master (the
DeltaRobotContact FMU under the DeltaController FMU in impedance mode: an approach, the impact on
the table, a press that ramps to 24.8 N and rests) without the estimator, which does not act on
the loop; its servo angles and torques, contact force and table height are recorded once. The
estimator, with the scenario's parameters, is then replayed on that recording from the start RUNS
times, each with its own seeded servo-angle noise (y_std, the noise the filter assumes, drawn as
the FMU's sensor_noise draws it), on the component's compiled kernels (the FMU's).

The test (Bar-Shalom, Li, Kirubarajan 2001, section 5.4.2; as
tests/models/test_peg_estimator_consistency.py): for a consistent filter the mean NEES over R
runs of a d-dimensional error lies in [chi2.ppf(0.025, d R), chi2.ppf(0.975, d R)] / R with
probability 0.95. Asserted: the mean over the runs and over the instants inside that interval, in contact (from
0.1 s after the touch: the impact's transient over, which no random walk follows, to the end),
over the press's ramp (with its end's swing) and at rest (the force constant: the filter's rest
level, the torques still, with the wrist's acceleration a pseudo-measurement of zero), for the
force (d = 3), its normal component (d = 1, in contact and at rest) and the table height (d = 1);
and over the impact's 0.1 s after the manoeuvre detector first fires the force's NEES below the
interval's upper end (its fast walk, held over the transient, is wider than the error: under-confident,
never over). The impact's samples before the detector fires (its delay, within manoeuvre_samples of
the touch) are left out: no walk at the press's levels predicts a jump of 10 N in one sample.
The instants of one run are strongly correlated, so the average over them is about as variable as
one instant's: the interval is one instant's. Printed: the NEES by phase (free flight, the impact,
the ramp, at rest).
"""
from __future__ import annotations

import numpy as np
import pytest
import yaml
from scipy.stats import chi2

from deltafmi.physics.delta.tactile import Readout
from deltafmi.physics.estimation.contact_ekf import ContactEKF

from test_peg_estimator_consistency import ROOT, T, recorded

SCENARIO = ROOT / "scenarios" / "contact_estimation.yaml"
RUNS = 5
SETTLE = 0.1  # s after the touch: the impact's transient


def plant_run(folder) -> dict:
    """The scenario without the estimator: the estimator's inputs and the truth."""
    c = recorded(SCENARIO, folder, None, "estimator",
                 ["plant.y[*]", "controller.u[*]", "plant.normal_force[*]", "plant.friction_force[*]",
                  "plant.surface_height", "plant.mode"])
    t = c["time"]
    on_grid = np.abs(t / T - np.round(t / T)) < 1e-6

    def vector(name: str) -> np.ndarray:
        return np.column_stack([c[f"{name}[{i}]"] for i in (1, 2, 3)])[on_grid]

    return {"time": t[on_grid], "y": vector("plant.y"), "u": vector("controller.u"),
            "force": vector("plant.normal_force") + vector("plant.friction_force"),
            "surface": c["plant.surface_height"][on_grid], "mode": c["plant.mode"][on_grid]}


@pytest.fixture(scope="module")
def estimator():
    """The scenario's estimator component, initialised, with its compiled kernels."""
    from deltafmi.builder.codegen import use_compiled_functions
    from deltafmi.models.contact_estimator import ContactEstimator
    from deltafmi.runtime.native_functions import register_library

    assert use_compiled_functions(ContactEstimator)
    try:
        c = ContactEstimator()
        for name, value in yaml.safe_load(SCENARIO.read_text())["components"]["estimator"]["parameters"].items():
            setattr(c, name, value)
        c.initialize(0.0)
        kernels = c.native_functions
    finally:
        register_library(ContactEstimator, None)
    assert kernels.compiled
    return c, kernels


def monte_carlo_run(d: dict, c, kernels, seed: int) -> np.ndarray:
    """(force NEES, surface NEES, normal force NEES, manoeuvre detected) at every sample of one seeded run,
    from the first sample on."""
    noise, ekf, rows = Readout(c.y_std, 0.0, seed), None, []
    for k, (y, u, force, surface) in enumerate(zip(d["y"], d["u"], d["force"], d["surface"])):
        read = [noise.read(float(v), k, j) for j, v in enumerate(y)]
        if ekf is None:
            ekf = ContactEKF(c.robot_params(), c._settings, read, kernels=kernels)
        est = ekf.step(read, u)
        ef, es = est.force - force, est.surface_height - surface
        rows.append((ef @ np.linalg.solve(ekf.P[18:21, 18:21], ef), es * es / ekf.P[21, 21], ef[2] ** 2 / ekf.P[20, 20],
                     float(ekf.manoeuvre)))
    return np.array(rows)


def test_force_and_surface_nees_are_within_their_chi_square_intervals(tmp_path, estimator):
    c, kernels = estimator
    d = plant_run(tmp_path)
    runs = np.array([monte_carlo_run(d, c, kernels, 100 + r) for r in range(RUNS)])  # (run, instant, column)
    t = d["time"][1:]  # the first sample only starts the filter
    runs = runs[:, 1:]
    touch = float(t[np.argmax(d["mode"][1:] > 0)])
    force = d["force"][1:, 2]
    rest = float(t[np.nonzero(np.abs(np.diff(force)) > 1e-6)[0][-1] + 1])
    phases = {"free": t < touch, f"impact ({SETTLE} s)": (t >= touch) & (t < touch + SETTLE),
              "ramp": (t >= touch + SETTLE) & (t < rest), "at rest": t >= rest}
    contact = t >= touch + SETTLE
    asserted = {"in contact": contact, "ramp": phases["ramp"]}
    print(f"\nContactEstimator NEES over {RUNS} runs of servo noise {c.y_std:g} rad (touch {touch:.3f} s, "
          f"at rest from {rest:.3f} s):")
    means = []
    for name, column, dof in (("force", 0, 3), ("table height", 1, 1), ("normal force", 2, 1)):
        mean = runs[:, :, column].mean(axis=0)
        lo, hi = chi2.ppf(0.025, dof * RUNS) / RUNS, chi2.ppf(0.975, dof * RUNS) / RUNS
        at_rest = {**asserted, "at rest": phases["at rest"]}
        checked = {0: at_rest, 1: at_rest, 2: {"in contact": contact, "at rest": phases["at rest"]}}[column]
        means += [(f"{name} {p}", mean[m].mean(), lo, hi) for p, m in checked.items()]
        print(f"  {name:12}: in contact (from {SETTLE} s after the touch) {mean[contact].mean():.3g}; "
              + ", ".join(f"{p} {mean[m].mean():.3g}" for p, m in phases.items())
              + f"; 95 % interval [{lo:.2f}, {hi:.2f}]; per run {np.round(runs[:, contact, column].mean(axis=1), 2)}")
    # the impact: its samples from the touch until the detector first fires in each run are its delay
    # (the innovations' sum over manoeuvre_samples crossing its gate), which no walk at the press's
    # levels predicts; after it the fast walk covers the error (from above: the walk is held for the
    # impact's transient)
    impact = phases[f"impact ({SETTLE} s)"]
    fired = [t[impact & (run[:, 3] > 0)][0] for run in runs]
    after = np.concatenate([run[impact & (t >= f), 0] for run, f in zip(runs, fired)])
    before = np.concatenate([run[impact & (t < f), 0] for run, f in zip(runs, fired)])
    hi = chi2.ppf(0.975, 3 * RUNS) / RUNS
    delay = np.array(fired) - touch
    print(f"  impact: the detector fires {1e3 * delay.min():.0f}-{1e3 * delay.max():.0f} ms after the touch; force NEES "
          f"before it {before.mean():.3g} (left out), after it to {SETTLE} s {after.mean():.3g} (asserted <= {hi:.2f})")
    assert delay.max() <= c.manoeuvre_samples * T
    means.append(("force in the impact after the detector fires", after.mean(), 0.0, hi))
    for name, value, lo, hi in means:
        assert lo <= value <= hi, f"{name} NEES {value:.3g} outside [{lo:.2f}, {hi:.2f}]"
