"""Per-sample cost of the assembly's estimators and insertion MPC against the 1 ms of a 1 kHz sample.

Each one is replayed on the inputs a real closed loop gave it: the scenario is run once through
the master (real FMUs) with the inputs recorded, then the estimator's or planner's class
(deltafmi.physics) steps through those inputs in this process, timed per sample. Before and after
in the same run, on the same inputs:

- InsertionMpc (peg_in_hole_mpc.yaml pushing on the bottom: --set mpc.goal_depth=0.06, 4.4 s,
  free and blocked modes switching): baseline one OSQP solver re-condensed and refactorized at
  every mode switch (``modes=1``), against one solver per mode set up once (the default), each
  with and without polishing;
- PegEstimator (peg_estimation.yaml, 3 s) and ContactEstimator (contact_estimation.yaml):
  baseline the pure-Python kernels, against the compiled ones (when a C compiler is there).

Prints median and 99th percentile per sample (ms), their ratios to the baseline, and the share of
samples over 1 ms. The machine's load goes into the figures: read the ratios.

Usage: python benchmarks/assembly_realtime.py [--only mpc|peg|contact] [--stop SECONDS]
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable, Dict, List

import numpy as np
import yaml

from deltafmi import resolve_system
from deltafmi.master.results.csv_file import columns
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "scenarios"


def record(name: str, folder: Path, outputs: List[str], stop: float, drop: tuple = (), **parameters: dict) -> dict:
    """Run scenarios/<name>.yaml with ``outputs`` added (and components ``drop``-ped), columns."""
    spec = yaml.safe_load((EXAMPLES / f"{name}.yaml").read_text())
    spec["experiment"]["stop"] = stop
    for component, values in parameters.items():
        spec["components"][component]["parameters"].update(values)
    for component in drop:
        del spec["components"][component]
    spec["connections"] = [c for c in spec["connections"]
                           if c["from"].split(".")[0] not in drop and c["to"].split(".")[0] not in drop]
    spec["outputs"] = [o for o in spec["outputs"] if o.split(".")[0] not in drop] + outputs
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    for resource in spec["components"].get("mpc", {}).get("resources", []):
        (folder / resource).write_bytes((EXAMPLES / resource).read_bytes())
    out = path.with_suffix(".csv")
    Master(resolve_system(load_scenario(path)), result=out).run()
    return columns(out)


def vector(c: dict, name: str, n: int) -> np.ndarray:
    return np.column_stack([c[f"{name}[{i}]"] for i in range(1, n + 1)])


def figures(times: List[float]) -> Dict[str, float]:
    t = np.asarray(times) * 1e3
    return {"median": float(np.median(t)), "p99": float(np.percentile(t, 99)), "max": float(t.max()),
            "over": float(np.mean(t > 1.0))}


def report(title: str, rows: Dict[str, Dict[str, float]]) -> None:
    base = next(iter(rows.values()))
    print(f"\n{title}\n{'':44}{'median ms':>10}{'p99 ms':>9}{'max ms':>9}{'> 1 ms':>8}{'median x':>10}{'p99 x':>8}")
    for label, f in rows.items():
        print(f"{label:44}{f['median']:10.3f}{f['p99']:9.3f}{f['max']:9.2f}{100 * f['over']:7.1f}%"
              f"{base['median'] / f['median']:10.2f}{base['p99'] / f['p99']:8.2f}")


# ------------------------------------------------------------------------------------------ MPC
def mpc_inputs(folder: Path, stop: float) -> dict:
    c = record("peg_in_hole_mpc", folder, ["plant.tip_velocity[*]", "plant.ft_sensor[*]"], stop,
               drop=("impedance", "impedance_plant"), mpc={"goal_depth": 0.06})
    return {"time": c["time"], "tip": vector(c, "plant.tip", 3), "velocity": vector(c, "plant.tip_velocity", 3),
            "push_back": -c["plant.ft_sensor[3]"]}


def mpc_replay(data: dict, modes: int, polish: bool, **options: object) -> tuple:
    """Step the planner through the recorded measurements at its 10 ms samples; its own reference
    moves as the FMU's does (the last plan's polynomial). Per-sample seconds, planned pushes."""
    from deltafmi.physics.control.insertion import InsertionMpc, InsertionTask
    from deltafmi.physics.control.model_file import LinearModelFile

    mpc_spec = yaml.safe_load((EXAMPLES / "peg_in_hole_mpc.yaml").read_text())["components"]["mpc"]["parameters"]
    K, M, zeta = mpc_spec["axial_stiffness"], mpc_spec["axial_mass"], 1.0
    task = InsertionTask(hole_top=mpc_spec["hole_position"], hole_axis=[0.0, 0.0, 1.0], goal_depth=0.06,
                         axial_stiffness=K, axial_damping=2.0 * zeta * math.sqrt(K * M),
                         force_limit=mpc_spec["force_limit"], speed_limit=mpc_spec["speed_limit"],
                         contact_speed=mpc_spec["contact_speed"], bore_speed=mpc_spec["bore_speed"],
                         contact_zone=mpc_spec["contact_zone"], acceleration_limit=mpc_spec["acceleration_limit"],
                         sample_period=mpc_spec["sample_period"], horizon=mpc_spec["horizon"],
                         bottom_depth=mpc_spec["hole_depth"], bottom_speed=mpc_spec["bottom_speed"],
                         polish=polish, modes=modes)
    planner = InsertionMpc(LinearModelFile.read(str(EXAMPLES / "peg_in_hole_mpc_model.npz")), task)
    for name, value in options.items():
        planner.mpc._options[name] = value
    if options:
        planner.mpc._switch(planner.mpc._stages, planner.mpc._weights)
        planner.mpc._modes.clear()
        planner.mpc._solver = planner.mpc._new_solver()
    T = task.sample_period
    r, rd, a = np.array(mpc_spec["start"], float), np.zeros(3), np.zeros(3)
    times, pushes, iterations = [], [], []
    for k in range(int(data["time"][-1] / T + 1e-9) + 1):
        i = int(np.searchsorted(data["time"], k * T + 1e-9)) - 1  # the last row at the sample instant
        if k:
            r, rd = r + rd * T + 0.5 * a * T * T, rd + a * T
        start = time.perf_counter()
        a, plan = planner.step(data["tip"][i], data["velocity"][i], r, rd, push_back=data["push_back"][i])
        times.append(time.perf_counter() - start)
        pushes.append(max(planner.axial_force(x) for x in plan.x[1:]))
        iterations.append(plan.iterations)
    return times, pushes, iterations


def mpc(folder: Path, stop: float) -> None:
    data = mpc_inputs(folder, stop)
    rows, pushes = {}, {}
    for label, modes, polish in (("baseline: rebuilt at mode switches", 1, False),
                                 ("one solver per mode", 8, False),
                                 ("rebuilt at mode switches, polished", 1, True),
                                 ("one solver per mode, polished", 8, True)):
        times, push, _ = mpc_replay(data, modes, polish)
        rows[label], pushes[label] = figures(times), max(push)
    report(f"InsertionMpc, {len(times)} samples of 10 ms (peg_in_hole_mpc.yaml pressing on the bottom)", rows)
    print("largest planned push over the run: " + ", ".join(f"{k}: {v:.4f} N" for k, v in pushes.items()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", choices=("mpc", "peg", "contact"), default=None)
    parser.add_argument("--stop", type=float, default=None, help="simulated seconds of each recorded run")
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.only in (None, "mpc"):
            mpc(folder, args.stop or 4.4)


if __name__ == "__main__":
    main()
