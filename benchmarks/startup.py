"""Start-up: a cached ``deltafmi run delta_tracking`` against ``fmpy simulate`` of a C BouncingBall FMU.

What a user waits for, measured as they would: the wall time of each command as a subprocess,
from its console script (the one ``pip install`` writes), bytecode caching allowed for both
(PYTHONDONTWRITEBYTECODE removed from their environment, every command run once before timing,
which also builds the flagship's FMUs into the cache and unpacks them). The baseline is fmpy's
own command line simulating the BouncingBall of tests/third_party (a C FMU in the Reference FMUs'
style: plain C, no Python inside, built here with ``cc``) on its default experiment; ``fmpy
--help`` is the baseline of ``deltafmi --help`` and ``deltafmi examples``. The commands run
interleaved, --rounds times; printed: each command's median and minimum, and its ratio to its
baseline: the median over the rounds of the ratio within a round (a command and its baseline run
seconds apart, under much the same load), and the ratios of the medians and of the minima; then
the same for each command's CPU time (user + system), which a loaded machine moves much less.

Usage: python benchmarks/startup.py [--rounds 15] [--scenario delta_tracking]
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Dict, List

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
sys.path.insert(0, str(ROOT / "tests" / "third_party"))
from build import build_fmu  # noqa: E402  (the C FMUs of tests/third_party)


#: CPU seconds (user + system) of each command, beside its wall time (filled by :func:`wall`)
CPU: Dict[str, List[float]] = {}


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def wall(command: List[str], env: Dict[str, str], name: str = "") -> float:
    """Seconds from start to exit of ``command`` (output discarded), its CPU seconds recorded in
    :data:`CPU` under ``name``; exits on a failure."""
    cpu = _children_cpu()
    start = time.perf_counter()
    done = subprocess.run(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed ({done.returncode}):\n{done.stderr}")
    if name:
        CPU.setdefault(name, []).append(_children_cpu() - cpu)
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--scenario", default="delta_tracking")
    args = parser.parse_args()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    with tempfile.TemporaryDirectory() as tmp:
        ball = build_fmu("BouncingBall", Path(tmp))
        commands = {
            "fmpy simulate BouncingBall": [str(BIN / "fmpy"), "simulate", str(ball), "--output-file",
                                           f"{tmp}/ball.csv"],
            f"deltafmi run {args.scenario}": [str(BIN / "deltafmi"), "run", args.scenario, "-o", f"{tmp}/run.csv"],
            "fmpy --help": [str(BIN / "fmpy"), "--help"],
            "deltafmi --help": [str(BIN / "deltafmi"), "--help"],
            "deltafmi examples": [str(BIN / "deltafmi"), "examples"],
        }
        baseline = {f"deltafmi run {args.scenario}": "fmpy simulate BouncingBall",
                    "deltafmi --help": "fmpy --help", "deltafmi examples": "fmpy --help"}
        for command in commands.values():  # warm: the FMUs built and unpacked, the bytecode written
            wall(command, env)
        times: Dict[str, List[float]] = {name: [] for name in commands}
        for _ in range(args.rounds):
            for name, command in commands.items():
                times[name].append(wall(command, env, name))
    load = os.getloadavg()
    print(f"start-up, wall time of each command ({args.rounds} interleaved rounds; "
          f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} on {os.cpu_count()} cores)")
    print("ratio: the median over the rounds of (command / its baseline in the same round); "
          "the medians' and the minima's ratios beside it")
    print(f"{'command':<30} {'median s':>9} {'min s':>7} {'ratio':>7} {'of med':>7} {'of min':>7}  baseline")
    for name, values in times.items():
        base = baseline.get(name)
        if base:
            paired = statistics.median(v / b for v, b in zip(values, times[base]))
            ratios = (f"{paired:7.2f} {statistics.median(values) / statistics.median(times[base]):7.2f} "
                      f"{min(values) / min(times[base]):7.2f}")
        else:
            ratios = " " * 23
        print(f"{name:<30} {statistics.median(values):9.3f} {min(values):7.3f} {ratios}  {base or ''}")
    # CPU time (user + system of the command's process): what the command itself costs, much less
    # moved by a loaded machine than its wall time, which waits for a core
    print("CPU seconds of each command: median, and the median over the rounds of (command / its baseline)")
    for name, values in CPU.items():
        base = baseline.get(name)
        paired = f"{statistics.median(v / b for v, b in zip(values, CPU[base])):7.2f}" if base else " " * 7
        print(f"{name:<30} {statistics.median(values):9.3f} {paired}  {base or ''}")


if __name__ == "__main__":
    main()
