"""The plain C host's algorithms (tests/c_host/host.c), step for step, through fmpy.

What the C host prints for an FMU must equal what these loops return for it in a Python host: the
same fmi2 calls in the same order, so any difference is the host process, not the algorithm.
"""
from __future__ import annotations

import ctypes
import os
import subprocess
from pathlib import Path
from typing import Sequence

import fmpy
import numpy as np
from fmpy.fmi2 import FMU2Model, FMU2Slave

from conftest import clean_env


def run_c_host(host: Path, directory: Path, mode: str, *args: object, env: dict | None = None,
               check: bool = True) -> subprocess.CompletedProcess:
    """``host <dir> <identifier> <guid> <mode> args...`` with no Python in its environment."""
    md = fmpy.read_model_description(str(directory))
    identifier = (md.coSimulation or md.modelExchange).modelIdentifier
    out = subprocess.run([str(host), str(directory), identifier, md.guid, mode, *map(str, args)],
                         capture_output=True, text=True, env=clean_env(**(env or {})), timeout=300)
    if check:
        assert out.returncode == 0, f"host exited with {out.returncode}:\n{out.stderr[-3000:]}"
    return out


def host_rows(text: str) -> np.ndarray:
    """The host's CSV rows (time, values...) as an array."""
    return np.array([[float(v) for v in line.split(",")] for line in text.strip().splitlines()])


def as_pointer(array: np.ndarray):
    """A float64 array as the double * that fmpy's ME calls take."""
    return array.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def co_simulation(directory: Path, stop: float, h: float, vrs: Sequence[int]) -> np.ndarray:
    """The host's ``cs`` mode: fixed steps of ``h``, a row after each."""
    md = fmpy.read_model_description(str(directory))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=str(directory),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="py")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    rows = [[0.0, *slave.getReal(list(vrs))]]
    for k in range(1, round(stop / h) + 1):
        slave.doStep((k - 1) * h, h)
        rows.append([k * h, *slave.getReal(list(vrs))])
    slave.terminate()
    slave.freeInstance()
    return np.array(rows)


def _settle_events(fmu: FMU2Model):
    info = fmu.newDiscreteStates()
    while info[0] and not info[1]:
        info = fmu.newDiscreteStates()
    return info


def model_exchange_euler(directory: Path, stop: float, h: float, vrs: Sequence[int]) -> np.ndarray:
    """The host's ``me`` mode: explicit Euler, time, state and step events, rows on the grid."""
    md = fmpy.read_model_description(str(directory))
    nx, nz = md.numberOfContinuousStates, md.numberOfEventIndicators
    fmu = FMU2Model(guid=md.guid, unzipDirectory=str(directory),
                    modelIdentifier=md.modelExchange.modelIdentifier, instanceName="py")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    info = _settle_events(fmu)
    fmu.enterContinuousTimeMode()
    x, dx, z, z_prev = np.zeros(nx), np.zeros(nx), np.zeros(nz), np.zeros(nz)
    fmu.getContinuousStates(as_pointer(x), nx)
    fmu.getEventIndicators(as_pointer(z_prev), nz)
    t, k, rows = 0.0, 1, [[0.0, *fmu.getReal(list(vrs))]]
    while k <= round(stop / h):
        t_grid = k * h
        time_event = info[4] and info[5] <= t_grid
        t_next = info[5] if time_event else t_grid
        fmu.getDerivatives(as_pointer(dx), nx)
        x += (t_next - t) * dx
        t = t_next
        fmu.setTime(t)
        fmu.setContinuousStates(as_pointer(x), nx)
        fmu.getEventIndicators(as_pointer(z), nz)
        enter, _ = fmu.completedIntegratorStep()
        if np.any((z > 0) != (z_prev > 0)) or time_event or enter:
            fmu.enterEventMode()
            info = _settle_events(fmu)
            fmu.enterContinuousTimeMode()
            if info[3]:
                fmu.getContinuousStates(as_pointer(x), nx)
            fmu.getEventIndicators(as_pointer(z), nz)
        z_prev[:] = z
        if t == t_grid:
            rows.append([t, *fmu.getReal(list(vrs))])
            k += 1
    fmu.terminate()
    fmu.freeInstance()
    return np.array(rows)


def me_env(directory: Path) -> dict:
    """The host's sizes for ``me`` mode (it reads them from the environment)."""
    md = fmpy.read_model_description(str(directory))
    return {"HOST_NX": str(md.numberOfContinuousStates), "HOST_NZ": str(md.numberOfEventIndicators)}


def shared_libraries(directory: Path) -> list[Path]:
    """Every ELF shared library in an extracted FMU."""
    return sorted(Path(root) / name for root, _, names in os.walk(directory) for name in names
                  if name.endswith(".so"))
