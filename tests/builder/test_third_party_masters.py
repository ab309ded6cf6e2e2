"""The example FMU, unmodified, in two third-party masters: OSP libcosim (libcosimpy) and Ecos (ecospy).

Both are C++ masters that call the FMU from their own threads inside this Python process: this
exercises the bridge's foreign-thread attachment. Optional extras: each test skips, saying why,
only when the package cannot be imported.
"""
from __future__ import annotations

import numpy as np
import pytest

from oscillator_analytic import solution

STOP, STEP = 2.0, 1e-3
X, V = 0, 1  # value references of x and v


def _import(name):
    try:
        return __import__(name)
    except ImportError as exc:  # also OSError-derived loader problems surface as ImportError subclasses
        pytest.skip(f"{name} is not usable here ({exc}); install it with pip install {name}")
    except OSError as exc:  # ecospy needs Debian's libtbb12
        pytest.skip(f"{name} cannot load its native library ({exc}); apt-get install libtbb12")


def test_libcosim(build_fmu_from_src):
    _import("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    execution = CosimExecution.from_step_size(step_size=int(STEP * 1e9))  # nanoseconds
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=str(build_fmu_from_src("oscillator.py")),
                                                      instance_name="osc"))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    samples = []
    for k in range(1, int(STOP / STEP) + 1):
        assert execution.step()
        if k % 100 == 0:
            samples.append((k * STEP, *observer.last_real_values(index, [X, V])))
    samples = np.array(samples)
    x, v, _ = solution(samples[:, 0])
    assert np.max(np.abs(samples[:, 1] - x)) < 1e-5
    assert np.max(np.abs(samples[:, 2] - v)) < 1e-4


def test_ecos(build_fmu_from_src):
    ecospy = _import("ecospy")
    structure = ecospy.EcosSimulationStructure()
    structure.add_model("osc", str(build_fmu_from_src("oscillator.py")))
    samples = []
    with ecospy.EcosSimulation(structure=structure, step_size=STEP) as sim:
        sim.init()
        for k in range(1, int(STOP / STEP) + 1):
            sim.step()
            if k % 100 == 0:
                samples.append((sim.get_time(), sim.get_real("osc::x"), sim.get_real("osc::v")))
        sim.terminate()
    samples = np.array(samples)
    x, v, _ = solution(samples[:, 0])
    assert np.max(np.abs(samples[:, 1] - x)) < 1e-5
    assert np.max(np.abs(samples[:, 2] - v)) < 1e-4
