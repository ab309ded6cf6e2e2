"""The flagship exported as one FMU (``deltafmi export-fmu``): what a communication step costs
through the system FMU against the same steps in our master.

Both run ``delta_tracking`` (3.5 s, 1 ms steps), rounds interleaved in one process:

- run: :func:`deltafmi.simulate` (the master's C loop, 64 steps per call, rows kept in memory);
  its stepping time from the run's summary (loading and writing apart);
- system FMU in fmpy: ``doStep`` of 1 ms and ``getReal`` of the wrist position, 3500 times,
  on an instance initialized beforehand: its doStep going from the FMU's C layer straight into
  the master's C loop (the default), and the same through the FMU's Python layer
  (``DELTAFMI_SYSTEM_C_STEP=0`` at its instantiation, the path every doStep took before);
- the same C to C steps with fmi2DoStep and fmi2GetReal called through bare ctypes (the
  arguments made once): without fmpy's Python around every call;
- a C host with no Python of its own (tests/c_host/host.c ``bench``; the FMU starts the
  interpreter it was built with): 3500 fmi2DoStep alone, then 3500 of fmi2SetReal of the payload
  force (a new value every step), fmi2DoStep and fmi2GetReal, C to C and through Python;

and prints the cost per step (medians of ``--repeats`` rounds) and their ratios. The system FMU
takes one master step per ``doStep``; the run takes up to 64 steps per call into C.

Usage: python benchmarks/system_fmu.py [--repeats 5]
"""
from __future__ import annotations

import argparse
import ctypes
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import fmpy
from fmpy.fmi2 import FMU2Slave

import deltafmi

ROOT = Path(__file__).resolve().parents[1]
STEPS, STEP = 3500, 1e-3


def system_step_cost(fmu: Path, unzipped: str, c_step: bool = True, bare: bool = False) -> float:
    """Seconds per doStep (with one getReal) over the whole run; ``c_step`` False: every doStep
    through the FMU's Python layer; ``bare``: fmi2DoStep and fmi2GetReal called through ctypes
    with their arguments made once (what the FMU costs without fmpy's Python around each call)."""
    if c_step:
        os.environ.pop("DELTAFMI_SYSTEM_C_STEP", None)
    else:
        os.environ["DELTAFMI_SYSTEM_C_STEP"] = "0"  # read when the instance is made
    md = fmpy.read_model_description(str(fmu))
    vrs = [v.valueReference for v in md.modelVariables if v.name in ("plant.z[1]", "plant.z[2]", "plant.z[3]")]
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier)
    slave.instantiate()
    slave.setupExperiment(startTime=0.0, stopTime=STEPS * STEP)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    start = time.perf_counter()
    if bare:  # the FMI functions called through ctypes alone, without fmpy's wrappers around them
        do_step, get_real, component = slave.dll.fmi2DoStep, slave.dll.fmi2GetReal, slave.component
        refs, values = (ctypes.c_uint * len(vrs))(*vrs), (ctypes.c_double * len(vrs))()
        for k in range(STEPS):
            if do_step(component, k * STEP, STEP, 1) or get_real(component, refs, len(vrs), values):
                raise RuntimeError(f"the system FMU failed at step {k}")
    else:
        for k in range(STEPS):
            slave.doStep(k * STEP, STEP)
            slave.getReal(vrs)
    seconds = time.perf_counter() - start
    slave.terminate()
    slave.freeInstance()
    os.environ.pop("DELTAFMI_SYSTEM_C_STEP", None)
    return seconds / STEPS


def c_host(workdir: Path) -> Path:
    """tests/c_host/host.c compiled into ``workdir``."""
    host = workdir / "host"
    subprocess.run(["cc", "-O2", f"-I{ROOT / 'deltafmi/runtime/native'}", str(ROOT / "tests/c_host/host.c"),
                    "-o", str(host), "-ldl", "-lm"], check=True)
    return host


def c_host_step_costs(host: Path, fmu: Path, unzipped: str, c_step: bool = True) -> tuple[float, float]:
    """Seconds per fmi2DoStep alone, and per fmi2SetReal + fmi2DoStep + fmi2GetReal, in the C host."""
    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    env = {**os.environ, "DELTAFMI_SYSTEM_C_STEP": "1" if c_step else "0"}
    out = subprocess.run([str(host), unzipped, md.coSimulation.modelIdentifier, md.guid, "bench", str(STEPS),
                          str(vr["plant.f[3]"]), str(vr["plant.z[1]"])], capture_output=True, text=True, check=True,
                         env=env).stdout
    figures = dict(line.split("=") for line in out.split())
    return float(figures["dostep_us"]) * 1e-6, float(figures["step_us"]) * 1e-6


def run_step_cost() -> float:
    summary = deltafmi.simulate("delta_tracking").summary
    return (summary.wall_time - summary.setup_time - summary.close_time) / summary.steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        fmu = deltafmi.export_fmu("delta_tracking", Path(tmp) / "Tracking.fmu")
        unzipped = fmpy.extract(str(fmu), str(Path(tmp) / "unzipped"))
        host = c_host(Path(tmp))
        runs, systems, bares, pythons, hosts, host_pythons = [], [], [], [], [], []
        for _ in range(args.repeats):
            runs.append(run_step_cost())
            systems.append(system_step_cost(fmu, unzipped))
            bares.append(system_step_cost(fmu, unzipped, bare=True))
            pythons.append(system_step_cost(fmu, unzipped, c_step=False))
            hosts.append(c_host_step_costs(host, fmu, unzipped))
            host_pythons.append(c_host_step_costs(host, fmu, unzipped, c_step=False))
    run, system, python = statistics.median(runs), statistics.median(systems), statistics.median(pythons)
    bare = statistics.median(bares)
    host_step, host_loop = (statistics.median(h[i] for h in hosts) for i in (0, 1))
    host_python_step, host_python_loop = (statistics.median(h[i] for h in host_pythons) for i in (0, 1))
    print(f"delta_tracking, {STEPS} steps of {STEP * 1e3:g} ms, medians of {args.repeats} interleaved rounds")
    print(f"  deltafmi run (master, C loop)             {run * 1e6:8.1f} us per step")
    print(f"  system FMU in fmpy, doStep C to C         {system * 1e6:8.1f} us per step   {system / run:6.2f}x run")
    print(f"  system FMU, bare ctypes host, C to C      {bare * 1e6:8.1f} us per step   {bare / run:6.2f}x run")
    print(f"  system FMU in fmpy, doStep through Python {python * 1e6:8.1f} us per step   {python / run:6.2f}x run")
    print(f"  through Python / C to C                   {python / system:8.2f}x")
    print(f"  C host, doStep C to C                     {host_step * 1e6:8.1f} us per step   "
          f"{host_step / run:6.2f}x run")
    print(f"  C host, set + doStep + get, C to C        {host_loop * 1e6:8.1f} us per step   "
          f"{host_loop / run:6.2f}x run")
    print(f"  C host, doStep through Python             {host_python_step * 1e6:8.1f} us per step   "
          f"{host_python_step / run:6.2f}x run")
    print(f"  C host, set + doStep + get through Python {host_python_loop * 1e6:8.1f} us per step   "
          f"{host_python_loop / run:6.2f}x run")


if __name__ == "__main__":
    main()
