"""An FMU state puts the instance back where it was taken, its place in the FMI state machine
included (FMI 2.0 and 3.0, Co-Simulation and Model Exchange, through fmpy on our binaries): a
state taken before fmiXTerminate steps on after it, a state taken before initialization
initializes again, and a serialized state carries its place as well. The lags are
x_i' = -k_i x_i + u_i, x_i(0) = 1: x_i(t) = u_i / k_i + (1 - u_i / k_i) exp(-k_i t)."""
from __future__ import annotations

import ctypes
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model, FMU3Slave

from deltafmi.builder.packager import build_cached

LAGS = Path(__file__).parents[1] / "components" / "first" / "model.py"
K = np.array([1.0, 2.0, 4.0])
H = 0.05


def _closed_form(t: float, u: np.ndarray) -> np.ndarray:
    return u / K + (1.0 - u / K) * np.exp(-K * t)


class Lags:
    """The lags FMU of one FMI version, unzipped, with the value references of x and u."""

    def __init__(self, version: int, directory: Path) -> None:
        fmu = build_cached(LAGS, fmi_version=version)
        self.version = version
        self.md = fmpy.read_model_description(str(fmu))
        self.dir = fmpy.extract(str(fmu), str(directory))
        vr = {v.name: v.valueReference for v in self.md.modelVariables}
        if version == 2:
            self.x, self.u = [vr[f"x[{i}]"] for i in (1, 2, 3)], [vr[f"u[{i}]"] for i in (1, 2, 3)]
        else:
            self.x, self.u = [vr["x"]], [vr["u"]]

    def instance(self, interface: str):
        cls = {(2, "CS"): FMU2Slave, (2, "ME"): FMU2Model, (3, "CS"): FMU3Slave, (3, "ME"): FMU3Model}[
            self.version, interface]
        md = self.md.coSimulation if interface == "CS" else self.md.modelExchange
        fmu = cls(guid=self.md.guid, unzipDirectory=self.dir, modelIdentifier=md.modelIdentifier,
                  instanceName=interface.lower())
        fmu.instantiate()
        return fmu

    def set_u(self, fmu, u) -> None:
        if self.version == 2:
            fmu.setReal(self.u, list(u))
        else:
            fmu.setFloat64(self.u, list(u))

    def get_x(self, fmu) -> list:
        return list(fmu.getReal(self.x) if self.version == 2 else fmu.getFloat64(self.x, nValues=3))

    def initialize(self, fmu, u) -> None:
        if self.version == 2:
            fmu.setupExperiment(startTime=0.0)
            self.set_u(fmu, u)
            fmu.enterInitializationMode()
        else:
            self.set_u(fmu, u)
            fmu.enterInitializationMode(startTime=0.0)
        fmu.exitInitializationMode()

    def steps(self, fmu, t: float, n: int) -> list:
        """``n`` Co-Simulation steps from ``t``: the states after each."""
        rows = []
        for _ in range(n):
            fmu.doStep(t, H)
            t += H
            rows.append(self.get_x(fmu))
        return rows


@pytest.fixture(scope="module", params=[2, 3], ids=["fmi2", "fmi3"])
def lags(request, tmp_path_factory) -> Lags:
    return Lags(request.param, tmp_path_factory.mktemp(f"lags{request.param}"))


U = [0.0, 1.0, 0.0]


def test_a_state_taken_before_terminate_steps_on_after_it(lags):
    fmu = lags.instance("CS")
    lags.initialize(fmu, U)
    lags.steps(fmu, 0.0, 10)
    state = fmu.getFMUState() if lags.version == 3 else fmu.getFMUstate()
    first = lags.steps(fmu, 10 * H, 10)
    fmu.terminate()
    (fmu.setFMUState if lags.version == 3 else fmu.setFMUstate)(state)
    again = lags.steps(fmu, 10 * H, 10)  # back in step mode at t = 0.5
    assert again == first
    np.testing.assert_allclose(again[-1], _closed_form(20 * H, np.array(U)), atol=1e-7)
    fmu.terminate()
    fmu.freeInstance()


def test_a_serialized_state_carries_its_place_in_the_state_machine(lags):
    fmu = lags.instance("CS")
    lags.initialize(fmu, U)
    lags.steps(fmu, 0.0, 4)
    if lags.version == 3:
        data = fmu.serializeFMUState(fmu.getFMUState())
    else:
        data = fmu.serializeFMUstate(fmu.getFMUstate())
    first = lags.steps(fmu, 4 * H, 6)
    fmu.terminate()
    if lags.version == 3:
        fmu.setFMUState(fmu.deserializeFMUState(data))
    else:
        fmu.setFMUstate(fmu.deSerializeFMUstate(data))
    assert lags.steps(fmu, 4 * H, 6) == first
    fmu.terminate()
    fmu.freeInstance()


def test_a_state_taken_before_initialization_initializes_again(lags):
    """Set in the instantiated state's snapshot, a terminated instance takes start values and
    initializes as a fresh one does (the start values set after the snapshot are undone)."""
    fmu = lags.instance("CS")
    fresh = (fmu.getFMUState if lags.version == 3 else fmu.getFMUstate)()
    lags.initialize(fmu, [5.0, 5.0, 5.0])
    lags.steps(fmu, 0.0, 3)
    fmu.terminate()
    (fmu.setFMUState if lags.version == 3 else fmu.setFMUstate)(fresh)
    lags.initialize(fmu, U)
    rows = lags.steps(fmu, 0.0, 20)
    other = lags.instance("CS")
    lags.initialize(other, U)
    assert rows == lags.steps(other, 0.0, 20)
    np.testing.assert_allclose(rows[-1], _closed_form(20 * H, np.array(U)), atol=1e-7)
    for f in (fmu, other):
        f.terminate()
        f.freeInstance()


def test_model_exchange_goes_back_to_event_mode(lags):
    """A state taken in Event Mode right after initialization: after continuous-time mode and
    terminate, setting it allows the event iteration again and the states are the initial ones."""
    fmu = lags.instance("ME")
    lags.initialize(fmu, U)
    state = (fmu.getFMUState if lags.version == 3 else fmu.getFMUstate)()
    x0 = _states(fmu)
    if lags.version == 2:
        fmu.newDiscreteStates()
    else:
        fmu.updateDiscreteStates()
    fmu.enterContinuousTimeMode()
    fmu.setTime(0.3)
    fmu.terminate()
    (fmu.setFMUState if lags.version == 3 else fmu.setFMUstate)(state)
    if lags.version == 2:
        fmu.newDiscreteStates()  # only in event mode
    else:
        fmu.updateDiscreteStates()
    fmu.enterContinuousTimeMode()
    assert _states(fmu) == x0 == [1.0, 1.0, 1.0]
    fmu.terminate()
    fmu.freeInstance()


def _states(fmu) -> list:
    x = (ctypes.c_double * 3)()
    fmu.getContinuousStates(x, 3)
    return list(x)


def test_in_a_c_host_a_state_set_after_terminate_steps_on(c_host, tmp_path):
    """The plain C host (tests/c_host/host.c, mode restore): fmi2GetFMUstate halfway, the steps to
    the end, fmi2Terminate, fmi2SetFMUstate, and the second half again gives the same rows bit
    for bit (the lags against their closed form)."""
    import subprocess

    lags = Lags(2, tmp_path / "lags")
    run = subprocess.run([str(c_host), lags.dir, lags.md.coSimulation.modelIdentifier, lags.md.guid, "restore", "1.0",
                          str(H), *map(str, lags.x)], capture_output=True, text=True, timeout=600,
                         env={"PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stderr
    first, again = run.stdout.split("again\n")
    assert first == again and len(first.split()) == 10
    t, *x = map(float, first.split()[-1].split(","))
    np.testing.assert_allclose(x, _closed_form(t, np.zeros(3)), atol=1e-7)
