"""Delta robot plant: cost per derivative evaluation and real-time factor of 1 s of free fall.

Prints medians over repeats, measured in this run: accelerations() in-process, one
fmi2SetContinuousStates + fmi2GetDerivatives through fmpy, and 1 s of free fall from
z0 = (0.1, -0.1, -0.9) in Model Exchange (fmpy's CVODE) and Co-Simulation at rtol 1e-6.
Usage: python benchmarks/plant.py [--repeats R]
"""
from __future__ import annotations

import argparse
import ctypes
import statistics
import sys
import tempfile
import time
from pathlib import Path

import fmpy
import numpy as np
from fmpy.fmi2 import FMU2Model

ROOT = Path(__file__).resolve().parents[1]
Z0 = {"z0[1]": 0.1, "z0[2]": -0.1, "z0[3]": -0.9}


def library_us(repeats: int, n: int = 3000) -> float:
    from deltafmi.mechanics import delta as d
    p = d.RL5
    q = d.inverse_kinematics(p, (0.1, -0.1, -0.9))
    v, u, f = np.full(9, 0.1), np.zeros(3), np.zeros(3)
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(n):
            d.accelerations(p, q, v, u, f, 5.0)
        samples.append((time.perf_counter() - start) / n * 1e6)
    return statistics.median(samples)


def fmi_derivative_us(fmu: Path, repeats: int, n: int = 3000) -> float:
    md = fmpy.read_model_description(str(fmu))
    model = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)), modelIdentifier="DeltaRobot")
    model.instantiate()
    model.setupExperiment(startTime=0.0)
    model.enterInitializationMode()
    model.exitInitializationMode()
    model.newDiscreteStates()
    model.enterContinuousTimeMode()
    x, dx = np.zeros(18), np.zeros(18)
    px, pdx = (a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)) for a in (x, dx))
    model.getContinuousStates(px, 18)
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for k in range(n):
            x[9] = 1e-6 * k  # a new state each time: no cached evaluation
            model.setContinuousStates(px, 18)
            model.getDerivatives(pdx, 18)
        samples.append((time.perf_counter() - start) / n * 1e6)
    model.terminate()
    model.freeInstance()
    return statistics.median(samples)


def free_fall_seconds(fmu: Path, fmi_type: str, repeats: int) -> float:
    directory = fmpy.extract(str(fmu))  # unzip once: the figure is simulation time
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        fmpy.simulate_fmu(directory, fmi_type=fmi_type, stop_time=1.0, relative_tolerance=1e-6,
                          output_interval=1e-2, start_values=Z0, output=["z[3]"])
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    from deltafmi.export import build_fmu
    with tempfile.TemporaryDirectory() as tmp:
        fmu = build_fmu(ROOT / "fmu_src" / "delta_robot.py", Path(tmp) / "DeltaRobot.fmu")
        lib = library_us(args.repeats)
        fmi = fmi_derivative_us(fmu, args.repeats)
        me = free_fall_seconds(fmu, "ModelExchange", args.repeats)
        cs = free_fall_seconds(fmu, "CoSimulation", args.repeats)
    print(f"DeltaRobot plant, medians of {args.repeats} runs")
    print(f"  accelerations() in-process               {lib:8.2f} us")
    print(f"  setContinuousStates + getDerivatives     {fmi:8.2f} us  (through fmpy and the FMU)")
    print(f"  1 s free fall, ME (fmpy CVODE, rtol 1e-6) {me * 1e3:7.1f} ms  real-time factor {1 / me:6.1f}")
    print(f"  1 s free fall, CS (internal CVODE)        {cs * 1e3:7.1f} ms  real-time factor {1 / cs:6.1f}")


if __name__ == "__main__":
    sys.exit(main())
