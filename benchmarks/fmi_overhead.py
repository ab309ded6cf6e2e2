"""Per-step cost of set/doStep/get through FMI: deltafmi vs pythonfmu vs direct Python, and C host.

The model is a first-order lag that steps itself (no solver), so the figures are the FMI path's
own cost. Prints medians over repeated runs, all measured in this one run on this machine.
Usage: python benchmarks/fmi_overhead.py [--steps N] [--repeats R]
"""
from __future__ import annotations

import argparse
import importlib.util
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import fmpy
from fmpy.fmi2 import FMU2Slave

ROOT = Path(__file__).resolve().parents[1]
MODELS = Path(__file__).parent / "models"


class FmpySlave:
    """One instance of an FMU through fmpy's FMU2Slave, initialized, timed in rounds."""

    def __init__(self, fmu: Path) -> None:
        md = fmpy.read_model_description(str(fmu))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                               modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
        self.slave.instantiate()
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()
        self.u, self.y, self.t = [vr["u"]], [vr["y"]], 0.0

    def round_us(self, steps: int, do_step: bool = True) -> float:
        """Microseconds per setReal/doStep/getReal (without doStep: what fmpy's own wrappers
        cost, for our FMU answers setReal/getReal in C)."""
        slave, u, y, h = self.slave, self.u, self.y, 1e-3
        start = time.perf_counter()
        for _ in range(steps):
            slave.setReal(u, [1.0])
            if do_step:
                slave.doStep(self.t, h)
                self.t += h
            slave.getReal(y)
        return (time.perf_counter() - start) / steps * 1e6

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()


def fmpy_rounds(ours: Path, theirs: Path | None, plain_c: Path, steps: int, repeats: int,
                blocks: int = 10) -> dict[str, float]:
    """Medians over rounds in which ours, fmpy's wrappers alone, theirs and a plain C FMU run
    back to back (a slow spell of the shared machine hits all). The ratio ours / theirs is the
    median over `blocks` pairs per round, each of steps / blocks steps in the order ours, theirs,
    theirs, ours: the machine's speed drifting within a pair cancels, and no pair is further apart
    than a few milliseconds."""
    a, b, c = FmpySlave(ours), FmpySlave(theirs) if theirs else None, FmpySlave(plain_c)
    rounds: dict[str, list[float]] = {"ours": [], "fmpy": [], "theirs": [], "ratio": [], "c": []}
    for _ in range(repeats):
        rounds["ours"].append(a.round_us(steps))
        rounds["fmpy"].append(a.round_us(steps, do_step=False))
        rounds["c"].append(c.round_us(steps))
        if b:
            rounds["theirs"].append(b.round_us(steps))
            n = max(1, steps // blocks)
            for _ in range(blocks):
                first, (second, third), last = a.round_us(n), (b.round_us(n), b.round_us(n)), a.round_us(n)
                rounds["ratio"].append((first + last) / (second + third))
    for slave in (a, b, c):
        if slave:
            slave.close()
    return {key: statistics.median(values) if values else float("nan") for key, values in rounds.items()}


def build_plain_c(workdir: Path) -> Path:
    """A C FMU with no Python (tests/third_party AllTypes: y = gain u, same u and y names)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from third_party.build import build_fmu as build_c_fmu
    return build_c_fmu("AllTypes", workdir / "plain_c")


def direct_step_us(steps: int, repeats: int) -> float:
    """Median microseconds per set/do_step/get calling the component in Python directly."""
    from deltafmi.builder import load_component_class
    lag = load_component_class(MODELS / "lag_deltafmi.py")()
    samples, t = [], 0.0
    for _ in range(repeats):
        start = time.perf_counter()
        for k in range(steps):
            lag.u = 1.0
            lag.do_step(t, 1e-3)
            _ = lag.y
            t += 1e-3
        samples.append((time.perf_counter() - start) / steps * 1e6)
    return statistics.median(samples)


def c_host_us(fmu: Path, steps: int, repeats: int, workdir: Path) -> dict[str, float]:
    """Median microseconds per call from the plain-C host (no Python in the host process)."""
    host = workdir / "host"
    subprocess.run(["cc", "-O2", f"-I{ROOT / 'deltafmi/runtime/native'}", str(ROOT / "tests/c_host/host.c"),
                    "-o", str(host), "-ldl", "-lm"], check=True)
    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    directory = fmpy.extract(str(fmu))
    runs: dict[str, list[float]] = {}
    for _ in range(repeats):
        out = subprocess.run([str(host), directory, "Lag", md.guid, "bench", str(steps), str(vr["u"]), str(vr["y"])],
                             capture_output=True, text=True, check=True, env={"PATH": "/usr/bin:/bin"}).stdout
        for line in out.split():
            key, value = line.split("=")
            if key.endswith("_us"):
                runs.setdefault(key, []).append(float(value))
    return {key: statistics.median(values) for key, values in runs.items()}


def c_host_instructions(fmu: Path, workdir: Path, steps: int = 2000) -> float | None:
    """Instructions per fmi2DoStep from the C host under callgrind (exact where wall clocks of
    a shared machine are not), or None without valgrind. The host calls fmi2DoStep 2 x steps."""
    if shutil.which("valgrind") is None:
        return None
    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    directory, out = fmpy.extract(str(fmu)), workdir / "callgrind.out"
    subprocess.run(["valgrind", "--tool=callgrind", "--toggle-collect=fmi2DoStep", f"--callgrind-out-file={out}",
                    str(workdir / "host"), directory, "Lag", md.guid, "bench", str(steps), str(vr["u"]),
                    str(vr["y"])], capture_output=True, check=True, env={"PATH": "/usr/bin:/bin"})
    summary = next(line for line in out.read_text().splitlines() if line.startswith("summary:"))
    return int(summary.split()[1]) / (2 * steps)


def build_pythonfmu(workdir: Path) -> Path | None:
    """The pythonfmu FMU of the same model, or None when pythonfmu is not installed."""
    if importlib.util.find_spec("pythonfmu") is None:
        return None
    subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", str(MODELS / "lag_pythonfmu.py"),
                    "-d", str(workdir)], check=True, capture_output=True)
    return workdir / "Lag.fmu"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--callgrind", action="store_true",
                        help="also count the instructions of the C host's fmi2DoStep (needs valgrind)")
    args = parser.parse_args()
    from deltafmi.builder import build_fmu
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        ours = build_fmu(MODELS / "lag_deltafmi.py", workdir / "ours" / "Lag.fmu")
        theirs = build_pythonfmu(workdir)
        through_fmpy = fmpy_rounds(ours, theirs, build_plain_c(workdir), args.steps, args.repeats)
        direct_us = direct_step_us(args.steps, args.repeats)
        c_us = c_host_us(ours, args.steps * 10, args.repeats, workdir)
        instructions = c_host_instructions(ours, workdir) if args.callgrind else None
    print(f"FMI overhead, medians of {args.repeats} runs x {args.steps} steps (us per set/doStep/get step)")
    print(f"  direct Python calls (floor)        {direct_us:8.3f}")
    print(f"  deltafmi FMU through fmpy          {through_fmpy['ours']:8.3f}")
    print(f"    of which fmpy's setReal+getReal  {through_fmpy['fmpy']:8.3f}   (answered in C: fmpy's own cost)")
    print(f"  a plain C FMU through fmpy         {through_fmpy['c']:8.3f}   (no Python in the FMU: fmpy's floor)")
    if theirs is None:
        print("  pythonfmu FMU through fmpy         skipped: pythonfmu is not installed")
    else:
        print(f"  pythonfmu FMU through fmpy         {through_fmpy['theirs']:8.3f}   (deltafmi / pythonfmu "
              f"{through_fmpy['ratio']:.3f}x, median of the rounds' ratios; target <= 0.7x)")
    print("C host, deltafmi FMU, no Python in the host process (us per call)")
    print(f"  fmi2SetReal                        {c_us['set_us']:8.4f}")
    print(f"  fmi2GetReal                        {c_us['get_us']:8.4f}")
    print(f"  fmi2DoStep (enters Python)         {c_us['dostep_us']:8.4f}")
    print(f"  set + doStep + get                 {c_us['step_us']:8.4f}")
    if instructions is not None:
        print(f"  fmi2DoStep, instructions (callgrind) {instructions:8.0f}")


if __name__ == "__main__":
    main()
