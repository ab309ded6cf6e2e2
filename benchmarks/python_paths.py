"""The paths where an FMU runs its Python between the compiled kernels: this tree against another.

Since the FMUs' kernels are C generated from the Python (deltafmi/builder/codegen), what the FMU
still runs in Python is: the Co-Simulation solver's Jacobian callback (DeltaRobot's exact
``jacobian``: deltafmi/physics/delta/jacobian.py, floats and numpy) and, with
``DELTAFMI_NATIVE_PROJECT=0``, its projection callback; Model Exchange directional derivatives (the
same ``jacobian``); every kernel's Python method with ``DELTAFMI_NATIVE=0`` (the fallback of a
build without a compiler); and the models that declare no kernels, such as the estimators, whose
EKFs call the delta mechanics (kinematics, dynamics) from numpy code, and the insertion MPC. This script times those
paths through fmpy, in the FMUs of this tree and of ``--baseline`` (another checkout, for example
an older commit whose FMUs carried compiled mechanics modules), alternated within each round, each case
in a fresh process (so that each FMU imports its own copy of deltafmi):

- ``cs DeltaRobot`` / ``cs DeltaWrist``: ``fmpy.simulate_fmu`` in Co-Simulation over ``--stop`` s
  with 1 ms steps, falling from rest (as benchmarks/projection.py), in the modes ``native`` (all
  kernels compiled), ``py-project`` (``DELTAFMI_NATIVE_PROJECT=0``) and ``python``
  (``DELTAFMI_NATIVE=0``);
- ``me dd``: DeltaRobot in Model Exchange, one ``fmi2GetDirectionalDerivative`` call per state
  (the derivatives' and the outputs' column), per call, after initialization;
- ``PegEstimator`` / ``ContactEstimator`` / ``InsertionMpc`` (models whose samples run Python:
  the estimators' numpy covariance algebra around their compiled functions, the MPC's QP):
  Co-Simulation over their default experiments in 1 ms steps (the estimators sample every ms),
  inputs at their defaults, time per ms.

Printed: the medians over ``--repeats`` rounds for each tree, wall and CPU time, and the ratios
this/baseline (medians of the rounds' ratios); above 1 this tree is slower.

Usage: python benchmarks/python_paths.py --baseline /path/to/other/checkout [--repeats 5] [--stop 2.0]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("DeltaRobot", "DeltaWrist", "PegEstimator", "ContactEstimator", "InsertionMpc")
MODES = {"native": {}, "py-project": {"DELTAFMI_NATIVE_PROJECT": "0"}, "python": {"DELTAFMI_NATIVE": "0"}}
START = {"DeltaRobot": {}, "DeltaWrist": {"qw0[1]": 0.4, "qw0[2]": -0.3}}


def cases() -> list[tuple[str, str, str]]:
    """(label, model, mode) of every case."""
    out = [(f"cs {plant} {mode}", plant, mode) for plant in ("DeltaRobot", "DeltaWrist") for mode in MODES]
    out.append(("me dd (per call)", "DeltaRobot", "dd"))
    out += [(f"{name} (per ms)", name, "sample") for name in ("PegEstimator", "ContactEstimator", "InsertionMpc")]
    return out


def build(tree: Path) -> dict[str, str]:
    """The FMUs of ``tree`` (its own build cache), built in a process that imports that tree."""
    code = ("import json, sys\nfrom deltafmi.builder.packager import build_cached\n"
            f"print(json.dumps({{n: str(build_cached(n)) for n in {list(MODELS)!r}}}))")
    env = dict(os.environ, PYTHONPATH=str(tree), DELTAFMI_CACHE=str(tree / ".cache"))
    done = subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def measure(fmu: str, model: str, mode: str, stop: float) -> tuple[float, float]:
    """(wall, CPU) seconds of one case in this process, per call or sample where the case says so
    (the CPU time of this process: the FMUs run in it; less sensitive than the wall time to
    other processes on a shared machine)."""
    from fmpy import extract, read_model_description, simulate_fmu
    from fmpy.fmi2 import FMU2Model

    directory = extract(fmu)
    md = read_model_description(directory)
    if mode in MODES:
        os.environ.update(MODES[mode])
        begin, cpu = time.perf_counter(), time.process_time()
        simulate_fmu(directory, model_description=md, fmi_type="CoSimulation", stop_time=stop,
                     output_interval=1e-3, start_values=START[model], output=["residual"])
        return time.perf_counter() - begin, time.process_time() - cpu
    if mode == "sample":
        experiment = md.defaultExperiment
        samples = round((float(experiment.stopTime) - float(experiment.startTime)) / 1e-3)
        begin, cpu = time.perf_counter(), time.process_time()
        simulate_fmu(directory, model_description=md, fmi_type="CoSimulation", output_interval=1e-3)
        return (time.perf_counter() - begin) / samples, (time.process_time() - cpu) / samples
    model_ = FMU2Model(guid=md.guid, unzipDirectory=directory, modelIdentifier=md.modelExchange.modelIdentifier)
    model_.instantiate()
    model_.setupExperiment(startTime=0.0)
    model_.enterInitializationMode()
    model_.exitInitializationMode()
    while model_.newDiscreteStates()[0]:
        pass
    model_.enterContinuousTimeMode()
    states = [u.variable.derivative.valueReference for u in md.derivatives]
    unknowns = [u.variable.valueReference for u in md.derivatives] + [
        v.valueReference for v in md.modelVariables
        if v.causality == "output" and v.type == "Real" and v.variability == "continuous"]
    calls = 0
    begin, cpu = time.perf_counter(), time.process_time()
    for _ in range(20):
        for state in states:
            model_.getDirectionalDerivative(unknowns, [state], [1.0])
            calls += 1
    return (time.perf_counter() - begin) / calls, (time.process_time() - cpu) / calls


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, help="the other checkout")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--stop", type=float, default=2.0)
    parser.add_argument("--case", nargs=3, metavar=("FMU", "MODEL", "MODE"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        print(*measure(*args.case, stop=args.stop))
        return
    if args.baseline is None:
        parser.error("--baseline is required")
    fmus = {"this": build(ROOT), "baseline": build(args.baseline.resolve())}
    times: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for _ in range(args.repeats):
        for label, model, mode in cases():
            for tree in ("baseline", "this"):
                env = {k: v for k, v in os.environ.items() if not k.startswith("DELTAFMI_NATIVE")}
                done = subprocess.run([sys.executable, __file__, "--stop", str(args.stop), "--case",
                                       fmus[tree][model], model, mode], env=env, check=True,
                                      capture_output=True, text=True)
                wall, cpu = map(float, done.stdout.strip().splitlines()[-1].split())
                times.setdefault((label, tree), []).append((wall, cpu))
    print(f"medians of {args.repeats} rounds; CS runs over {args.stop} s; baseline: {args.baseline}")
    print(f"{'case':<32} {'wall: baseline':>15} {'this':>11} {'ratio':>6}   {'CPU: baseline':>14} {'this':>11} {'ratio':>6}")
    for label, _, mode in cases():
        before, after = times[(label, "baseline")], times[(label, "this")]
        unit, scale = ("s", 1.0) if mode in MODES else ("us", 1e6)
        row = f"{label:<32}"
        for k in (0, 1):
            ratio = statistics.median(a[k] / b[k] for a, b in zip(after, before))
            row += (f" {statistics.median(b[k] for b in before) * scale:13.3f}{unit:>2} "
                    f"{statistics.median(a[k] for a in after) * scale:9.3f}{unit:>2} {ratio:6.2f}  ")
        print(row)

if __name__ == "__main__":
    main()
