"""Parallel units: ``master: {threads: 2}`` against ``threads: 1``, the same scenario run both ways.

Two systems of 8 independent Co-Simulation units, 1 ms communication steps:

- ``c``: 8 instances of the C Oscillator of tests/third_party (a plain C FMU in the Reference FMUs'
  style, no Python inside: its fmi2DoStep lets go of the GIL), each integrating with Runge-Kutta
  substeps of --substep seconds so that a step costs measurable time; coupled in a ring (Jacobi)
  or not at all (Gauss-Seidel). It shows what the threads themselves give; the same with one
  Runge-Kutta step per communication step ("cheap steps") shows what handing steps to the threads
  costs, in the C loop (POSIX threads) and in the Python loop (a thread pool).
- ``delta``: 8 compiled DeltaRobot units as Co-Simulation FMUs (built from deltafmi.models), in
  free fall. A deltafmi FMU that runs its component's Python in every fmi2DoStep holds the GIL,
  and the master steps it on its own thread whatever ``threads`` says (ratio near 1); one that
  takes its steps in C (Python at events only) steps on the threads. The line says which.

Each is run by the master's C loop, by the C loop with its threads meeting at every step
("C lockstep": what it did before units that exchange nothing stepped through blocks of steps; the
Jacobi ring is one component and always steps in lockstep) and by the Python loop
(``Master(native=False)``), threads 1 and 2 interleaved, --repeats times; printed: the median
stepping wall time (set-up excluded), the ratio threads 1 / threads 2 (above 1: faster with two
threads), the median CPU time of the process while stepping (all its threads: what the threads
cost beyond the steps themselves), and whether the results are equal bit for bit. The load average
is printed: on a shared machine the ratio is what the other processes leave of the second core.

Usage: python benchmarks/parallel_units.py [--repeats 5] [--stop 2] [--substep 2e-7] [--systems c,delta]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Dict, List, Tuple

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "third_party"))
from build import build_fmu  # noqa: E402  (the C FMUs of tests/third_party)

import deltafmi.apps  # noqa: E402,F401  (the composition root: source: components are built)
from deltafmi.master.scenario.resolve import resolve_system  # noqa: E402
from deltafmi.master.scenario.spec import load_scenario  # noqa: E402
from deltafmi.master.stepping.master import Master, NativeLoop  # noqa: E402
from deltafmi.master.stepping.parallel import pooled  # noqa: E402

UNITS = 8


def c_scenario(folder: Path, fmu: Path, algorithm: str, stop: float, substep: float, name: str = "") -> Path:
    lines = [f"experiment: {{start: 0.0, stop: {stop}, step: 1.0e-3}}", f"master: {{algorithm: {algorithm}}}",
             "components:"]
    for i in range(UNITS):
        lines.append(f"  o{i}: {{fmu: '{fmu}', interface: CS, parameters: {{k: {1.0 + i}, substep: {substep}}}}}")
    if algorithm == "jacobi":
        lines.append("connections:")
        lines += [f"  - {{from: o{i}.x, to: o{(i + 1) % UNITS}.F, factor: 0.3}}" for i in range(UNITS)]
    lines.append(f"outputs: [{', '.join(f'o{i}.x' for i in range(UNITS))}]")
    path = folder / f"c_{name or algorithm}.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def delta_scenario(folder: Path, stop: float) -> Path:
    lines = [f"experiment: {{start: 0.0, stop: {stop}, step: 1.0e-3}}", "master: {algorithm: jacobi}", "components:"]
    lines += [f"  r{i}: {{source: deltafmi.models:DeltaRobot, interface: CS}}" for i in range(UNITS)]
    lines.append(f"outputs: [{', '.join(repr(f'r{i}.z[3]') for i in range(UNITS))}]")
    path = folder / "delta.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def stepping(path: Path, threads: int, native: bool, lockstep: bool = False) -> Tuple[float, float, bytes]:
    """Stepping wall seconds of one run, the CPU seconds of the process meanwhile (every thread's)
    and its results file (CSV: every value as Python's repr). ``lockstep``: the C loop's threads meet
    at every step even where the units fall into components that exchange nothing (as before blocks
    of steps)."""
    scenario = load_scenario(path)
    scenario = replace(scenario, master=replace(scenario.master, threads=threads))
    result = path.with_name(f"{path.stem}-{threads}.csv")
    run_fixed, plan_components, spent = Master._run_fixed, NativeLoop._plan_components, [0.0]

    def timed(master):
        begin = time.process_time()
        try:
            return run_fixed(master)
        finally:
            spent[0] += time.process_time() - begin

    Master._run_fixed = timed
    if lockstep:
        NativeLoop._plan_components = lambda loop, sampler: None
    try:
        summary = Master(resolve_system(scenario), result=result, native=native).run()
    finally:
        Master._run_fixed, NativeLoop._plan_components = run_fixed, plan_components
    return summary.wall_time - summary.setup_time, spent[0], result.read_bytes()


def pooled_count(path: Path) -> int:
    """How many units of the scenario at ``path`` step on the threads (see deltafmi.master.stepping.parallel)."""
    master = Master(resolve_system(load_scenario(path)), result=path.with_name("pooled.csv"))
    try:
        master.open()
        return sum(map(pooled, master.units))
    finally:
        master.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--stop", type=float, default=2.0)
    parser.add_argument("--substep", type=float, default=2e-7, help="the C Oscillator's Runge-Kutta substep [s]")
    parser.add_argument("--systems", default="c,delta")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        cases = []
        if "c" in args.systems.split(","):
            fmu = build_fmu("Oscillator", folder)
            cases += [(f"{UNITS} C Oscillators, {algorithm}", c_scenario(folder, fmu, algorithm, args.stop,
                                                                         args.substep))
                      for algorithm in ("jacobi", "gauss-seidel")]
            # one Runge-Kutta step per communication step: what handing steps to threads costs
            cheap = c_scenario(folder, fmu, "jacobi", args.stop, 1e-3, "cheap")
            cases.append((f"{UNITS} C Oscillators, cheap steps", cheap))
        if "delta" in args.systems.split(","):
            cases.append((f"{UNITS} DeltaRobot CS, free fall", delta_scenario(folder, args.stop)))
        print(f"{args.stop:g} s of 1 ms steps; median stepping wall time (and CPU time of the process, all "
              f"threads) of {args.repeats} interleaved runs; load average {os.getloadavg()[0]:.1f} on "
              f"{os.cpu_count()} cores")
        print(f"{'system':<36} {'loop':<10} {'threads 1 s':>11} {'threads 2 s':>11} {'1/2':>6} {'CPU 1 s':>8} "
              f"{'CPU 2 s':>8}  identical  pooled")
        loops = [("C", True, False), ("C lockstep", True, True), ("Python", False, False)]
        for name, path in cases:
            count = pooled_count(path)
            for loop, native, lockstep in loops:
                stepping(path, 1, native)  # warm: FMUs built and unpacked
                times: Dict[int, List[float]] = {1: [], 2: []}
                cpu: Dict[int, List[float]] = {1: [], 2: []}
                results: Dict[int, bytes] = {}
                for _ in range(args.repeats):
                    for threads in (1, 2):
                        seconds, spent, results[threads] = stepping(path, threads, native, lockstep)
                        times[threads].append(seconds)
                        cpu[threads].append(spent)
                same = results[1] == results[2]
                one, two = statistics.median(times[1]), statistics.median(times[2])
                print(f"{name:<36} {loop:<10} {one:11.3f} {two:11.3f} {one / two:6.2f} "
                      f"{statistics.median(cpu[1]):8.3f} {statistics.median(cpu[2]):8.3f}  "
                      f"{'yes' if same else 'NO':<9}  {count}/{UNITS}")
        print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
