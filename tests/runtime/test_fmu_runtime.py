"""FMI behaviour of exported components: variables of every type, errors, FMU state, isolation."""
from __future__ import annotations

import math
import os
from ctypes import POINTER, c_double
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.validation import validate_fmu

from deltafmi.builder import build_fmu

COMPONENTS = Path(__file__).parents[1] / "components"
K = np.array([1.0, 2.0, 4.0])


@pytest.fixture(scope="module")
def lags(tmp_path_factory):
    return build_fmu(COMPONENTS / "first" / "model.py", tmp_path_factory.mktemp("lags") / "Lags.fmu")


@pytest.fixture(scope="module")
def counter(tmp_path_factory):
    return build_fmu(COMPONENTS / "second" / "model.py", tmp_path_factory.mktemp("counter") / "Counter.fmu")


class Slave:
    """An FMU2Slave with value references by name and the log messages kept."""

    def __init__(self, fmu: Path, name: str = "instance", **start: float) -> None:
        self.md = fmpy.read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.messages: list[str] = []
        directory = fmpy.extract(str(fmu))
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=directory,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name,
                             fmiCallLogger=None)
        self.fmu.instantiate(callbacks=None, loggingOn=False)
        self.fmu.setupExperiment(startTime=0.0)
        for key, value in start.items():
            self.fmu.setReal([self.vr[key]], [value])
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        self.t = 0.0

    def reset(self) -> None:
        """fmi2Reset, then initialized again from t = 0 with the start values."""
        self.fmu.reset()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        self.t = 0.0

    def real(self, *names: str) -> list[float]:
        return self.fmu.getReal([self.vr[n] for n in names])

    def step(self, h: float, n: int = 1) -> None:
        for _ in range(n):
            self.fmu.doStep(self.t, h)
            self.t += h


def _lag_solution(t, x0=1.0, u=np.zeros(3)):
    return (x0 - u / K) * np.exp(-K * t) + u / K


def test_arrays_become_modelica_scalars(lags):
    assert validate_fmu(str(lags)) == []
    md = fmpy.read_model_description(str(lags))
    names = [v.name for v in md.modelVariables]
    assert names[:6] == ["x[1]", "x[2]", "x[3]", "der(x[1])", "der(x[2])", "der(x[3])"]
    by_name = {v.name: v for v in md.modelVariables}
    assert by_name["der(x[2])"].derivative is by_name["x[2]"]
    assert by_name["k[3]"].start == "4.0" and by_name["k[3]"].unit == "1/s"
    assert by_name["label"].type == "String" and by_name["n_steps"].type == "Integer"
    assert by_name["positive"].type == "Boolean" and by_name["gain"].variability == "tunable"
    # direct_feedthrough = {}: outputs depend on the states only, not on the inputs
    outputs = {u.variable.name: u for u in md.outputs}
    assert {d.name for d in outputs["y[1]"].dependencies} == {"x[1]", "x[2]", "x[3]"}


@pytest.mark.parametrize("fmi_type", ["ModelExchange", "CoSimulation"])
def test_array_states_and_inputs_match_closed_form(lags, fmi_type):
    u = np.array([0.5, -1.0, 2.0])
    start = {f"u[{i + 1}]": u[i] for i in range(3)}
    result = fmpy.simulate_fmu(str(lags), fmi_type=fmi_type, start_values=start, output_interval=0.01,
                               output=["x[1]", "x[2]", "x[3]", "y[3]"], relative_tolerance=1e-10)
    t = result["time"][:, None]
    x = np.column_stack([result[f"x[{i}]"] for i in (1, 2, 3)])
    np.testing.assert_allclose(x, _lag_solution(t, u=u), atol=1e-8)
    np.testing.assert_allclose(result["y[3]"], 2.0 * x[:, 2], rtol=1e-14)


def test_strings_integers_booleans_and_tunable_parameters(lags):
    s = Slave(lags)
    assert s.fmu.getString([s.vr["label"]]) == [b"lags"]
    assert s.fmu.getInteger([s.vr["n_steps"]]) == [3]
    assert s.fmu.getBoolean([s.vr["positive"]]) == [True]
    s.fmu.setReal([s.vr["gain"]], [3.0])  # tunable: allowed in step-complete state
    s.step(0.1)
    x1, y1 = s.real("x[1]", "y[1]")
    assert y1 == pytest.approx(3.0 * x1, rel=1e-15)
    with pytest.raises(FMICallException):  # fixed parameter after initialization
        s.fmu.setReal([s.vr["k[1]"]], [5.0])


def test_setting_an_output_is_an_error(lags):
    s = Slave(lags)
    with pytest.raises(FMICallException):
        s.fmu.setReal([s.vr["y[1]"]], [1.0])


def test_calls_in_the_wrong_state_return_error(lags):
    md = fmpy.read_model_description(str(lags))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(lags)), modelIdentifier="Lags")
    fmu.instantiate()
    with pytest.raises(FMICallException):
        fmu.getReal([0])  # not before initialization mode
    fmu.freeInstance()
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(lags)), modelIdentifier="Lags")
    fmu.instantiate()
    with pytest.raises(FMICallException):
        fmu.doStep(0.0, 0.1)  # not before initialization
    fmu.freeInstance()


def test_python_exception_becomes_fmi2error_with_traceback(lags, capfd):
    s = Slave(lags, fail_at=0.25)
    with pytest.raises(FMICallException) as error:
        s.step(0.1, n=5)
    assert error.value.status == 3
    err = capfd.readouterr()
    assert "Traceback" in err.out + err.err and "deliberate failure" in err.out + err.err
    # the host keeps running: a new instance of the same FMU works
    healthy = Slave(lags, name="healthy")
    healthy.step(0.1, n=5)
    assert healthy.real("x[1]")[0] == pytest.approx(math.exp(-0.5), abs=1e-8)


def test_fmu_state_rollback_and_serialization(lags):
    s = Slave(lags, **{"u[2]": 1.0})
    s.step(0.05, n=10)
    state, t_state = s.fmu.getFMUstate(), s.t
    serialized = s.fmu.serializeFMUstate(state)
    s.step(0.05, n=10)
    reference = s.real("x[1]", "x[2]", "x[3]", "y[2]")
    # replaying from the snapshot reproduces the continuation exactly
    s.fmu.setFMUstate(state)
    s.t = t_state
    s.step(0.05, n=10)
    assert s.real("x[1]", "x[2]", "x[3]", "y[2]") == reference
    s.fmu.setFMUstate(s.fmu.deSerializeFMUstate(serialized))
    s.t = t_state
    s.step(0.05, n=10)
    assert s.real("x[1]", "x[2]", "x[3]", "y[2]") == reference
    np.testing.assert_allclose(reference[:3], _lag_solution(1.0, u=np.array([0, 1.0, 0])), atol=1e-8)
    s.fmu.freeFMUstate(state)


class _RunsACommand:
    """Unpickled, a plain pickle would run ``touch`` on the path it was made with."""

    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return (os.system, (f"touch {self.path}",))


def test_serialized_state_bytes_that_name_a_function_are_refused_and_run_nothing(lags, tmp_path):
    """fmi2DeSerializeFMUstate takes the importer's bytes: ones naming a callable outside what an
    FMU state holds (here os.system, in Python's own bytes after the loader's header) are refused
    with fmi2Error, nothing they name runs, and the instance steps on."""
    import pickle
    import struct

    s = Slave(lags, **{"u[2]": 1.0})
    s.step(0.05, n=4)
    state = s.fmu.getFMUstate()
    good = bytes(s.fmu.serializeFMUstate(state))
    header = struct.calcsize("=IddiiidddQ")
    marker = tmp_path / "ran"
    bad = good[:header] + pickle.dumps({"real": _RunsACommand(marker)}, protocol=pickle.HIGHEST_PROTOCOL)
    with pytest.raises(Exception):
        s.fmu.deSerializeFMUstate(bad)
    assert not marker.exists()
    s.fmu.setFMUstate(s.fmu.deSerializeFMUstate(good))  # its own bytes still load
    s.step(0.05, n=2)
    np.testing.assert_allclose(s.real("x[1]", "x[2]", "x[3]"), _lag_solution(0.3, u=np.array([0, 1.0, 0])), atol=1e-8)
    s.fmu.freeFMUstate(state)


def _global_call(module: str, name: str, args: tuple) -> bytes:
    """Pickle bytes (protocol 2) calling ``module.name(*args)``, ``name`` dotted as the bytes like."""
    import pickle

    return b"\x80\x02c" + f"{module}\n{name}\n".encode() + pickle.dumps(args, protocol=2)[2:-1] + b"R."


def test_serialized_state_bytes_reaching_a_class_through_a_module_attribute_are_refused(lags, tmp_path):
    """A name the bytes give must be what is defined under it: io.FileIO reached as an attribute
    of deltafmi's runtime module (which imports io) is no runtime class, and calling it would
    truncate the file. fmi2DeSerializeFMUstate refuses with fmi2Error and the file keeps its bytes."""
    import struct

    s = Slave(lags, **{"u[2]": 1.0})
    state = s.fmu.getFMUstate()
    good = bytes(s.fmu.serializeFMUstate(state))
    header = struct.calcsize("=IddiiidddQ")
    victim = tmp_path / "results.csv"
    victim.write_text("t,x\n0,1\n")
    for module in ("deltafmi.runtime.state_bytes", "deltafmi.runtime.state_bytes.io"):
        bad = good[:header] + _global_call(module, "io.FileIO" if module.endswith("bytes") else "FileIO",
                                           (str(victim), "w"))
        with pytest.raises(Exception):
            s.fmu.deSerializeFMUstate(bad)
    assert victim.read_text() == "t,x\n0,1\n"
    s.fmu.setFMUstate(s.fmu.deSerializeFMUstate(good))
    s.step(0.05, n=2)
    np.testing.assert_allclose(s.real("x[1]", "x[2]", "x[3]"), _lag_solution(0.1, u=np.array([0, 1.0, 0])), atol=1e-8)
    s.fmu.freeFMUstate(state)


def _lags_in_continuous_time(lags: Path, instance_name: str = "Lags") -> FMU2Model:
    """The Lags FMU's Model Exchange instance, initialized and in continuous-time mode."""
    md = fmpy.read_model_description(str(lags))
    fmu = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(lags)), modelIdentifier="Lags",
                    instanceName=instance_name)
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.newDiscreteStates()
    fmu.enterContinuousTimeMode()
    return fmu


def test_a_model_exchange_state_is_refused_by_a_co_simulation_instance(lags):
    """An FMU state says where in its state machine it was got; one got in continuous-time mode
    by the Model Exchange instance, given (as it is or serialized) to the Co-Simulation instance of
    the same FMU, is refused with fmi2Error: set, it left that instance in a mode none of its calls
    leads out of (fmi2DoStep refused for good). So is a serialized header whose state is no state
    at all (damaged bytes). The Co-Simulation instance steps on from a state of its own."""
    import struct

    me = _lags_in_continuous_time(lags, instance_name="me")
    me_state = me.getFMUstate()
    me_bytes = bytes(me.serializeFMUstate(me_state))
    s = Slave(lags, name="cs", **{"u[2]": 1.0})
    own = s.fmu.getFMUstate()
    own_bytes = bytes(s.fmu.serializeFMUstate(own))
    with pytest.raises(FMICallException):
        s.fmu.setFMUstate(me_state)
    with pytest.raises(FMICallException):
        s.fmu.deSerializeFMUstate(me_bytes)
    at = struct.calcsize("=Idd")  # the header's state machine position
    for damaged in (0x7FF, -1, 3):
        with pytest.raises(FMICallException):
            s.fmu.deSerializeFMUstate(own_bytes[:at] + struct.pack("=i", damaged) + own_bytes[at + 4:])
    s.fmu.setFMUstate(s.fmu.deSerializeFMUstate(own_bytes))
    s.step(0.05, n=4)
    np.testing.assert_allclose(s.real("x[1]", "x[2]", "x[3]"), _lag_solution(0.2, u=np.array([0, 1.0, 0])), atol=1e-8)
    s.fmu.freeFMUstate(own)
    me.freeFMUstate(me_state)
    me.terminate()
    me.freeInstance()


@pytest.mark.parametrize("spoiled", [(b"shared", b"shaRed"), (b"terminate_requested", b"terminate_requesteX")])
def test_a_damaged_state_that_loads_is_refused_and_a_good_one_restores_after_it(lags, spoiled):
    """Bytes damaged where pickle still reads them (one letter of a key) load, but are no
    snapshot: setting them fails with fmi2Error before anything changes. They left an attribute
    named by a tuple on the component (the internal state's marker key, spoilt), after which no
    state restored again, not even a good one; or half a snapshot set. A good state restores
    after them and the instance steps on exactly (closed form)."""
    s = Slave(lags, **{"u[2]": 1.0})
    s.step(0.05, n=4)
    state = s.fmu.getFMUstate()
    good = bytes(s.fmu.serializeFMUstate(state))
    assert good.count(spoiled[0]) == 1
    damaged = s.fmu.deSerializeFMUstate(good.replace(*spoiled))
    with pytest.raises(FMICallException):
        s.fmu.setFMUstate(damaged)
    s.fmu.setFMUstate(state)
    s.step(0.05, n=4)
    np.testing.assert_allclose(s.real("x[1]", "x[2]", "x[3]"), _lag_solution(0.4, u=np.array([0, 1.0, 0])), atol=1e-8)
    s.fmu.freeFMUstate(damaged)
    s.fmu.freeFMUstate(state)


@pytest.mark.parametrize("point, step", [(0.0, math.inf), (math.nan, 0.05)])
def test_a_step_of_no_finite_size_or_from_no_time_is_refused(build_fmu_from_src, point, step):
    """fmi2DoStep(t, inf) and fmi2DoStep(NaN, h) passed the checks (inf > 0; a NaN compares
    false): the oscillator returned fmi2OK at no time in particular, a controller sampling at
    1 kHz sampled for ever. Both are refused with fmi2Error; after fmi2Reset the instance steps on
    (the damped oscillator's closed form before it reaches the wall)."""
    s = Slave(build_fmu_from_src("oscillator.py"))
    with pytest.raises(FMICallException):
        s.fmu.doStep(point, step)
    s.reset()
    s.step(0.05, n=4)
    omega, zeta = 2 * math.pi, 0.2 / (2 * 2 * math.pi)  # k = (2 pi)^2 N/m, m = 1 kg, c = 0.2 N s/m
    wd, t = omega * math.sqrt(1 - zeta ** 2), 0.2
    x = math.exp(-zeta * omega * t) * (math.cos(wd * t) + zeta * omega / wd * math.sin(wd * t))
    assert s.real("x")[0] == pytest.approx(x, abs=1e-6)


@pytest.mark.parametrize("spoil", ["error", "terminate"])
def test_a_state_got_before_an_error_restarts_the_simulation(lags, spoil):
    """FMI 2.0, 2.1.3: after fmi2Error the simulation may go on from an FMU state got before;
    so it may from a terminated one. A deserialized copy of the state does the same."""
    s = Slave(lags, **{"u[2]": 1.0})
    s.step(0.05, n=10)
    state = s.fmu.getFMUstate()
    serialized = s.fmu.serializeFMUstate(state)
    for restore in (lambda: state, lambda: s.fmu.deSerializeFMUstate(serialized)):
        if spoil == "error":
            with pytest.raises(FMICallException):
                s.fmu.doStep(7.0, 0.05)  # not the FMU's time: fmi2Error, the instance in state error
        else:
            s.fmu.terminate()
        s.fmu.setFMUstate(restore())
        s.t = 0.5
        s.step(0.05, n=10)
        np.testing.assert_allclose(s.real("x[1]", "x[2]", "x[3]"), _lag_solution(1.0, u=np.array([0, 1.0, 0])),
                                   atol=1e-8)
    s.fmu.freeFMUstate(state)


def test_a_model_exchange_state_got_before_an_error_restarts_the_integration(lags):
    fmu = _lags_in_continuous_time(lags)
    state = fmu.getFMUstate()
    with pytest.raises(FMICallException):
        fmu.exitInitializationMode()  # not in continuous-time mode: fmi2Error
    fmu.setFMUstate(state)
    fmu.setTime(0.1)
    x, dx = np.array([0.5, 0.25, 2.0]), np.zeros(3)
    fmu.setContinuousStates(x.ctypes.data_as(POINTER(c_double)), 3)
    fmu.getDerivatives(dx.ctypes.data_as(POINTER(c_double)), 3)
    np.testing.assert_array_equal(dx, -K * x)
    fmu.freeFMUstate(state)
    fmu.terminate()
    fmu.freeInstance()


def test_an_fmu_unpacked_in_a_folder_whose_name_is_not_utf8_runs(lags, tmp_path):
    """A file name is bytes: a resources folder named in Latin-1 is read as Python reads file names."""
    md = fmpy.read_model_description(str(lags))
    folder = fmpy.extract(str(lags), unzipdir=str(tmp_path / os.fsdecode(b"caf\xe9")))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier="Lags")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    for i in range(10):
        fmu.doStep(i * 0.1, 0.1)
    np.testing.assert_allclose(fmu.getReal([0, 1, 2]), _lag_solution(1.0), atol=1e-8)
    fmu.terminate()
    fmu.freeInstance()


def test_discrete_component_state_includes_python_attributes(counter):
    s = Slave(counter, u=2.0)
    s.step(0.1, n=3)
    state = s.fmu.getFMUstate()
    s.step(0.1, n=3)
    assert s.real("total") == pytest.approx([1.2])
    s.fmu.setFMUstate(state)
    assert s.real("total") == pytest.approx([0.6])
    assert s.fmu.getInteger([s.vr["count"]]) == [3]


def test_sources_with_the_same_file_name_coexist(lags, counter):
    """Both FMUs ship model.py; each is imported under its own unique module name."""
    a, b = Slave(lags, name="a"), Slave(counter, name="b", u=1.0, scale=10.0)
    for _ in range(10):
        a.step(0.1)
        b.step(0.1)
    assert a.real("x[3]")[0] == pytest.approx(math.exp(-4.0), abs=1e-8)
    assert b.real("total")[0] == pytest.approx(10.0)


def test_three_instances_of_one_fmu_side_by_side(lags):
    slaves = [Slave(lags, name=f"lag{i}", **{"x[1]": float(i + 1)}) for i in range(3)]
    for _ in range(20):
        for s in slaves:
            s.step(0.05)
    for i, s in enumerate(slaves):
        assert s.real("x[1]")[0] == pytest.approx((i + 1) * math.exp(-1.0), abs=1e-8)


def test_reset_restores_start_values(lags):
    s = Slave(lags)
    s.step(0.1, n=5)
    s.reset()
    assert s.real("x[1]") == [1.0]
    s.step(0.1, n=5)
    assert s.real("x[1]")[0] == pytest.approx(math.exp(-0.5), abs=1e-8)


@pytest.mark.parametrize("model", ["lags", "counter"])  # integrated by CVODE; stepping itself
def test_a_step_from_another_time_is_an_error(model, request, capfd):
    s = Slave(request.getfixturevalue(model))
    s.step(0.1, n=2)
    with pytest.raises(FMICallException) as error:
        s.fmu.doStep(0.1, 0.1)  # the FMU is at 0.2
    assert error.value.status == 3
    err = capfd.readouterr()
    assert "currentCommunicationPoint 0.1 differs from the FMU time 0.2" in err.out + err.err


def test_reset_of_a_component_that_steps_itself(counter):
    s = Slave(counter, u=2.0)
    s.step(0.1, n=4)
    s.reset()
    assert s.real("total") == [0.0] and s.fmu.getInteger([s.vr["count"]]) == [0]
    s.step(0.1, n=3)  # u is back at its start value 1.0
    assert s.real("total")[0] == pytest.approx(0.3, abs=1e-15)
    assert s.fmu.getInteger([s.vr["count"]]) == [3]


def test_a_component_that_steps_itself_sees_every_step_size(counter):
    """The bridge passes the float of an unchanged step size again: a changed size must arrive."""
    s = Slave(counter, u=2.0)
    sizes = [0.1, 0.1, 0.25, 0.05, 0.05, 1e-3, 0.1]
    for h in sizes:
        s.step(h)
    expected = 0.0
    for h in sizes:  # Counter: accumulated += u * h, in the same order
        expected += 2.0 * h
    assert s.real("total") == [expected]
    assert s.fmu.getInteger([s.vr["count"]]) == [len(sizes)]


def test_the_python_time_follows_a_component_that_steps_itself(counter):
    """Such a step leaves FmuInstance.time to the next call that may read it (the bridge's
    catch_up_time): the snapshot of fmi2GetFMUstate, taken in Python, holds the step's end."""
    import pickle
    import struct

    s = Slave(counter, u=2.0)
    s.step(0.1, n=3)
    state = s.fmu.getFMUstate()
    data = bytes(s.fmu.serializeFMUstate(state))
    # the loader's own copy (magic, time, last successful time; the instance's state machine
    # position, stop and tolerance defined, start, stop, tolerance, active clocks), then Python's bytes
    header = "=IddiiidddQ"
    _, loader_time, _, position, *_ = struct.unpack_from(header, data)
    assert loader_time == s.t and position == 1 << 5  # step complete
    assert pickle.loads(data[struct.calcsize(header):])["time"] == s.t
    s.step(0.1, n=2)
    s.fmu.setFMUstate(state)  # back at 0.3: stepping on from there is accepted and counts from 3
    s.t = loader_time
    s.step(0.1)
    assert s.fmu.getInteger([s.vr["count"]]) == [4]
    s.fmu.freeFMUstate(state)
