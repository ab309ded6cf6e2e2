"""The constrained plants' Co-Simulation speed with CVODE's projection compiled (``project`` kernel).

A Co-Simulation step of a plant that overrides ``project`` (the delta robot's DAE plants) runs
CVODE with a compiled right-hand side, and CVODE projects onto the closed loops after every
internal step. Three runs of the same FMU, alternated within each round (the machine may be
shared: read the ratios):

- ``after``: everything compiled, the projection included (the C projection callback of
  deltafmi/builder/codegen/cvode_rhs.c over the generated kernel);
- ``before``: the projection in Python (``DELTAFMI_NATIVE_PROJECT=0``), the rest compiled: what
  a step ran before the project kernel;
- ``python``: no compiled kernels at all (``DELTAFMI_NATIVE=0``), for reference.

Each run is ``fmpy.simulate_fmu`` in Co-Simulation over ``--stop`` seconds with 1 ms steps: the
DeltaRobot falling from rest (no torques: it swings through its workspace under gravity) and the
DeltaWrist likewise with its wrist tilted (qw0), free. Printed: median wall time over
``--repeats`` rounds, the real-time factor (simulated / wall seconds), the before/after ratio
(median of the rounds' ratios), and whether the runs agree bit for bit (they must).

Usage: python benchmarks/projection.py [--repeats 5] [--stop 2.0]
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import extract, read_model_description, simulate_fmu

from deltafmi.builder.packager import build_cached

ROOT = Path(__file__).resolve().parents[1]
PLANTS = {"DeltaRobot": ("delta_robot.py", {}, ["q[1]", "v[9]", "residual"]),
          "DeltaWrist": ("delta_wrist.py", {"qw0[1]": 0.4, "qw0[2]": -0.3}, ["q[1]", "v[9]", "v_w[3]", "residual"])}
MODES = {"after": {}, "before": {"DELTAFMI_NATIVE_PROJECT": "0"}, "python": {"DELTAFMI_NATIVE": "0"}}


def run(directory: str, model_description: Any, mode: str, stop: float, start: dict,
        output: list) -> tuple[float, np.ndarray]:
    """(wall seconds, result) of one CS run with ``mode``'s environment."""
    for name in ("DELTAFMI_NATIVE", "DELTAFMI_NATIVE_PROJECT"):
        os.environ.pop(name, None)
    os.environ.update(MODES[mode])
    try:
        begin = time.perf_counter()
        result = simulate_fmu(directory, model_description=model_description, fmi_type="CoSimulation",
                              stop_time=stop, output_interval=1e-3, start_values=start, output=output)
        return time.perf_counter() - begin, result
    finally:
        for name in MODES[mode]:
            os.environ.pop(name, None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--stop", type=float, default=2.0)
    args = parser.parse_args()
    print(f"Co-Simulation over {args.stop} s, 1 ms steps, medians of {args.repeats} rounds")
    print(f"{'plant':<11} {'mode':<7} {'wall s':>8} {'x real time':>12}")
    for plant, (source, start, output) in PLANTS.items():
        fmu = build_cached(ROOT / "fmu_src" / source)
        directory = extract(str(fmu))
        md = read_model_description(directory)
        times: dict[str, list[float]] = {mode: [] for mode in MODES}
        results = {}
        for _ in range(args.repeats):
            for mode in MODES:
                wall, results[mode] = run(directory, md, mode, args.stop, start, output)
                times[mode].append(wall)
        for mode in MODES:
            wall = statistics.median(times[mode])
            print(f"{plant:<11} {mode:<7} {wall:8.3f} {args.stop / wall:12.1f}")
        ratio = statistics.median(b / a for a, b in zip(times["after"], times["before"]))
        same = all(np.array_equal(results["after"][name], results[mode][name]) for mode in MODES for name in output)
        print(f"{plant:<11} before/after {ratio:.2f}x; runs bit for bit equal: {same}; "
              f"max loop residual {np.max(results['after']['residual']):.2e} m")


if __name__ == "__main__":
    main()
