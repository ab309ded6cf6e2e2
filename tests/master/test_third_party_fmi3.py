"""Third-party-style FMI 3.0 FMUs: the plain-C models of tests/third_party built as FMI 3.0 (ME and
CS in one binary at binaries/x86_64-linux, exporting only fmi3 functions, no Python) pass fmpy's
validation and, run by ``fmpy.simulate_fmu`` and by fmpy's FMU3 classes call by call, agree with
closed forms: every FMI 3.0 type round-tripped (Int64/UInt64 extremes, Float32 rounding, Binary,
Enumeration), the array-valued state-space model against scipy's matrix exponential, the bouncing
ball's impacts (Co-Simulation with and without Event Mode), the time events and the termination
time, the table read from the resources; and calls out of the state machine return fmi3Error.
"""
from __future__ import annotations

import ctypes
import re
import shutil
import subprocess
from pathlib import Path

import fmpy
import numpy as np
import pytest
import scipy.linalg
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.validation import validate_fmu

from test_third_party_fmus import ball_exact
from third_party.build import MODELS3, build_all3

NATIVE = Path(__file__).parents[2] / "deltafmi" / "runtime" / "native"
TABLE = np.loadtxt(Path(__file__).parents[1] / "third_party" / "Table3" / "resources" / "table.txt")
ERROR = 3  # fmi3Error


@pytest.fixture(scope="session")
def fmus(tmp_path_factory) -> dict:
    """``{model: .fmu}`` of every FMI 3.0 C model, compiled once per session."""
    return build_all3(tmp_path_factory.mktemp("third_party3"))


class Log(list):
    """The messages an FMU logs, as (status, category, message)."""

    def __call__(self, environment, status, category, message):
        self.append((status, category.decode(), message.decode()))


def open_instance(fmu: Path, tmp_path: Path, interface: str, log: Log = None, **instantiate):
    """An instantiated FMU3Slave or FMU3Model of ``fmu`` (extracted to ``tmp_path``)."""
    md = fmpy.read_model_description(str(fmu))
    unzipped = fmpy.extract(str(fmu), unzipdir=str(tmp_path / "unzipped"))
    cls = FMU3Slave if interface == "CS" else FMU3Model
    instance = cls(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
                   instanceName="it")
    instance.instantiate(logMessage=log, loggingOn=log is not None, **instantiate)
    return instance


def initialized(instance, start: dict = None):
    """``instance`` through initialization (``start``: {setter name: (vrs, values)})."""
    instance.enterInitializationMode(startTime=0.0)
    for setter, (vrs, values) in (start or {}).items():
        getattr(instance, setter)(vrs, values)
    instance.exitInitializationMode()
    return instance


def raw(instance, function: str, *args) -> int:
    """The status of the fmi3 ``function`` called straight from the binary (for what fmpy's class
    of the other interface does not offer)."""
    return getattr(instance.dll, function)(ctypes.c_void_p(instance.component), *args)


def fails(call, *args) -> bool:
    """``call(*args)`` returns fmi3Error."""
    with pytest.raises(FMICallException) as raised:
        call(*args)
    return raised.value.status == ERROR


# --- the FMUs themselves ---------------------------------------------------------------------------

def declared_functions() -> set:
    header = (NATIVE / "fmi3Functions.h").read_text()
    return set(re.findall(r"FMI3_Export fmi3\w+TYPE\s+(fmi3\w+);", header))


@pytest.mark.parametrize("model", MODELS3)
def test_fmus_are_valid_plain_c_fmi3(fmus, tmp_path, model):
    fmu = fmus[model]
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu), validate=True)
    assert md.fmiVersion == "3.0" and md.modelExchange is not None and md.coSimulation is not None
    binary = Path(fmpy.extract(str(fmu), unzipdir=str(tmp_path))) / "binaries" / "x86_64-linux" / f"{model}.so"
    exported = subprocess.run(["nm", "-D", "--defined-only", binary], capture_output=True, text=True,
                              check=True).stdout.split()
    functions = {name for kind, name in zip(exported[1::3], exported[2::3]) if kind == "T"}
    declared = declared_functions()
    assert len(declared) > 70 and functions == declared  # all of the API and nothing else
    linked = subprocess.run(["ldd", binary], capture_output=True, text=True, check=True).stdout
    libraries = {line.split()[0].split(".so")[0] for line in linked.splitlines() if line.strip()}
    assert libraries <= {"linux-vdso", "libc", "libm", "/lib64/ld-linux-x86-64"}, libraries


# --- AllTypes3: every type round-tripped ------------------------------------------------------------

EXTREMES = {  # setter/getter type: (input vr, output vr, values to pass through)
    "Int8": (10, 11, [-128, 127]),
    "UInt8": (12, 13, [0, 255]),
    "Int16": (14, 15, [-32768, 32767]),
    "UInt16": (16, 17, [0, 65535]),
    "Int32": (18, 19, [-2**31, 2**31 - 1]),
    "UInt32": (20, 21, [0, 2**32 - 1]),
    "Int64": (22, 23, [-2**63, 2**63 - 1]),
    "UInt64": (24, 25, [0, 2**64 - 1]),
}


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_all_types_pass_every_value_through(fmus, tmp_path, interface):
    fmu = initialized(open_instance(fmus["AllTypes3"], tmp_path, interface))
    if interface == "ME":
        fmu.updateDiscreteStates()  # stays in Event Mode, where discrete inputs may be set
    for type_, (u, y, values) in EXTREMES.items():
        for value in values:
            getattr(fmu, f"set{type_}")([u], [value])
            assert getattr(fmu, f"get{type_}")([y]) == [value], (type_, value)
    fmu.setFloat32([1], [0.1])
    assert fmu.getFloat32([2]) == [np.float32(0.1)] and fmu.getFloat32([2])[0] != 0.1  # rounded to 24 bits
    fmu.setFloat64([5, 3], [-2.5, 0.1])
    assert fmu.getFloat64([4]) == [-2.5 * 0.1]
    fmu.setBoolean([30, 32], [True, True])
    assert fmu.getBoolean([31]) == [False]
    fmu.setString([42, 40], ["ünï: ", 'say "hi", then stop'])
    assert fmu.getString([41]) == ['ünï: say "hi", then stop']
    payload = bytes([0, 255, 0, 1, 2]) * 40
    fmu.setBinary([50], [payload])
    assert fmu.getBinary([51]) == [payload]
    fmu.setInt64([60], [3])
    assert fmu.getInt64([61]) == [3]
    if interface == "ME":  # in Continuous-Time Mode, continuous inputs only
        fmu.enterContinuousTimeMode()
        fmu.setFloat64([3], [1.0])
        assert fails(fmu.setInt8, [10], [1]) and fmu.getInt8([11]) == [127]
        fmu.enterEventMode()
    # an Enumeration out of range, a String too long, a Binary too large are refused and change nothing
    assert fails(fmu.setInt64, [60], [4])
    fmu.setInt64([60], [2])
    assert fails(fmu.setString, [40], ["x" * 300])
    assert fails(fmu.setBinary, [50], [bytes(257)])
    assert fmu.getInt64([61]) == [2] and fmu.getBinary([51]) == [payload] and fmu.getString([41])[0].endswith("stop")


def test_all_types_through_simulate_fmu(fmus):
    """The same through fmpy's simulation: start values of every type, outputs recorded."""
    start = {"u_f32": 0.1, "u_f64": 3.0, "scale": 0.5, "u_bool": True, "invert": False, "u_color": 3}
    start.update({f"u_{short}": values[0] for short, values in zip(
        ["i8", "u8", "i16", "u16", "i32", "u32", "i64", "u64"], [v[2][::-1] for v in EXTREMES.values()])})
    for interface in ("ModelExchange", "CoSimulation"):
        r = fmpy.simulate_fmu(str(fmus["AllTypes3"]), fmi_type=interface, stop_time=0.3, output_interval=0.1,
                              start_values=start, output=["y_f32", "y_f64", "y_bool", "y_color", "y_i64", "y_u64",
                                                          "y_i8", "y_u8", "y_i16", "y_u16", "y_i32", "y_u32"])
        assert len(r) == 4
        assert np.all(r["y_f32"] == np.float32(0.1)) and np.all(r["y_f64"] == 1.5) and np.all(r["y_bool"])
        assert np.all(r["y_color"] == 3)
        for short in ["i8", "u8", "i16", "u16", "i32", "u32", "i64", "u64"]:
            assert np.all(r[f"y_{short}"] == start[f"u_{short}"]), short
        assert r["y_i64"][0] == 2**63 - 1 and r["y_u64"][0] == 2**64 - 1


# --- StateSpace3: arrays --------------------------------------------------------------------------

A = np.array([[-0.5, 3.0, 0.0], [-1.0, -0.2, 0.4], [0.3, 0.0, -1.5]])  # not symmetric: tells row-major
B = np.array([[1.0, 0.0], [0.0, 0.0], [0.5, 1.0]])
C = np.array([[1.0, 0.0, -1.0], [0.0, 2.0, 1.0]])
D = np.array([[0.0, 0.25], [0.0, 0.5]])
X0, U = np.array([1.0, -0.5, 0.25]), np.array([0.8, -0.3])


def state_space_exact(t: np.ndarray):
    """x(t), y(t) for constant u: [x; 1](t) = expm(t [A, B u; 0, 0]) [x0; 1]."""
    m = np.zeros((4, 4))
    m[:3, :3], m[:3, 3] = A, B @ U
    x = np.array([(scipy.linalg.expm(ti * m) @ np.r_[X0, 1.0])[:3] for ti in t])
    return x, x @ C.T + D @ U


@pytest.mark.parametrize("interface, atol", [("CoSimulation", 1e-13), ("ModelExchange", 1e-8)])
def test_state_space_arrays_match_the_matrix_exponential(fmus, interface, atol):
    start = {"A": A.ravel(), "B": B.ravel(), "C": C.ravel(), "D": D.ravel(), "x": X0, "u": U}
    r = fmpy.simulate_fmu(str(fmus["StateSpace3"]), fmi_type=interface, stop_time=2.0, output_interval=0.1,
                          start_values=start, output=["x", "y"], relative_tolerance=1e-12)
    x, y = state_space_exact(r["time"])
    assert r["x"].shape == (21, 3) and r["y"].shape == (21, 2)
    deviation = max(np.max(np.abs(r["x"] - x)), np.max(np.abs(r["y"] - y)))
    print(f"StateSpace3 {interface}: max deviation from expm {deviation:.1e}")
    assert deviation <= atol


def test_state_space_arrays_are_row_major_and_checked(fmus, tmp_path):
    fmu = initialized(open_instance(fmus["StateSpace3"], tmp_path, "ME"),
                      {"setFloat64": ([1, 2, 3, 4, 6, 5], [*A.ravel(), *B.ravel(), *C.ravel(), *D.ravel(), *X0, *U])})
    assert fmu.getFloat64([1], nValues=9) == list(A.ravel())
    assert fmu.getFloat64([7, 8], nValues=5) == list(A @ X0 + B @ U) + list(C @ X0 + D @ U)
    assert fails(fmu.getFloat64, [7, 8], 4)  # nValues too few for der(x) and y
    assert fails(fmu.getFloat64, [7, 8], 6)  # or too many
    assert fails(fmu.setFloat64, [1], list(A.ravel()))  # A is fixed: not after initialization


# --- BouncingBall3: state events ------------------------------------------------------------------

BALL = ["h", "v", "bounces"]


@pytest.mark.parametrize("kind", ["ME", "CS", "CS event mode", "CS event mode, early return"])
def test_bouncing_ball_matches_closed_form(fmus, kind):
    options = {"fmi_type": "ModelExchange" if kind == "ME" else "CoSimulation"}
    if "event mode" in kind:
        options.update(use_event_mode=True, early_return_allowed="early" in kind)
    r = fmpy.simulate_fmu(str(fmus["BouncingBall3"]), stop_time=3.0, output_interval=0.01, output=BALL,
                          relative_tolerance=1e-12, **options)
    h, impacts = ball_exact(r["time"])
    assert r["bounces"][-1] == len(impacts) == 11
    atol = 1e-9 if kind == "ME" else 1e-12
    on_grid = np.r_[True, np.diff(r["time"]) > 0]  # at an event, the row before it
    np.testing.assert_allclose(r["h"][on_grid], h[on_grid], rtol=0, atol=atol)
    events = r["time"][1:][np.diff(r["time"]) == 0]
    if kind in ("ME", "CS event mode, early return"):  # a row at each impact, and one after it
        np.testing.assert_allclose(events, impacts, rtol=0, atol=atol)
    else:  # Co-Simulation handles the impacts inside its steps: grid rows only
        assert len(r) == 301 and len(events) == 0


def test_bouncing_ball_returns_early_at_the_impact(fmus, tmp_path):
    """Call by call: fmi3DoStep stops at the first impact with eventHandlingNeeded and earlyReturn;
    the importer handles it in Event Mode (v := -e v) and steps on."""
    fmu = initialized(open_instance(fmus["BouncingBall3"], tmp_path, "CS", eventModeUsed=True,
                                    earlyReturnAllowed=True))
    assert fmu.updateDiscreteStates()[0] is False
    fmu.enterStepMode()
    impact = np.sqrt(2 / 9.81)
    event, terminate, early, t = fmu.doStep(0.0, 1.0)
    assert (event, terminate, early) == (True, False, True) and abs(t - impact) < 1e-15
    assert fmu.getFloat64([1])[0] == 0 and fmu.getFloat64([3])[0] == pytest.approx(-9.81 * impact, abs=1e-12)
    assert fails(fmu.doStep, 0.0, 1.0)  # from where it stopped, not from the old point
    fmu.enterEventMode()
    assert fmu.updateDiscreteStates()[3] is True  # valuesOfContinuousStatesChanged
    fmu.enterStepMode()
    assert fmu.getFloat64([3])[0] == pytest.approx(0.7 * 9.81 * impact, abs=1e-12)
    assert fmu.getInt32([8]) == [1]
    assert fmu.doStep(t, 0.1)[:3] == (False, False, False)


def test_fmu_state_serializes(fmus, tmp_path):
    fmu = initialized(open_instance(fmus["BouncingBall3"], tmp_path, "CS"))
    fmu.doStep(0.0, 0.3)
    data = fmu.serializeFMUState(fmu.getFMUState())
    fmu.doStep(0.3, 0.7)
    later = fmu.getFloat64([1, 3])
    fmu.setFMUState(fmu.deserializeFMUState(data))
    assert fmu.getFloat64([0]) == [0.3]
    fmu.doStep(0.3, 0.7)
    assert fmu.getFloat64([1, 3]) == later


# --- Stopper3: time events and termination --------------------------------------------------------

@pytest.mark.parametrize("kind", ["ME", "CS early return", "CS event mode, early return"])
def test_stopper_samples_and_terminates(fmus, kind):
    options = {"fmi_type": "ModelExchange" if kind == "ME" else "CoSimulation"}
    if kind.startswith("CS"):
        options.update(use_event_mode="event mode" in kind, early_return_allowed=True)
    r = fmpy.simulate_fmu(str(fmus["Stopper3"]), stop_time=3.0, output_interval=0.1, start_values={"u": 0.75},
                          output=["held", "samples", "stopped"], **options)
    assert r["time"][-1] == pytest.approx(1.55, abs=1e-12)  # terminated at stop_time, not at 3 s
    assert r["samples"][-1] == 6 and np.all(r["held"] == 0.75)  # at 0.25, 0.5, ..., 1.5 s
    # the samples at 0.25 s, 0.5 s, ...: a count of floor(t / 0.25) on the rows between events
    inside = np.abs(r["time"] / 0.25 - np.round(r["time"] / 0.25)) > 1e-9
    np.testing.assert_array_equal(r["samples"][inside], np.floor(r["time"][inside] / 0.25))


@pytest.mark.parametrize("early_return", [False, True])
def test_stopper_terminates_inside_a_step(fmus, tmp_path, early_return):
    log = Log()
    fmu = initialized(open_instance(fmus["Stopper3"], tmp_path, "CS", log, earlyReturnAllowed=early_return))
    assert fmu.doStep(0.0, 1.5) == (False, False, False, 1.5)
    assert fmu.getUInt32([5]) == [6]
    event, terminate, early, t = fmu.doStep(1.5, 0.1)
    assert (event, terminate, early) == (False, True, early_return) and t == pytest.approx(1.55, abs=1e-15)
    assert fmu.getBoolean([6]) == [True]
    assert (0, "logEvents", "stop_time 1.55 reached after 6 samples: terminating") in log
    fmu.terminate()


def test_stopper_terminates_from_update_discrete_states(fmus, tmp_path):
    fmu = initialized(open_instance(fmus["Stopper3"], tmp_path, "ME"))
    update = fmu.updateDiscreteStates()
    assert update == (False, False, False, False, True, 0.25)  # next time event at the first sample
    fmu.enterContinuousTimeMode()
    for t in [0.25, 0.5, 0.75, 1.0, 1.25, 1.5]:
        fmu.setTime(t)
        fmu.enterEventMode()
        update = fmu.updateDiscreteStates()
        fmu.enterContinuousTimeMode()
    assert update[1:] == (False, False, False, True, 1.55) and fmu.getUInt32([5]) == [6]
    fmu.setTime(1.55)
    fmu.enterEventMode()
    assert fmu.updateDiscreteStates()[1] is True  # terminateSimulation
    fmu.terminate()


# --- Table3: resources ----------------------------------------------------------------------------

@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
def test_table_interpolates_its_resource_file(fmus, interface):
    signal = np.array([(0.0, -5.0), (1.0, 35.0)], dtype=[("time", np.float64), ("u", np.float64)])
    r = fmpy.simulate_fmu(str(fmus["Table3"]), fmi_type=interface, stop_time=1.0, output_interval=0.01,
                          input=signal, output=["u", "y", "rows"])
    assert len(TABLE) == 6 and np.all(r["rows"] == 6)
    assert r["u"].min() < TABLE[0, 0] and r["u"].max() > TABLE[-1, 0]  # beyond both ends
    np.testing.assert_allclose(r["y"], np.interp(r["u"], TABLE[:, 0], TABLE[:, 1]), rtol=0, atol=1e-12)


def test_table_without_its_resources_does_not_instantiate(fmus, tmp_path):
    unzipped = Path(fmpy.extract(str(fmus["Table3"]), unzipdir=str(tmp_path / "unzipped")))
    shutil.rmtree(unzipped / "resources")
    md = fmpy.read_model_description(str(fmus["Table3"]))
    log = Log()
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=str(unzipped), modelIdentifier="Table3", instanceName="it")
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate(logMessage=log, loggingOn=True)
    assert log == [(ERROR, "logStatusError", f"cannot open the table '{unzipped}/resources/table.txt'")]


# --- the state machine ----------------------------------------------------------------------------

def test_calls_out_of_the_state_machine_return_error(fmus, tmp_path):
    log = Log()
    cs = open_instance(fmus["BouncingBall3"], tmp_path, "CS", log)
    assert fails(cs.doStep, 0.0, 0.1)                      # before initialization
    assert fails(cs.getFloat64, [1])                       # no values before initialization
    assert fails(cs.exitInitializationMode)                # not in Initialization Mode
    assert fails(cs.setInt32, [8], [3])                    # bounces is an output
    assert fails(cs.setFloat64, [8], [3.0])                # and an Int32, not a Float64
    assert fails(cs.setFloat64, [99], [3.0])               # no such variable
    assert fails(cs.setFloat64, [6], [1.5])                # e outside [0, 1]
    initialized(cs)
    assert fails(cs.setFloat64, [5], [1.62])               # g is fixed
    assert fails(cs.enterEventMode)                        # instantiated without Event Mode
    assert raw(cs, "fmi3EnterContinuousTimeMode") == ERROR  # a Model Exchange function
    assert fails(cs.doStep, 0.5, 0.1)                      # the FMU is at 0, not 0.5
    assert fails(cs.doStep, 0.0, -0.1)                     # no steps backwards
    assert fails(cs.enterConfigurationMode)                # no structural parameters
    assert raw(cs, "fmi3GetDirectionalDerivative", None, 0, None, 0, None, 0, None, 0) == ERROR
    cs.setFloat64([6], [0.5])                              # e is tunable
    cs.terminate()
    assert fails(cs.doStep, 0.0, 0.1)
    assert all(status == ERROR and category == "logStatusError" for status, category, _ in log)
    assert (ERROR, "logStatusError", "fmi3EnterEventMode: the importer instantiated this FMU without "
            "Event Mode") in log
    assert len(log) == 15
    me = initialized(open_instance(fmus["BouncingBall3"], tmp_path / "me", "ME"))
    assert fails(me.setTime, 0.1)                          # Event Mode: time advances in Continuous-Time Mode
    assert raw(me, "fmi3EnterStepMode") == ERROR           # a Co-Simulation function
    me.updateDiscreteStates()
    me.enterContinuousTimeMode()
    assert fails(me.updateDiscreteStates)                  # only in Event Mode
    assert fails(me.setContinuousStates, (fmpy.fmi3.fmi3Float64 * 3)(), 3)  # there are 2 states


def test_a_wrong_instantiation_token_is_refused(fmus, tmp_path):
    unzipped = fmpy.extract(str(fmus["AllTypes3"]), unzipdir=str(tmp_path / "unzipped"))
    log = Log()
    fmu = FMU3Model(guid="{not-this-one}", unzipDirectory=unzipped, modelIdentifier="AllTypes3", instanceName="it")
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate(logMessage=log, loggingOn=True)
    assert log and log[0][0] == ERROR and "instantiationToken" in log[0][2]


def test_logging_respects_the_settings(fmus, tmp_path):
    """logMessage is not called with logging off; fmi3SetDebugLogging chooses the categories."""
    quiet = Log()
    fmu = open_instance(fmus["Stopper3"], tmp_path, "CS", quiet)
    fmu.setDebugLogging(False, [])
    assert fails(fmu.doStep, 0.0, 0.1) and quiet == []
    fmu.setDebugLogging(True, ["logStatusError"])
    initialized(fmu)
    fmu.doStep(0.0, 2.0)  # terminates at 1.55: a logEvents message, not shown
    assert fails(fmu.setFloat64, [1], [0.5])  # period is fixed
    assert [category for _, category, _ in quiet] == ["logStatusError"]
    fmu.setDebugLogging(True, [])
    fmu.doStep(1.55, 0.1)  # a step after termination: a warning
    assert quiet[-1][:2] == (1, "logStatusWarning")
    assert fails(fmu.setDebugLogging, True, ["logEverything"])
