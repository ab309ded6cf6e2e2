"""Per-sample cost of the assembly's estimators and insertion MPC against the 1 ms of a 1 kHz sample.

Each one is replayed on the inputs a real closed loop gave it: the scenario is run once through
the master (real FMUs) with the inputs recorded, then the estimator's or planner's class
(deltafmi.physics) steps through those inputs in this process, timed per sample. Before and after
in the same run, on the same inputs:

- InsertionMpc (peg_in_hole_mpc.yaml pushing on the bottom: --set mpc.goal_depth=0.06, 4.4 s,
  free and blocked modes switching): baseline OSQP, one solver re-condensed and refactorized at
  every mode switch (``modes=1``); OSQP with one solver per mode set up once, without and with
  polishing; and the default, DAQP (dual active set) with one solver per mode set up at
  construction, warm-started from the last active set;
- PegEstimator (peg_estimation.yaml, 0.9-2.2 s: free, the chamfer, the bore; with its parts, in
  alternating passes, wall clock and the thread's CPU time): baseline its kernels (prediction,
  contact law, hole locator) as Python (the path without a C compiler) against the compiled
  functions its FMU calls (C generated from the same Python), with their estimates compared; and,
  compiled, the extended filter (one linearisation of the contact law, the whole process Jacobian
  every sample) against the defaults (iterated contact update, the Jacobian's columns refreshed
  in turn), with the hole's error each ends with; and the wrench a plain random walk (the
  previous wrench model, 1 N/s and 0.05 N m/s per sqrt(Hz) between manoeuvres, its rate states
  held at zero: the same covariance algebra);
- ContactEstimator (contact_estimation.yaml, the filter's cycle with its estimate and gap as the
  FMU takes them, in alternating passes): baseline the process model's kernels as Python (the
  path without a C compiler) against the compiled functions its FMU calls (C generated from the
  same Python), with their estimates compared; the previous settings and the last release's
  levels (the force a random walk, no rate, no law detector: the same covariance algebra, the
  rate states held at zero) and without the rest level as variants, compiled, and the rest's last
  0.2 s (the rest level on: its zero-acceleration update adds a process-model call) apart.

Prints median and 99th percentile per sample (ms), their ratios to the baseline and to the 1 ms
budget, and the share of samples over 1 ms, and the thread's CPU time per sample, which a loaded
machine's preemption does not inflate (its wall-clock 99th percentile is mostly the time other
processes held the core). The machine's load goes into the wall-clock figures: read the ratios,
and the CPU time.

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
from dataclasses import replace
from typing import Dict, List

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


def figures(times: List[float], cpu: List[float] | None = None) -> Dict[str, float]:
    t = np.asarray(times) * 1e3
    f = {"median": float(np.median(t)), "p99": float(np.percentile(t, 99)), "max": float(t.max()),
         "over": float(np.mean(t > 1.0))}
    if cpu is not None:
        c = np.asarray(cpu) * 1e3
        f.update(cpu_median=float(np.median(c)), cpu_p99=float(np.percentile(c, 99)), cpu_over=float(np.mean(c > 1.0)))
    return f


def report(title: str, rows: Dict[str, Dict[str, float]], ratios: bool = True) -> None:
    """One line per row; with ``ratios``, the first row is the baseline (how many times faster).
    Rows timed with CPU time too (the thread's, which the machine's load does not inflate) print
    its median and 99th percentile, and every row its median and 99th percentile against the
    1 ms budget of a 1 kHz sample (x budget: 1 is exactly real time, below 1 faster)."""
    base = next(iter(rows.values()))
    cpu = any("cpu_median" in f for f in rows.values())
    head = f"{'median x':>10}{'p99 x':>8}" if ratios else ""
    head += f"{'cpu median':>11}{'cpu p99':>9}{'cpu > 1 ms':>11}" if cpu else ""
    print(f"\n{title}\n{'':44}{'median ms':>10}{'p99 ms':>9}{'max ms':>9}{'> 1 ms':>8}{'x budget':>9}{'p99 x b.':>9}"
          f"{head}")
    for label, f in rows.items():
        tail = f"{base['median'] / f['median']:10.2f}{base['p99'] / f['p99']:8.2f}" if ratios else ""
        tail += f"{f['cpu_median']:11.3f}{f['cpu_p99']:9.3f}{100 * f['cpu_over']:10.1f}%" if "cpu_median" in f else ""
        print(f"{label:44}{f['median']:10.3f}{f['p99']:9.3f}{f['max']:9.2f}{100 * f['over']:7.1f}%"
              f"{f['median'] / 1.0:9.2f}{f['p99'] / 1.0:9.2f}{tail}")


# ------------------------------------------------------------------------------------------ MPC
def mpc_inputs(folder: Path, stop: float) -> dict:
    c = record("peg_in_hole_mpc", folder, ["plant.tip_velocity[*]", "plant.ft_sensor[*]"], stop,
               drop=("impedance", "impedance_plant"), mpc={"goal_depth": 0.06})
    return {"time": c["time"], "tip": vector(c, "plant.tip", 3), "velocity": vector(c, "plant.tip_velocity", 3),
            "push_back": -c["plant.ft_sensor[3]"]}


def mpc_replay(data: dict, **changes: object) -> tuple:
    """Step the planner (the scenario's task with ``changes``) through the recorded measurements at
    its 10 ms samples; its own reference moves as the FMU's does (the last plan's polynomial).
    Per-sample seconds (wall clock, and the thread's CPU time: what the load does not inflate),
    planned pushes, QP iterations, whether the plan is an active set's exact solution."""
    from deltafmi.physics.control.insertion import InsertionMpc, InsertionTask
    from deltafmi.physics.control.model_file import LinearModelFile

    spec = yaml.safe_load((EXAMPLES / "peg_in_hole_mpc.yaml").read_text())["components"]["mpc"]["parameters"]
    K, M = spec["axial_stiffness"], spec["axial_mass"]
    task = InsertionTask(hole_top=spec["hole_position"], hole_axis=[0.0, 0.0, 1.0], goal_depth=0.06,
                         axial_stiffness=K, axial_damping=2.0 * math.sqrt(K * M), force_limit=spec["force_limit"],
                         speed_limit=spec["speed_limit"], contact_speed=spec["contact_speed"],
                         bore_speed=spec["bore_speed"], contact_zone=spec["contact_zone"],
                         acceleration_limit=spec["acceleration_limit"], sample_period=spec["sample_period"],
                         horizon=spec["horizon"], bottom_depth=spec["hole_depth"], bottom_speed=spec["bottom_speed"],
                         **changes)
    planner = InsertionMpc(LinearModelFile.read(str(EXAMPLES / "peg_in_hole_mpc_model.npz")), task)
    T = task.sample_period
    r, rd, a = np.array(spec["start"], float), np.zeros(3), np.zeros(3)
    times, cpu, pushes, iterations, polished = [], [], [], [], []
    for k in range(int(data["time"][-1] / T + 1e-9) + 1):
        i = int(np.searchsorted(data["time"], k * T + 1e-9)) - 1  # the last row at the sample instant
        if k:
            r, rd = r + rd * T + 0.5 * a * T * T, rd + a * T
        start, start_cpu = time.perf_counter(), time.thread_time()
        a, plan = planner.step(data["tip"][i], data["velocity"][i], r, rd, push_back=data["push_back"][i])
        times.append(time.perf_counter() - start)
        cpu.append(time.thread_time() - start_cpu)
        pushes.append(planner.planned_force(plan))
        iterations.append(plan.iterations)
        polished.append(plan.polished)
    return times, cpu, pushes, iterations, polished, planner


def mpc(folder: Path, stop: float) -> None:
    data = mpc_inputs(folder, stop)
    rows, cpu_rows, extra, plans = {}, {}, {}, {}
    osqp = dict(solver="osqp")
    for label, changes in (("OSQP rebuilt at mode switches", dict(osqp, modes=1, polish=False, relaxation=1.6)),
                           ("OSQP one solver per mode", dict(osqp, polish=False, relaxation=1.6)),
                           ("OSQP per mode, polished, alpha 1 (before)", osqp),
                           ("now: DAQP per mode, warm (default)", {})):
        times, cpu, push, iterations, polished, planner = mpc_replay(data, **changes)
        rows[label], cpu_rows[label] = figures(times), figures(cpu)
        extra[label] = (max(push), np.median(iterations), np.percentile(iterations, 99), max(iterations),
                        np.mean(polished))
        plans[label] = np.array(push)
    title = f"InsertionMpc, {len(times)} samples of 10 ms (peg_in_hole_mpc.yaml pressing on the bottom)"
    report(title + ", wall clock", rows)
    report(title + ", the thread's CPU time", cpu_rows)
    budget("InsertionMpc (now)", {"wall clock": rows[label], "CPU time": cpu_rows[label]},
           "1 ms (a 1 kHz sample; the MPC's own period is 10 ms)")
    print(f"\n{'':44}{'largest planned push N':>24}{'iterations median':>19}{'p99':>7}{'max':>7}{'exact':>7}")
    for label, (push, med, p99, most, share) in extra.items():
        print(f"{label:44}{push:24.6f}{med:19.0f}{p99:7.0f}{most:7d}{100 * share:6.0f}%")
    labels = list(plans)
    gap = np.abs(plans[labels[-1]] - plans[labels[-2]])
    print(f"planned push, DAQP against OSQP polished: median difference {np.median(gap):.2e} N, largest {gap.max():.2e} N "
          f"(where OSQP's polish failed its plan is ADMM's iterate, and each replay moves its own reference on)")


# ----------------------------------------------------------------------------------- estimators
def peg_truth(folder: Path, stop: float) -> dict:
    c = record("peg_estimation", folder, ["plant.qw[*]", "controller.u[*]", "controller.tau[*]", "plant.z[*]",
                                          "plant.zd[*]", "plant.qwd[*]", "plant.active_contacts"], stop,
               drop=("estimator",))
    return {"time": c["time"], "y": vector(c, "plant.y", 3), "qw": vector(c, "plant.qw", 3),
            "u": vector(c, "controller.u", 3), "tau": vector(c, "controller.tau", 3),
            "force": vector(c, "plant.contact_force", 3), "moment": vector(c, "plant.contact_moment", 3),
            "hole": np.column_stack([vector(c, "plant.hole_position", 3)[:, :2], vector(c, "plant.hole_tilt", 2)]),
            "s": np.hstack([vector(c, "plant.z", 3), vector(c, "plant.qw", 3), vector(c, "plant.zd", 3),
                            vector(c, "plant.qwd", 3)]), "active": c["plant.active_contacts"]}


def component() -> "PegEstimator":  # noqa: F821
    """The scenario's estimator (its parameters as the scenario sets them), initialised."""
    from deltafmi.models.peg_estimator import PegEstimator

    c = PegEstimator()
    c.hole_position, c.hole_tilt, c.mu = [0.0, 0.0, -1.2], [0.0, 0.0], 0.3
    c.initialize(0.0)
    return c


def contact_truth(folder: Path) -> dict:
    c = record("contact_estimation", folder, ["controller.u[*]", "plant.friction_force[*]", "plant.normal_force[*]"],
               5.5, drop=("estimator",))
    return {"time": c["time"], "y": vector(c, "plant.y", 3), "u": vector(c, "controller.u", 3),
            "force": vector(c, "plant.normal_force", 3) + vector(c, "plant.friction_force", 3),
            "surface": c["plant.surface_height"], "mode": c["plant.mode"], "fn": c["plant.fn"], "gap": c["plant.gap"],
            "z": vector(c, "plant.z", 3), "zd": vector(c, "plant.zd", 3)}


def contact_component() -> "ContactEstimator":  # noqa: F821
    """The scenario's ContactEstimator, initialised (its parameters as the scenario sets them)."""
    from deltafmi.models.contact_estimator import ContactEstimator

    c = ContactEstimator()
    spec = yaml.safe_load((EXAMPLES / "contact_estimation.yaml").read_text())
    for name, value in spec["components"]["estimator"]["parameters"].items():
        setattr(c, name, value)
    c.initialize(0.0)
    return c


def timed(step, calls: List[tuple], cpu: List[float] | None = None) -> List[float]:
    """Wall-clock seconds of each ``step(*args)``; with ``cpu``, the thread's CPU seconds appended there."""
    times = []
    for args in calls:
        start, start_cpu = time.perf_counter(), time.thread_time()
        step(*args)
        times.append(time.perf_counter() - start)
        if cpu is not None:
            cpu.append(time.thread_time() - start_cpu)
    return times


def budget(label: str, rows: Dict[str, Dict[str, float]], period: str = "the 1 ms sample period") -> None:
    """The median and 99th percentile of each row as a share of 1 ms (``period`` says what it is)."""
    for name, f in rows.items():
        print(f"{label}: {name}: median {f['median']:.2f}, p99 {f['p99']:.2f} of {period}")


def peg_run(d: dict, c: "PegEstimator", settings, rows: List[int], functions) -> tuple:  # noqa: F821
    """PegEKF with ``settings`` and ``functions`` (its kernels) through the recorded rows: (wall, cpu,
    predict, update) seconds per sample, the filter at the end, and its state and covariance's
    diagonal after every sample."""
    from deltafmi.physics.estimation.peg_ekf import PegEKF

    ekf = PegEKF(c.robot_params(), c._wrist, c._mount, c._hole, c._peg, c._law, settings, d["y"][rows[0]],
                 d["qw"][rows[0]], functions=functions)
    parts: Dict[str, List[float]] = {"predict": [], "update": []}
    for name in parts:
        method = getattr(ekf, name)

        def wrapped(*a, _m=method, _n=name):
            start = time.thread_time()
            _m(*a)
            parts[_n].append(time.thread_time() - start)
        setattr(ekf, name, wrapped)
    states: list = []

    def sample(*args):
        ekf.step(*args)
        states.append(np.concatenate([ekf.x, np.diag(ekf.P)]))
    cpu: List[float] = []
    times = timed(sample, [(d["y"][i], d["qw"][i], d["u"][i], d["tau"][i]) for i in rows], cpu)
    return times, cpu, parts["predict"], parts["update"], ekf, np.array(states)


def peg(folder: Path, stop: float) -> None:
    """PegEKF on peg_estimation.yaml's recorded angles and torques (noise-free) from 0.9 s (before
    the chamfer) to ``stop``, in turns (baseline, now, ...: the load falls on all alike): per
    sample, and its parts (prediction: process Jacobian and Runge-Kutta; measurement update with
    the contact law's). Before: the kernels as Python; now: compiled, as the FMU calls them
    (their estimates must be the same numbers). The extended filter (contact_iterations 1,
    jacobian_columns 18) against the defaults, both compiled: what the iterated update costs, and
    the hole's error at the end says what each buys in accuracy."""

    from deltafmi.builder.codegen import use_compiled_functions
    from deltafmi.models.peg_estimator import PegEstimator
    from deltafmi.physics.estimation.peg_ekf import PYTHON_FUNCTIONS

    if not use_compiled_functions(PegEstimator):
        raise SystemExit("PegEstimator: its functions could not be compiled (no C compiler?)")
    d, c = peg_truth(folder, stop), component()
    assert c.native_functions.compiled
    t = d["time"]
    rows = [int(np.searchsorted(t, k * 1e-3 + 1e-9)) - 1 for k in range(900, int(round(stop / 1e-3)) + 1)]
    ekf_settings = replace(c._settings, contact_iterations=1, jacobian_columns=18)
    walk_settings = replace(c._settings, force_acceleration_std=0.0, moment_acceleration_std=0.0, force_ramp_std=0.0,
                            moment_ramp_std=0.0, steady_force_rate_std=1.0, steady_moment_rate_std=0.05)
    variants = {"before: Python kernels": (c._settings, PYTHON_FUNCTIONS),
                "now: compiled kernels (the FMU's)": (c._settings, c.native_functions),
                "compiled, EKF update, full Jacobian": (ekf_settings, c.native_functions),
                "compiled, the wrench a random walk (its rate states held at zero)": (walk_settings,
                                                                                     c.native_functions)}
    runs: Dict[str, list] = {label: [] for label in variants}
    for _ in range(2):
        for label, (settings, functions) in variants.items():
            runs[label].append(peg_run(d, c, settings, rows, functions))
    table, accuracy = {}, {}
    for label, done in runs.items():
        times, cpu, predict, update = ([x for r in done for x in r[k]] for k in range(4))
        table[label] = figures(times, cpu)
        table["  prediction (CPU)"] = figures(predict)
        table["  measurement + contact-law update (CPU)"] = figures(update)
        ekf = done[-1][4]
        accuracy[label] = (np.linalg.norm(ekf.x[18:20] - d["hole"][rows[-1]][:2]),
                           np.abs(ekf.x[20:22] - np.array([0.01745, 0.0])).max())
        report(f"PegEstimator {label}: {len(times)} samples of 1 ms (peg_estimation.yaml, 0.9-{stop:g} s: free, "
               f"chamfer, bore; 2 passes)", dict(table), ratios=False)
        table.clear()
    labels = list(variants)
    whole = {k: figures([x for r in runs[k] for x in r[0]], [x for r in runs[k] for x in r[1]]) for k in labels}
    report(f"PegEstimator per sample, {len(rows)} samples x 2 passes, against the first row", whole)
    base, now = whole[labels[0]], whole[labels[1]]
    print(f"\ncompiled against Python kernels: CPU time median {base['cpu_median'] / now['cpu_median']:.2f}x, "
          f"p99 {base['cpu_p99'] / now['cpu_p99']:.2f}x faster; wall clock median {base['median'] / now['median']:.2f}x")
    budget("PegEstimator (now)", {"CPU time": {"median": now["cpu_median"], "p99": now["cpu_p99"]},
                                  "wall clock": now})
    python, compiled = runs[labels[0]][-1][5], runs[labels[1]][-1][5]
    scale = np.maximum(np.abs(python).max(axis=0), 1e-300)
    print(f"compiled against Python estimates (state and variances, every sample): largest difference "
          f"{np.max(np.abs(compiled - python) / scale):.1e} of each one's range"
          f"{' (identical)' if np.array_equal(compiled, python) else ''}")
    for label, (hole, tilt) in accuracy.items():
        print(f"{label}: hole error at {stop:g} s {hole * 1e6:.1f} um, tilt error {tilt * 1e3:.2f} mrad (noise-free)")


def contact_run(d: dict, c: "ContactEstimator", rows: List[int], kernels, settings=None) -> tuple:  # noqa: F821
    """ContactEKF with ``kernels`` (and ``settings``, default the scenario's) through the recorded rows
    as the FMU's take_sample runs it (the filter's cycle, its estimate and the gap): (wall, cpu,
    {part: cpu seconds per call; a manoeuvre's window filtered again adds calls}, estimates)."""
    from deltafmi.physics.estimation.contact_ekf import ContactEKF

    ekf = ContactEKF(c.robot_params(), settings or c._settings, d["y"][rows[0]], kernels=kernels)
    parts: Dict[str, List[float]] = {"predict": [], "update": [], "estimate": []}
    for name in parts:
        method = getattr(ekf, name)

        def wrapped(*a, _m=method, _n=name):
            start = time.thread_time()
            out = _m(*a)
            parts[_n].append(time.thread_time() - start)
            return out
        setattr(ekf, name, wrapped)
    estimates: list = []

    def sample(y, u):
        estimates.append((ekf.step(y, u), ekf.gap()))
    cpu: List[float] = []
    times = timed(sample, [(d["y"][i], d["u"][i]) for i in rows], cpu)
    return times, cpu, parts, np.array([np.hstack([np.ravel(value) for value in (*est, gap)]) for est, gap in estimates])


def contact(folder: Path) -> None:
    """ContactEKF on contact_estimation.yaml's recorded angles and torques, the whole run, in turns
    (baseline, now, baseline, now: the load falls on both alike). Baseline: the process model's
    kernels as Python (the path without a C compiler); now: the compiled functions the FMU calls
    (C generated from the same Python). Their estimates must be the same numbers."""
    from deltafmi.builder.codegen import use_compiled_functions
    from deltafmi.models.contact_estimator import ContactEstimator
    from deltafmi.physics.estimation.delta_process_kernels import PYTHON_KERNELS

    if not use_compiled_functions(ContactEstimator):
        raise SystemExit("ContactEstimator: its functions could not be compiled (no C compiler?)")
    d, c = contact_truth(folder), contact_component()
    assert c.native_functions.compiled
    t = d["time"]
    rows = [int(np.searchsorted(t, k * 1e-3 + 1e-9)) - 1 for k in range(1, int(round(t[-1] / 1e-3)) + 1)]
    previous = replace(c._settings, acceleration_std=0.05, force_rate_std=100.0, steady_force_rate_std=0.0,
                       contact_model_std=5.0, contact_threshold=10.0, contact_samples=10, manoeuvre_hold=0)
    walk = replace(c._settings, acceleration_std=1e-4, steady_force_rate_std=0.3, force_acceleration_std=0.0,
                   force_ramp_std=0.0, law_manoeuvre=False, contact_model_std=1e-3)
    variants = {"baseline: Python kernels": (PYTHON_KERNELS, None), "now: compiled kernels": (c.native_functions, None),
                "compiled, the previous settings (one walk level, no manoeuvre detector)": (c.native_functions, previous),
                "compiled, the last release's levels (the force a random walk, no rate)": (c.native_functions, walk),
                "compiled, without the rest level": (c.native_functions, replace(c._settings, rest_force_rate_std=0.0,
                                                                                   rest_acceleration_std=0.0))}
    runs: Dict[str, list] = {label: [] for label in variants}
    for _ in range(2):
        for label, (kernels, settings) in variants.items():
            runs[label].append(contact_run(d, c, rows, kernels, settings))
    figure: Dict[str, Dict[str, float]] = {}
    for label, done in runs.items():
        times, cpu = [x for r in done for x in r[0]], [x for r in done for x in r[1]]
        rows_ = {"per sample, wall clock": figures(times), "per sample, the thread's CPU time": figures(cpu)}
        parts = {f"  {title} (CPU)": figures([x for r in done for x in r[2][name]])
                 for name, title in (("predict", "prediction"), ("update", "measurement + contact-law update"),
                                     ("estimate", "estimate and its deviations"))}
        report(f"ContactEstimator {label}: {len(times)} samples of 1 ms (contact_estimation.yaml, whole run; 2 passes)",
               {**rows_, **parts}, ratios=False)
        budget(f"ContactEstimator {label}", rows_)
        figure[label] = rows_["per sample, the thread's CPU time"]
    base, now, before, last, restless = figure.values()
    resting = np.asarray(t)[rows] >= t[-1] - 0.2  # the rest level is on over the last 0.24 s (estimator_consistency)
    for label in ("now: compiled kernels", "compiled, without the rest level"):
        cpu = figures([x for r in runs[label] for x in np.asarray(r[1])[resting]])
        print(f"ContactEstimator {label}, the last 0.2 s (at rest), the thread's CPU time per sample: "
              f"median {cpu['median']:.3f} ms, p99 {cpu['p99']:.3f} ms")
    print(f"\nnow against baseline (CPU time): median {base['median'] / now['median']:.2f}x, "
          f"p99 {base['p99'] / now['p99']:.2f}x faster; against the previous settings (compiled): median "
          f"{now['median'] / before['median']:.2f}x, p99 {now['p99'] / before['p99']:.2f}x the time; against the "
          f"last release's levels (compiled): median {now['median'] / last['median']:.2f}x, "
          f"p99 {now['p99'] / last['p99']:.2f}x the time; against no rest level: median "
          f"{now['median'] / restless['median']:.2f}x, p99 {now['p99'] / restless['p99']:.2f}x the time")
    python, compiled = (runs[label][-1][3] for label in list(variants)[:2])
    worst = np.max(np.abs(compiled - python) / np.maximum(np.abs(python), 1e-300))
    print(f"estimates, compiled against Python: largest relative difference {worst:.1e} over {python.size} numbers")


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
        if args.only in (None, "peg"):
            peg(folder, args.stop or 2.2)
        if args.only in (None, "contact"):
            contact(folder)


if __name__ == "__main__":
    main()
