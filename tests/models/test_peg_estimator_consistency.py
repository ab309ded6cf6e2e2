"""Consistency of the peg estimator (PegEstimator over deltafmi.physics.estimation.PegEKF): the
normalised estimation error squared (NEES) of the hole (x, y, tilt_x, tilt_y) and of the contact
force over seeded Monte Carlo runs against its chi-square interval, on the chamfer and in the bore.

The plant is the real one: scenarios/peg_estimation.yaml run by the master (the DeltaWristPeg
FMU under the AssemblyController FMU, the true hole 1.8 mm off and 1 degree tilted from the
nominal one) without the estimator, which does not act on the loop; its angles, torques, contact
force and hole are recorded once, from the free approach through the chamfer's impact (~1.012 s),
the slide down the chamfer, the peg's fall off it and its impact on the bore's wall (~1.26 s), into
the bore, where it slides with the force following a slow ramp. The estimator, with the scenario's
parameters, its default noise models and its compiled kernels (as its FMU runs them; the Python
ones give the same bits, tests/models/test_peg_estimator.py), is then replayed on that recording
RUNS times, each with its own seeded encoder noise on y and qw, the noise the filter assumes
(y_std, qw_std: 1e-6 rad), drawn as the FMU's sensor_noise draws it.

The test (Bar-Shalom, Li, Kirubarajan, "Estimation with Applications to Tracking and Navigation",
2001, section 5.4.2): for a consistent filter the error e of a d-dimensional estimate is N(0, P),
e' P^-1 e is chi-square with d degrees of freedom, and its mean over R independent runs at one
instant is chi-square(d R) / R, inside [chi2.ppf(0.025, d R), chi2.ppf(0.975, d R)] / R with
probability 0.95. The instants of one run are strongly correlated (the hole's error moves slowly),
so the average over the instants is about as variable as one instant's: the interval is the one
instant's. The runs' hole NEES spread over two decades (0.1 to 13 over the bore): 16 runs.

Asserted, the mean over the runs and over the instants inside the interval, for the hole (d = 4)
and the force (d = 3):

- sliding (the chamfer, CHAMFER, and the bore, BORE): the contact's phases the wrench's model
  describes. The impacts (the first touch before CHAMFER[0], the fall and the wall's impact
  between CHAMFER[1] and BORE[0]) are left out: no walk predicts a step, and the samples before
  the manoeuvre detector flags one carry NEES of thousands (their windows' mean printed);
- the bore alone, the hole over BORE (to 1.5 s) and the force over BORE_FORCE (to STOP): at about
  1.6 s the peg takes a new contact in the bore and the hole's covariance falls to its considered
  floor (law_hole_std) some 100 ms before its estimate reaches the hole (NEES 15-35 over 1.6-1.8 s),
  then the estimate sits micrometres from the hole under that 30 um floor (NEES ~0.01): the mean
  after 1.5 s printed, docs/assembly.md's Limits.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
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
RUNS = 16
START, STOP = 0.9, 2.2  # s
CHAMFER, BORE, BORE_FORCE = (1.05, 1.2), (1.3, 1.5), (1.3, STOP)  # s, [start, end)
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


@pytest.fixture(scope="module")
def estimator():
    """The scenario's estimator component (its parameters as the scenario sets them), initialised, with
    its kernels compiled (C generated from peg_kernels' Python); the class goes back to Python after."""
    from deltafmi.builder.codegen import use_compiled_functions
    from deltafmi.runtime.native_functions import register_library

    assert use_compiled_functions(PegEstimator)
    try:
        c = PegEstimator()
        for name, value in yaml.safe_load(SCENARIO.read_text())["components"]["estimator"]["parameters"].items():
            setattr(c, name, value)
        c.initialize(0.0)
        yield c
    finally:
        register_library(PegEstimator, None)


def monte_carlo_run(d: dict, c: PegEstimator, seed: int) -> np.ndarray:
    """(time, hole NEES, force NEES, hole x-y error, tilt error) at every sample of one seeded run."""
    noise, ekf, t, rows = Readout(c.y_std, 0.0, seed), None, d["time"], []
    samples = np.arange(int(round(START / T)), int(round(STOP / T)) + 1)
    at = np.searchsorted(t, samples * T + 1e-9) - 1  # the rows at the sample instants
    angles = np.hstack([d["y"], d["qw"]]).tolist()
    for k, i in zip(samples.tolist(), at.tolist()):
        read = [noise.read(v, k, j) for j, v in enumerate(angles[i])]
        if ekf is None:
            ekf = PegEKF(c.robot_params(), c._wrist, c._mount, c._hole, c._peg, c._law, c._settings, read[:3], read[3:],
                         functions=c.native_functions)
        est = ekf.step(read[:3], read[3:], d["u"][i], d["tau"][i])
        eh, ef = est.hole - d["hole"][i], est.force - d["force"][i]
        rows.append((t[i], eh @ np.linalg.solve(ekf.P[18:22, 18:22], eh), ef @ np.linalg.solve(ekf.P[12:15, 12:15], ef),
                     np.hypot(*eh[:2]), np.abs(eh[2:]).max()))
    return np.array(rows)


def test_hole_and_force_nees_are_within_their_chi_square_intervals(tmp_path, estimator):
    c = estimator
    assert c.native_functions.compiled
    d = plant_run(tmp_path)
    runs = np.array([monte_carlo_run(d, c, 100 + r) for r in range(RUNS)])  # (run, instant, column)
    t = runs[0, :, 0]

    def within(window: tuple[float, float]) -> np.ndarray:
        return (t >= window[0]) & (t < window[1] + 0.5 * T)

    chamfer, bore, bore_force = within(CHAMFER), within(BORE), within(BORE_FORCE)
    windows = {"hole": (chamfer | bore, bore, 1, 4), "force": (chamfer | bore_force, bore_force, 2, 3)}
    print(f"\nPegEstimator NEES over {RUNS} runs of encoder noise {c.y_std:g} rad, {START}-{STOP} s:")
    checked = []
    for name, (sliding, steady, column, dof) in windows.items():
        nees = runs[:, :, column]
        mean = nees.mean(axis=0)  # per instant, over the runs
        lo, hi = chi2.ppf(0.025, dof * RUNS) / RUNS, chi2.ppf(0.975, dof * RUNS) / RUNS
        phases = {"chamfer": chamfer, "impacts": within((CHAMFER[1], BORE[0])) | within((1.0, CHAMFER[0])),
                  "bore to 1.5 s": bore, "bore after 1.5 s": within((BORE[1], STOP)) & ~bore}
        print(f"  {name}: 95 % interval for dof {dof} [{lo:.2f}, {hi:.2f}]; sliding {mean[sliding].mean():.3g}, "
              f"bore {mean[steady].mean():.3g} (asserted); "
              + ", ".join(f"{p} {mean[m].mean():.3g}" for p, m in phases.items())
              + f"; per run in the bore {np.round(nees[:, steady].mean(axis=1), 2)}")
        checked += [(f"{name} sliding", mean[sliding].mean(), lo, hi), (f"{name} bore", mean[steady].mean(), lo, hi)]
    end = int(np.argmin(np.abs(t - BORE[1])))
    print(f"  hole error at {BORE[1]} s: x-y median {np.median(runs[:, end, 3]) * 1e6:.1f} um (largest "
          f"{runs[:, end, 3].max() * 1e6:.1f} um), tilt median {np.median(runs[:, end, 4]) * 1e3:.2f} mrad (largest "
          f"{runs[:, end, 4].max() * 1e3:.2f} mrad)")
    for name, value, lo, hi in checked:
        assert lo <= value <= hi, f"{name} NEES {value:.3g} outside [{lo:.2f}, {hi:.2f}]"
