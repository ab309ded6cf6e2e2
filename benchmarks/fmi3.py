"""Cost per communication step of the same component built as FMI 3.0 and as FMI 2.0.

Three paths, each measured for both builds in interleaved rounds of this one run (medians):
fmpy's own FMU2Slave/FMU3Slave loop (doStep + get of every output), fmpy.simulate_fmu, and our
master (the Oscillator alone, and the flagship delta_tracking with its three FMUs); the fmpy loop
also for the DeltaRobot, a component whose step costs more than fmpy's wrappers. The issue's
target: FMI 3.0 <= 1.1x FMI 2.0 on every path. To tell fmpy's share from ours, the fmpy loop also
runs the plain-C BouncingBall of tests/third_party (FMI 2.0 and 3.0 front ends on one model, a
step costs next to nothing there): the difference is what fmpy's FMI 3.0 wrappers add per step,
and with bare ctypes calls what ctypes takes to pass fmi3DoStep's four more arguments.
Usage: python benchmarks/fmi3.py [--steps N] [--rounds R]
"""
from __future__ import annotations

import argparse
import ctypes
import functools
import math
import statistics
import tempfile
import time
from pathlib import Path
from typing import Callable

import fmpy
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from deltafmi.master.scenario.fmu_scenario import fmu_scenario
from deltafmi.master.scenario.overrides import with_overrides
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.builder.packager import build_cached

STEP = 1e-3
ROOT = Path(__file__).resolve().parents[1]


def fmpy_loop(fmu: Path, steps: int, bare: bool = False) -> float:
    """Microseconds per doStep + get of the real outputs through fmpy's low-level slave classes;
    ``bare``: through the same ctypes functions of fmpy's loaded binary without fmpy's Python
    wrappers (which for FMI 3.0 build four output objects per doStep), the FMU's own cost."""
    md = fmpy.read_model_description(str(fmu))
    real_outputs = [v for v in md.modelVariables if v.causality == "output" and v.type in ("Real", "Float64")]
    outputs = [v.valueReference for v in real_outputs]
    n_values = sum(math.prod(v.shape) if v.dimensions else 1 for v in real_outputs)  # FMI 3.0 arrays whole
    unzipped = fmpy.extract(str(fmu))
    if md.fmiVersion.startswith("3"):
        slave = FMU3Slave(guid=md.instantiationToken, unzipDirectory=unzipped,
                          modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
        slave.instantiate()
        slave.enterInitializationMode(startTime=0.0)
        slave.exitInitializationMode()
        get = slave.getFloat64
    else:
        slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                          modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        get = slave.getReal
    t = 0.0
    if bare:
        do_step, get = _bare_calls(slave, md.fmiVersion.startswith("3"), outputs, n_values)
    else:
        do_step = slave.doStep
        get = functools.partial(get, outputs, n_values) if md.fmiVersion.startswith("3") else \
            functools.partial(get, outputs)
    start = time.perf_counter()
    for _ in range(steps):
        do_step(t, STEP)
        t += STEP
        get()
    elapsed = time.perf_counter() - start
    slave.terminate()
    slave.freeInstance()
    return elapsed / steps * 1e6


def _bare_calls(slave, fmi3: bool, outputs: list[int], n_values: int):
    """doStep(t, h) and get() calling the binary's functions with arguments made once."""
    handle, n = slave.component, len(outputs)
    vrs, values = (ctypes.c_uint32 * n)(*outputs), (ctypes.c_double * n_values)()
    if fmi3:
        flags = [ctypes.c_bool() for _ in range(3)]
        last = ctypes.c_double()
        refs = [ctypes.byref(x) for x in (*flags, last)]
        step, get = slave.dll.fmi3DoStep, slave.dll.fmi3GetFloat64
        return (lambda t, h: step(handle, t, h, True, *refs)), (lambda: get(handle, vrs, n, values, n_values))
    step, get = slave.dll.fmi2DoStep, slave.dll.fmi2GetReal
    return (lambda t, h: step(handle, t, h, 1)), (lambda: get(handle, vrs, n, values))


def simulate_fmu(fmu: Path, steps: int) -> float:
    """Microseconds per output step of fmpy.simulate_fmu (Co-Simulation)."""
    start = time.perf_counter()
    fmpy.simulate_fmu(str(fmu), stop_time=steps * STEP, output_interval=STEP, fmi_type="CoSimulation")
    return (time.perf_counter() - start) / steps * 1e6


def master_run(scenario, steps: int, result: Path) -> float:
    """Microseconds per communication step of our master (set-up and close excluded)."""
    system = resolve_system(with_overrides(scenario, stop=steps * STEP, step=STEP))
    summary = Master(system, result=str(result)).run()
    return (summary.wall_time - summary.setup_time - summary.close_time) / summary.steps * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--rounds", type=int, default=7)
    args = parser.parse_args()
    fmus = {v: build_cached("Oscillator", fmi_version=v) for v in (2, 3)}
    robots = {v: build_cached("DeltaRobot", fmi_version=v) for v in (2, 3)}
    flagship = load_scenario("delta_tracking")
    with tempfile.TemporaryDirectory() as tmp:
        result = Path(tmp) / "result.csv"
        plain_c = _plain_c_balls(Path(tmp))
        paths: dict[str, Callable[[int], float]] = {}
        for v in (2, 3):
            paths[f"fmpy loop, plain-C BouncingBall|{v}"] = lambda n, f=plain_c[v]: fmpy_loop(f, n)
            paths[f"  same, bare ctypes calls (ball)|{v}"] = lambda n, f=plain_c[v]: fmpy_loop(f, n, bare=True)
            paths[f"fmpy FMU2Slave/FMU3Slave, Oscillator|{v}"] = lambda n, f=fmus[v]: fmpy_loop(f, n)
            paths[f"  same, bare ctypes calls (Oscillator)|{v}"] = lambda n, f=fmus[v]: fmpy_loop(f, n, bare=True)
            paths[f"fmpy FMU2Slave/FMU3Slave, DeltaRobot|{v}"] = lambda n, f=robots[v]: fmpy_loop(f, n)
            paths[f"fmpy.simulate_fmu, Oscillator|{v}"] = lambda n, f=fmus[v]: simulate_fmu(f, n)
            paths[f"our master, Oscillator|{v}"] = lambda n, f=fmus[v]: master_run(fmu_scenario(f), n, result)
            paths[f"our master, flagship (3 FMUs)|{v}"] = (
                lambda n, v=v: master_run(with_overrides(flagship, fmi_version=v), n, result))
        for run in paths.values():  # warm up: builds, unpacking, first imports
            run(50)
        times: dict[str, list[float]] = {key: [] for key in paths}
        for _ in range(args.rounds):
            for key, run in paths.items():
                times[key].append(run(args.steps))
    print(f"{args.steps} steps of {STEP:g} s, medians of {args.rounds} interleaved rounds (us per step)")
    print(f"{'path':36s} {'FMI 2.0':>9s} {'FMI 3.0':>9s} {'3.0/2.0':>8s} {'3.0-2.0':>8s}")
    for name in dict.fromkeys(key.split("|")[0] for key in times):
        two, three = (statistics.median(times[f"{name}|{v}"]) for v in (2, 3))
        print(f"{name:36s} {two:9.2f} {three:9.2f} {three / two:7.3f}x {three - two:+8.2f}")


def _plain_c_balls(folder: Path) -> dict[int, Path]:
    """The third-party-style BouncingBall (plain C) with its FMI 2.0 and FMI 3.0 front ends."""
    import sys
    sys.path.insert(0, str(ROOT / "tests" / "third_party"))
    from build import build_fmu as build_third_party
    return {2: build_third_party("BouncingBall", folder), 3: build_third_party("BouncingBall3", folder)}


if __name__ == "__main__":
    main()
