"""How well this machine can pace at all: the bare C floor (benchmarks/native/paced_floor.c, no
Python in its process) waiting each way a paced loop can, at 50x (20 us paced steps) and 1x (1 ms).

Each configuration releases ``--points`` points around ``--busy`` seconds of work per step (the
flagship's busy time in the master's C loop), waiting by

- ``sleep``: clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME) to the deadline, nothing else;
- ``spin``: polling clock_gettime(CLOCK_MONOTONIC) until the deadline;
- ``hybrid S``: sleeping to S before the deadline, then polling (the master's default, S = 200 us);

at the usual priority and at SCHED_FIFO 50 (root or CAP_SYS_NICE; said when refused), with and
without mlockall and pinned to one CPU (``cpu=1``) or not; and with a lead window (a point may be
released up to L before its deadline, so that the steps computed ahead absorb a stall shorter
than L). Configurations run interleaved, in an order shuffled anew each repeat, ``--repeats``
times; medians over the repeats, the load average beside them.

Figures per configuration (T: the paced step, in wall time):

- wake-up lateness (release - deadline) median, 99th, 99.9th percentile, largest;
- ``overrun``: the Pacer's: a point released later than T/4 after its deadline;
- ``miss``: a real-time engineer's deadline miss: the step before the point completed its
  computation after the point's deadline (the wake-up itself is not counted);
- ``behind``: the Pacer's fell-behind episodes: stretches of points each later than T;
- ``stretch``: the longest such stretch [points], and ``end``: whether the last point is still
  later than T (a run that did not catch up: the real-time sense of falling behind);
- ``early``: with a lead, the largest earliness of a release (the price: up to L early).

Usage: python benchmarks/pacing_floor.py [--repeats 3] [--points-fast 10000] [--points-real 2000]
       [--busy 2.5e-6] [--quick]
"""
from __future__ import annotations

import argparse
import os
import random
import statistics
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from deltafmi.toolchain import require_compiler

SOURCE = Path(__file__).resolve().parent / "native" / "paced_floor.c"


def build(folder: Path) -> Path:
    program = folder / "paced_floor"
    subprocess.run([*require_compiler(SOURCE), "-std=c99", "-O2", str(SOURCE), "-o", str(program)], check=True,
                   capture_output=True)
    return program


def run(program: Path, folder: Path, mode: str, points: int, period: float, busy: float, spin: float,
        options: tuple) -> dict:
    out, done = folder / "late.bin", folder / "done.bin"
    result = subprocess.run([str(program), mode, str(points), repr(period), repr(busy), repr(spin), str(out),
                             *options, f"done={done}"], check=True, capture_output=True, text=True)
    cpu, wall, locked, fifo = result.stdout.split()
    late, finished = np.fromfile(out), np.fromfile(done)
    beyond = late > period
    starts = beyond & ~np.concatenate(([False], beyond[:-1]))
    stretch, longest = 0, 0
    for b in beyond.tolist():
        stretch = stretch + 1 if b else 0
        longest = max(longest, stretch)
    return {"p50": float(np.median(late)), "p99": float(np.percentile(late, 99)),
            "p999": float(np.percentile(late, 99.9)), "max": float(late.max()),
            "overrun": float(np.mean(late > period / 4)), "miss": float(np.mean(finished > 0)),
            "behind": int(np.count_nonzero(starts)), "stretch": longest, "end": bool(late[-1] > period),
            "early": float(max(0.0, -late.min())), "cpu": float(cpu) / float(wall),
            "locked": locked == "1", "fifo": fifo == "1"}


def configurations(quick: bool) -> list:
    """(label, speed, mode, spin, options)"""
    plan = []
    for speed in (50.0, 1.0):
        modes = [("spin", 0.0)] if speed == 50.0 else [("sleep", 0.0), ("spin", 0.0), ("hybrid", 2e-4),
                                                        ("hybrid", 5e-5)]
        if speed == 50.0:
            modes.append(("sleep", 0.0))
        for mode, spin in modes:
            name = mode + (f" {spin * 1e6:.0f}us" if mode == "hybrid" else "")
            variants = [("", ("mlock",)), (" fifo", ("mlock", "fifo=50")), (" fifo cpu1", ("mlock", "fifo=50", "cpu=1"))]
            if not quick:
                variants += [(" no-mlock", ()), (" cpu1", ("mlock", "cpu=1"))]
            for suffix, options in variants:
                plan.append((f"{speed:g}x {name}{suffix}", speed, mode, spin, options))
        for lead in ((1e-4, 5e-4) if speed == 50.0 else (1e-4, 5e-4)):
            for mode, spin in (("spin", 0.0), ("sleep", 0.0)) if speed == 50.0 else (("hybrid", 5e-5), ("sleep", 0.0)):
                name = mode + (f" {spin * 1e6:.0f}us" if mode == "hybrid" else "")
                for suffix, options in (("", ("mlock",)), (" fifo", ("mlock", "fifo=50"))):
                    plan.append((f"{speed:g}x {name} lead {lead * 1e6:.0f}us{suffix}", speed, mode, spin,
                                 options + (f"lead={lead!r}",)))
    return plan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--points-fast", type=int, default=10000)
    parser.add_argument("--points-real", type=int, default=2000)
    parser.add_argument("--busy", type=float, default=2.5e-6)
    parser.add_argument("--quick", action="store_true", help="fewer variants (no no-mlock, no pinned at usual priority)")
    parser.add_argument("--only", default="", help="only the configurations whose label contains this")
    args = parser.parse_args()
    plan = [c for c in configurations(args.quick) if args.only in c[0]]
    found: dict = {label: [] for label, *_ in plan}
    loads = []
    shuffle = random.Random(7).shuffle
    with tempfile.TemporaryDirectory() as text:
        folder = Path(text)
        program = build(folder)
        for _ in range(args.repeats):
            loads.append(os.getloadavg()[0])
            order = list(plan)
            shuffle(order)
            for label, speed, mode, spin, options in order:
                points = args.points_fast if speed == 50.0 else args.points_real
                found[label].append(run(program, folder, mode, points, 1e-3 / speed, args.busy, spin, options))
    print(f"bare C floor, {args.repeats} repeats interleaved (shuffled), busy {args.busy * 1e6:g} us per step; "
          f"50x: {args.points_fast} points of 20 us (overrun > 5 us), 1x: {args.points_real} points of 1 ms "
          f"(overrun > 250 us); load average (1 min) at each repeat's start: " + ", ".join(f"{x:.2f}" for x in loads))
    fifo_refused = any(label.endswith("fifo") and not all(f["fifo"] for f in runs) for label, runs in found.items())
    if fifo_refused:
        print("  SCHED_FIFO refused (not root, no CAP_SYS_NICE): the 'fifo' rows ran at the usual priority")
    print(f"  {'':32} {'p50':>8} {'p99':>9} {'p99.9':>9} {'max':>9} {'overrun':>8} {'miss':>7} {'behind':>6} "
          f"{'stretch':>7} {'end':>4} {'early':>8} {'CPU':>5}   per repeat: overrun/behind")
    for label, runs in found.items():
        med = {key: statistics.median(r[key] for r in runs) for key in
               ("p50", "p99", "p999", "max", "overrun", "miss", "behind", "stretch", "early", "cpu")}
        each = " ".join(f"{r['overrun']:.2%}/{r['behind']}" for r in runs)
        print(f"  {label:32} {_us(med['p50'])} {_us(med['p99'])} {_us(med['p999'])} {_us(med['max'])} "
              f"{med['overrun']:8.2%} {med['miss']:7.2%} {med['behind']:6g} {med['stretch']:7g} "
              f"{sum(r['end'] for r in runs):4d} {_us(med['early'])} {med['cpu']:5.0%}   {each}")


def _us(seconds: float) -> str:
    return f"{seconds * 1e6:6.1f}us" if abs(seconds) < 1e-2 else f"{seconds * 1e3:6.1f}ms"


if __name__ == "__main__":
    main()
