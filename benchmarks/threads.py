"""What the GIL costs a C host that steps deltafmi FMUs from several threads.

Every deltafmi FMU in a process runs in one interpreter, so the Python part of fmi2DoStep runs in
one thread at a time. tests/c_host/threads_host.c steps K Co-Simulation instances of an FMU, either
one after another on one thread (serial, the baseline, measured in the same run) or from K threads
at once (parallel); it reports each instance's stepping interval. Printed: the median over
--repeats of the time per step (the serial sum of stepping times, or the parallel wall time from
the first thread's first step to the last thread's last, divided by K x steps), and the ratio
parallel / serial: 1.0 means threads neither help nor cost, above 1.0 is the price of handing the
GIL between threads. Start-up is not included.

Usage: python benchmarks/threads.py [--model oscillator] [--steps 5000] [--repeats 5]
"""
from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from deltafmi.builder.packager import build_cached

ROOT = Path(__file__).resolve().parents[1]
NATIVE = ROOT / "deltafmi" / "runtime" / "native"
TIMING = re.compile(r"timing job=(\d+) steps=(\d+) start=([\d.]+) end=([\d.]+)")


def per_step(host: Path, mode: str, job: list[str], k: int, steps: int, step: float) -> float:
    """Seconds per step of one run of threads_host with k instances of the job."""
    command = [str(host), mode, repr(steps * step), repr(step), *job * k]
    result = subprocess.run(command, capture_output=True, text=True, env={"PATH": "/usr/bin:/bin"})
    if result.returncode != 0:
        raise SystemExit(f"threads_host failed:\n{result.stderr}")
    spans = [(float(m[3]), float(m[4])) for m in TIMING.finditer(result.stderr)]
    elapsed = (sum(end - start for start, end in spans) if mode == "serial"
               else max(end for _, end in spans) - min(start for start, _ in spans))
    return elapsed / (k * steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="oscillator", help="fmu_src/<model>.py")
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--step", type=float, default=1e-3)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        host = Path(tmp) / "threads_host"
        subprocess.run(["cc", "-O2", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "threads_host.c"), "-o",
                        str(host), "-ldl", "-lm", "-lpthread"], check=True)
        with zipfile.ZipFile(build_cached(ROOT / "fmu_src" / f"{args.model}.py")) as z:
            z.extractall(Path(tmp) / "fmu")
        root = ET.parse(Path(tmp) / "fmu" / "modelDescription.xml").getroot()
        job = [str(Path(tmp) / "fmu"), root.find("CoSimulation").get("modelIdentifier"), root.get("guid"), "0"]
        print(f"{args.model}: {args.steps} CS steps of {args.step} s per instance, median of {args.repeats} runs")
        print(f"{'instances':>9} {'serial us/step':>15} {'parallel us/step':>17} {'parallel/serial':>16}")
        for k in (1, 2, 4):
            serial = statistics.median(per_step(host, "serial", job, k, args.steps, args.step)
                                       for _ in range(args.repeats))
            parallel = statistics.median(per_step(host, "parallel", job, k, args.steps, args.step)
                                         for _ in range(args.repeats))
            print(f"{k:>9} {1e6 * serial:>15.2f} {1e6 * parallel:>17.2f} {parallel / serial:>16.2f}")


if __name__ == "__main__":
    main()
