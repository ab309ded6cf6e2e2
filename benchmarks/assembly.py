"""Issue 27's figures: the 6-DOF closed loop's real-time factor, and the peg study's throughput.

1. Real-time factor (simulated seconds per wall second; median of ``--repeats``) of the 6-DOF
   closed loops: scenarios/peg_in_hole.yaml (DeltaWristPeg in contact with a chamfered
   hole, AssemblyController, 1 kHz) and wrist_pose_tracking.yaml (DeltaWrist in free space), each
   with the plant as Model Exchange (the master's CVODE) and as Co-Simulation (the FMU's own
   CVODE). Whole run (FMU loading and initialization included) and the stepping alone. Baseline in
   the same run: the 3-DOF flagship delta_tracking.yaml (DeltaRobot ME, DeltaController and
   Trajectory CS), and each loop's cost per simulated second against it.
2. Study throughput (cases per second) on ``--cases`` cases spread over
   scenarios/studies/peg_robustness.yaml (3 s insertions, every offset, tilt, direction
   and Monte Carlo draw): the sweep on a LocalCluster of 1 and of 2 worker processes (cluster
   start-up printed apart), against the baseline of a serial loop of the same cases in one
   process, each case a ``deltafmi.simulate`` of its exported scenario (loading the FMUs every
   case, as a plain script does). The sweep's metrics are checked against the loop's to 1e-9.

Usage: python benchmarks/assembly.py [--repeats 3] [--cases 24]
"""
from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Dict, List

import yaml

import deltafmi
from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.apps.studies.cases import Case
from deltafmi.apps.studies.export import case_scenario
from deltafmi.apps.studies.plan import PlannedStudy, plan_study
from deltafmi.apps.studies.spec import load_study

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sweep import spread, sweep  # noqa: E402  (benchmarks/sweep.py: a sweep on a LocalCluster, timed)

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "scenarios"
STUDY = EXAMPLES / "studies" / "peg_robustness.yaml"


def variant(name: str, folder: Path, interface: str) -> Path:
    """scenarios/<name>.yaml with its plant as ``interface`` (ME or CS)."""
    spec = yaml.safe_load((EXAMPLES / f"{name}.yaml").read_text())
    spec["components"]["plant"]["interface"] = interface
    path = folder / f"{name}_{interface}.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def real_time_factors(path: Path, repeats: int, folder: Path) -> Dict[str, float]:
    """Median real-time factors of the whole run and of the stepping alone, over ``repeats``."""
    whole, stepping = [], []
    for _ in range(repeats):
        summary = Master(resolve_system(load_scenario(path)), result=folder / "rtf.csv").run()
        whole.append(summary.simulated / summary.wall_time)
        stepping.append(summary.simulated / summary.stepping_time)
    return {"whole": statistics.median(whole), "stepping": statistics.median(stepping),
            "steps": summary.steps, "events": summary.events}


def serial_loop(planned: PlannedStudy, cases: List[Case], folder: Path) -> tuple[float, List[dict]]:
    """Wall seconds of the cases one after another in this process, and each case's metrics."""
    files = []
    for case in cases:
        path = folder / f"case{case.id}.yaml"
        path.write_text(case_scenario(planned, case))
        files.append(path)
    deltafmi.simulate(files[0], output=folder / "warm.csv")  # FMU builds and imports, untimed
    metrics = []
    wall = time.perf_counter()
    for path in files:
        out = path.with_suffix(".csv")
        deltafmi.simulate(path, output=out)
        recorded = columns(out)
        metrics.append({m.name: m.value(recorded) for m in planned.plan.metrics})
    return time.perf_counter() - wall, metrics


def same(a: float | None, b: float) -> bool:
    """Equal to 1e-9 (a sweep row stores an undefined metric as None, the loop as NaN)."""
    a = math.nan if a is None else a
    return (math.isnan(a) and math.isnan(b)) or abs(a - b) <= 1e-9 * max(1.0, abs(a))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="runs per real-time factor (median)")
    parser.add_argument("--cases", type=int, default=24, help="peg_robustness cases for the throughput")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        print(f"1. Real-time factor, median of {args.repeats} (whole run with loading | stepping alone)")
        base = real_time_factors(EXAMPLES / "delta_tracking.yaml", args.repeats, folder)
        rows = [("delta_tracking (3-DOF flagship, baseline)", base)]
        for name in ("peg_in_hole", "wrist_pose_tracking"):
            for interface in ("ME", "CS"):
                rows.append((f"{name}, plant {interface}",
                             real_time_factors(variant(name, folder, interface), args.repeats, folder)))
        for label, r in rows:
            print(f"   {label:42s} {r['whole']:6.2f}x | {r['stepping']:6.2f}x  ({r['steps']} steps, {r['events']} "
                  f"events); cost per simulated second {base['stepping'] / r['stepping']:5.2f}x the flagship's")

        planned = plan_study(load_study(STUDY))
        cases = spread(planned.cases, args.cases)
        n = len(cases)
        stop = planned.system.scenario.experiment.stop
        print(f"\n2. Study throughput: {n} cases spread over {STUDY.relative_to(ROOT)} ({stop:g} s simulated each)")
        loop, plain = serial_loop(planned, cases, folder)
        print(f"   baseline, serial loop of deltafmi.simulate in one process: {n} cases in {loop:.2f} s: "
              f"{n / loop:.2f} cases/s")
        for workers in (1, 2):
            run = sweep(planned, cases, workers, folder)
            agree = all(same(row["metrics"][m], p[m]) for row, p in zip(run.rows, plain) for m in p)
            print(f"   sweep, {workers} worker{'s' * (workers > 1)}: {n} cases in {run.wall:.2f} s: "
                  f"{n / run.wall:.2f} cases/s = {loop / run.wall:.2f}x the loop; cluster start-up "
                  f"{run.startup:.2f} s apart ({n / (run.wall + run.startup):.2f} cases/s with it); "
                  f"metrics equal to the loop's: {'yes' if agree else 'NO'}")


if __name__ == "__main__":
    main()
