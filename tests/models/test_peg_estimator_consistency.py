"""Consistency of the peg estimator (PegEstimator over deltafmi.physics.estimation.PegEKF): the
normalised estimation error squared (NEES) of the hole (x, y, tilt_x, tilt_y) and of the contact
force over seeded Monte Carlo runs against its chi-square interval.

The plant is the real one: scenarios/peg_estimation.yaml run by the master (the DeltaWristPeg
FMU under the AssemblyController FMU, the true hole 1.8 mm off and 1 degree tilted from the
nominal one) without the estimator, which does not act on the loop; its angles, torques, contact
force and hole are recorded once, from the free approach through the chamfer's impact (~1.012 s)
into the bore. The estimator, with the scenario's parameters and its default noise models, is
then replayed on that recording RUNS times, each with its own seeded encoder noise on y and qw,
the noise the filter assumes (y_std, qw_std: 1e-6 rad), drawn as the FMU's sensor_noise draws it.

The test (Bar-Shalom, Li, Kirubarajan, "Estimation with Applications to Tracking and Navigation",
2001, section 5.4.2): for a consistent filter the error e of a d-dimensional estimate is N(0, P),
e' P^-1 e is chi-square with d degrees of freedom, and its mean over R independent runs at one
instant is chi-square(d R) / R, inside [chi2.ppf(0.025, d R), chi2.ppf(0.975, d R)] / R with
probability 0.95. Asserted: the mean over the runs and over the instants in contact (from CONTACT
s, the chamfer's first bounces over, to STOP) inside that interval, for the hole (d = 4) and the
force (d = 3). The instants of one run are strongly correlated (the hole's error moves slowly), so
the average over the instants is about as variable as one instant's: the interval is the one
instant's. Printed: the share of instants inside, the bore alone, the errors.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from scipy.stats import chi2

from deltafmi import resolve_system
from deltafmi.master.results.csv_file import columns
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.models.peg_estimator import PegEstimator
from deltafmi.physics.delta.tactile import Readout
from deltafmi.physics.estimation.peg_ekf import PegEKF

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "peg_estimation.yaml"
RUNS = 5
START, CONTACT, BORE, STOP = 0.9, 1.05, 1.3, 1.5  # s
T = 1e-3


def recorded(scenario: Path, folder: Path, stop: float | None, estimator: str, outputs: list) -> dict:
    """The columns of ``scenario`` run by the master up to ``stop`` (None: its own) without the
    component ``estimator`` and its connections, recording ``outputs``."""
    spec = yaml.safe_load(scenario.read_text())
    if stop is not None:
        spec["experiment"]["stop"] = stop
    del spec["components"][estimator]
    spec["connections"] = [c for c in spec["connections"] if estimator not in (c["from"] + c["to"])]
    spec["outputs"] = outputs
    path = folder / "plant.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    Master(resolve_system(load_scenario(path)), result=path.with_suffix(".csv")).run()
    return columns(path.with_suffix(".csv"))


def plant_run(folder: Path) -> dict:
    """The scenario without the estimator up to STOP: the estimator's inputs and the truth."""
    c = recorded(SCENARIO, folder, STOP, "estimator",
                 ["plant.y[*]", "plant.qw[*]", "controller.u[*]", "controller.tau[*]", "plant.contact_force[*]",
                  "plant.hole_position[*]", "plant.hole_tilt[*]"])

    def vector(name: str, n: int) -> np.ndarray:
        return np.column_stack([c[f"{name}[{i}]"] for i in range(1, n + 1)])

    return {"time": c["time"], "y": vector("plant.y", 3), "qw": vector("plant.qw", 3), "u": vector("controller.u", 3),
            "tau": vector("controller.tau", 3), "force": vector("plant.contact_force", 3),
            "hole": np.column_stack([vector("plant.hole_position", 3)[:, :2], vector("plant.hole_tilt", 2)])}


def estimator() -> PegEstimator:
    """The scenario's estimator component (its parameters as the scenario sets them), initialised."""
    c = PegEstimator()
    for name, value in yaml.safe_load(SCENARIO.read_text())["components"]["estimator"]["parameters"].items():
        setattr(c, name, value)
    c.initialize(0.0)
    return c


def monte_carlo_run(d: dict, c: PegEstimator, seed: int) -> np.ndarray:
    """(time, hole NEES, force NEES, hole x-y error, tilt error) at every sample of one seeded run."""
    noise, ekf, t, rows = Readout(c.y_std, 0.0, seed), None, d["time"], []
    for k in range(int(round(START / T)), int(round(STOP / T)) + 1):
        i = int(np.searchsorted(t, k * T + 1e-9)) - 1  # the row at the sample instant
        read = [noise.read(float(v), k, j) for j, v in enumerate(np.r_[d["y"][i], d["qw"][i]])]
        if ekf is None:
            ekf = PegEKF(c.robot_params(), c._wrist, c._mount, c._hole, c._peg, c._law, c._settings, read[:3], read[3:])
        est = ekf.step(read[:3], read[3:], d["u"][i], d["tau"][i])
        eh, ef = est.hole - d["hole"][i], est.force - d["force"][i]
        rows.append((t[i], eh @ np.linalg.solve(ekf.P[18:22, 18:22], eh), ef @ np.linalg.solve(ekf.P[12:15, 12:15], ef),
                     np.hypot(*eh[:2]), np.abs(eh[2:]).max()))
    return np.array(rows)


def test_hole_and_force_nees_are_within_their_chi_square_intervals(tmp_path):
    d = plant_run(tmp_path)
    c = estimator()
    runs = np.array([monte_carlo_run(d, c, 100 + r) for r in range(RUNS)])  # (run, instant, column)
    t = runs[0, :, 0]
    contact, bore = t >= CONTACT, t >= BORE
    print(f"\nPegEstimator NEES over {RUNS} runs of encoder noise {c.y_std:g} rad, {START}-{STOP} s:")
    means = {}
    for name, column, dof in (("hole (x, y, tilt)", 1, 4), ("force", 2, 3)):
        mean = runs[:, :, column].mean(axis=0)  # per instant, over the runs
        lo, hi = chi2.ppf(0.025, dof * RUNS) / RUNS, chi2.ppf(0.975, dof * RUNS) / RUNS
        means[name] = (mean[contact].mean(), lo, hi)
        print(f"  {name:17}: in contact (from {CONTACT} s) {mean[contact].mean():.3g}, in the bore (from {BORE} s) "
              f"{mean[bore].mean():.3g}; 95 % interval [{lo:.2f}, {hi:.2f}], "
              f"{100 * np.mean((mean[contact] >= lo) & (mean[contact] <= hi)):.0f} % of the instants inside; "
              f"per run {np.round(runs[:, contact, column].mean(axis=1), 2)}")
    print(f"  hole error at {STOP} s: x-y median {np.median(runs[:, -1, 3]) * 1e6:.1f} um (largest "
          f"{runs[:, -1, 3].max() * 1e6:.1f} um), tilt median {np.median(runs[:, -1, 4]) * 1e3:.2f} mrad (largest "
          f"{runs[:, -1, 4].max() * 1e3:.2f} mrad)")
    for name, (value, lo, hi) in means.items():
        assert lo <= value <= hi, f"{name} NEES {value:.3g} outside [{lo:.2f}, {hi:.2f}]"
