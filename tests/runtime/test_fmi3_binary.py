"""The FMI 3.0 binary (deltafmi/runtime/native/fmi3.c over core.c) through fmpy's fmi3 calls and the
plain-C FMI 3.0 host (tests/c_host/host3.c): arrays against the FMI 2.0 build's scalars, the state
machine's errors, FMU state, exact partial derivatives, Co-Simulation event mode and the end of a
simulation asked for by the component."""
from __future__ import annotations

import ctypes
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model, FMU3Slave, fmi3LogMessageCallback

from conftest import FMU_SRC, NATIVE, ROOT, unzip
from deltafmi.builder.compiler import exported_symbols, fmu_binary
from test_portable_fmus import no_python  # noqa: F401 - the fixture: a command prefix where no Python exists

COMPONENTS = ROOT / "tests" / "components"


def _build(source: Path, version: int) -> Path:
    from deltafmi.builder.packager import build_cached
    return build_cached(source, fmi_version=version)


@pytest.fixture(scope="module")
def host3(tmp_path_factory) -> Path:
    exe = tmp_path_factory.mktemp("host3") / "host3"
    subprocess.run(["cc", "-O2", "-Wall", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "host3.c"), "-o", str(exe),
                    "-ldl", "-lm"], check=True)
    return exe


@pytest.fixture(scope="module")
def host2(tmp_path_factory) -> Path:
    exe = tmp_path_factory.mktemp("host2") / "host"
    subprocess.run(["cc", "-O2", "-Wall", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "host.c"), "-o", str(exe),
                    "-ldl", "-lm"], check=True)
    return exe


class Opened:
    """An FMU unzipped with its model description and value references by name."""

    def __init__(self, fmu: Path, directory: Path) -> None:
        self.fmu = fmu
        self.md = read_model_description(str(fmu))
        self.dir = Path(extract(str(fmu), str(directory)))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.size = {v.name: int(np.prod([int(d.start) for d in v.dimensions])) if getattr(v, "dimensions", None)
                     else 1 for v in self.md.modelVariables}
        self.identifier = (self.md.coSimulation or self.md.modelExchange).modelIdentifier

    def slave(self, name: str = "cs", **instantiate) -> FMU3Slave | FMU2Slave:
        cls = FMU3Slave if self.md.fmiVersion == "3.0" else FMU2Slave
        fmu = cls(guid=self.md.guid, unzipDirectory=str(self.dir), modelIdentifier=self.identifier,
                  instanceName=name)
        fmu.instantiate(**instantiate)
        return fmu

    def model(self, name: str = "me", **instantiate) -> FMU3Model | FMU2Model:
        cls = FMU3Model if self.md.fmiVersion == "3.0" else FMU2Model
        fmu = cls(guid=self.md.guid, unzipDirectory=str(self.dir), modelIdentifier=self.identifier,
                  instanceName=name)
        fmu.instantiate(**instantiate)
        return fmu

    def host(self, exe: Path, mode: str, stop: float, step: float, *variables: str, **env) -> list[list[str]]:
        run = subprocess.run([str(exe), str(self.dir), self.identifier, self.md.guid, mode, str(stop), str(step),
                              *variables], capture_output=True, text=True, timeout=600,
                             env={"PATH": "/usr/bin:/bin", **env})
        assert run.returncode == 0, run.stderr
        return [line.split(",") for line in run.stdout.split()]


@pytest.fixture(scope="module")
def opened(tmp_path_factory):
    cache: dict = {}

    def open_(source: Path, version: int) -> Opened:
        key = (source, version)
        if key not in cache:
            cache[key] = Opened(_build(source, version), tmp_path_factory.mktemp(f"{source.stem}{version}"))
        return cache[key]

    return open_


def _collecting_logger(messages: list):
    def log(env, status, category, message):
        messages.append((status, message.decode()))
    return log


# --------------------------------------------------------------------------------------------------

def test_the_fmi3_binary_exports_exactly_the_fmi3_functions(opened):
    header = (NATIVE / "fmi3Functions.h").read_text().split()
    declared = sorted(word.rstrip(";") for before, word in zip(header, header[2:]) if before == "FMI3_Export"
                      and word.startswith("fmi3"))
    assert len(declared) == 75 and exported_symbols(fmu_binary(3)) == declared
    assert all(name.startswith("fmi2") for name in exported_symbols(fmu_binary(2)))
    ball = opened(FMU_SRC / "bouncing_ball_restitution.py", 3)
    packed = ball.dir / "binaries" / "x86_64-linux" / f"{ball.identifier}.so"
    assert packed.read_bytes() == fmu_binary(3).read_bytes()


def test_array_variables_read_and_write_the_fmi2_builds_scalars(opened):
    """DeltaRobot: q (9), u (3), z (3) as one variable each; the same steps give the same values
    bit for bit as the FMI 2.0 build's q[1]..q[9], and element k of q lives at vr(q) + k - 1."""
    robot3, robot2 = opened(FMU_SRC / "delta_robot.py", 3), opened(FMU_SRC / "delta_robot.py", 2)
    assert [robot2.vr[f"q[{k}]"] for k in range(1, 10)] == [robot3.vr["q"] + k for k in range(9)]
    assert robot3.size["q"] == 9 and robot3.size["u"] == 3
    three, two = robot3.slave(), robot2.slave()
    three.enterInitializationMode(startTime=0.0)
    two.setupExperiment(startTime=0.0)
    two.enterInitializationMode()
    for fmu in (three, two):
        fmu.exitInitializationMode()
    torques = [1.5, -0.5, 0.25]
    three.setFloat64([robot3.vr["u"]], torques)
    two.setReal([robot2.vr[f"u[{k}]"] for k in (1, 2, 3)], torques)
    t, h = 0.0, 2e-3
    for _ in range(5):
        three.doStep(t, h)
        two.doStep(t, h)
        t += h
    names = ["q", "z", "energy"]
    got3 = three.getFloat64([robot3.vr[n] for n in names], nValues=13)
    got2 = two.getReal([robot2.vr[f"q[{k}]"] for k in range(1, 10)] + [robot2.vr[f"z[{k}]"] for k in (1, 2, 3)]
                       + [robot2.vr["energy"]])
    assert got3 == got2
    assert max(abs(x) for x in got3[:9]) > 0.0  # the torques moved the arms
    assert three.getFloat64([robot3.vr["time"]]) == [pytest.approx(t, abs=1e-15)]
    assert three.getFloat64([robot3.vr["u"]], nValues=3) == torques
    for fmu in (three, two):
        fmu.terminate()
        fmu.freeInstance()


def test_event_indicator_variables_are_the_event_indicators(opened):
    ball = opened(FMU_SRC / "bouncing_ball_restitution.py", 3)
    me = ball.model()
    me.enterInitializationMode(startTime=0.0)
    me.exitInitializationMode()
    while me.updateDiscreteStates()[0]:
        pass
    me.enterContinuousTimeMode()
    nz = me.getNumberOfEventIndicators()
    x = (ctypes.c_double * 2)(-0.25, -3.0)  # below the floor, falling
    me.setTime(0.3)
    me.setContinuousStates(x, 2)
    z = (ctypes.c_double * nz)()
    me.getEventIndicators(z, nz)
    indicators = [v.variable.valueReference for v in ball.md.eventIndicators]
    assert nz == 2 and me.getFloat64(indicators) == list(z) and z[0] < 0.0
    me.terminate()
    me.freeInstance()


@pytest.mark.parametrize("call, expected", [
    ("get_before_initialization", "fmi3GetFloat64 must not be called in state 'instantiated'"),
    ("step_mode_on_model_exchange", "fmi3EnterStepMode: not a function of Co-Simulation"),
    ("event_mode_unused", "fmi3EnterEventMode: the instance was made with eventModeUsed = false"),
    ("int8_getter", "fmi3GetInt8: 0 is not the value reference of an Int8 variable (it names a Float64"),
    ("set_time", "is `time`, the independent variable: set it with fmi3SetTime"),
    ("wrong_n_values", "fmi3GetFloat64: nValues is 2, the variables have 1 values"),
    ("set_output", "cannot be set in state 'step mode'"),
    ("configuration", "fmi3EnterConfigurationMode: this FMU has no structural parameters"),
    ("do_step_twice_the_time", "fmi3DoStep: currentCommunicationPoint 5 differs from the FMU time 0.1"),
])
def test_state_machine_and_argument_errors_return_fmi3Error_and_say_why(opened, call, expected):
    osc = opened(FMU_SRC / "oscillator.py", 3)
    messages: list = []
    logger = _collecting_logger(messages)
    me = call == "step_mode_on_model_exchange"
    fmu = osc.model(logMessage=logger) if me else osc.slave(logMessage=logger)
    output = next(v.valueReference for v in osc.md.modelVariables if v.causality == "output")
    with pytest.raises(Exception, match="status 3|error"):
        if call == "get_before_initialization":
            fmu.getFloat64([0])
        if call == "configuration":
            fmu.enterConfigurationMode()
        fmu.enterInitializationMode(startTime=0.0)
        fmu.exitInitializationMode()
        if me:  # fmpy has no Co-Simulation calls on a Model Exchange instance: the binary's own
            status = fmu.dll.fmi3EnterStepMode(ctypes.c_void_p(fmu.component))
            raise RuntimeError(f"status {status}")
        if call == "event_mode_unused":
            fmu.enterEventMode()
        elif call == "int8_getter":
            fmu.getInt8([0])
        elif call == "set_time":
            fmu.setFloat64([osc.vr["time"]], [1.0])
        elif call == "wrong_n_values":
            fmu.getFloat64([0], nValues=2)
        elif call == "set_output":
            fmu.setFloat64([output], [1.0])
        elif call == "do_step_twice_the_time":
            fmu.doStep(0.0, 0.1)
            fmu.doStep(5.0, 0.1)
    assert any(status == 3 and expected in text for status, text in messages), messages
    fmu.freeInstance()


def test_scheduled_execution_is_refused_by_name(opened):
    osc = opened(FMU_SRC / "oscillator.py", 3)
    lib = ctypes.CDLL(str(osc.dir / "binaries" / "x86_64-linux" / f"{osc.identifier}.so"))
    messages: list = []
    logger = fmi3LogMessageCallback(_collecting_logger(messages))
    lib.fmi3InstantiateScheduledExecution.restype = ctypes.c_void_p
    instance = lib.fmi3InstantiateScheduledExecution(b"se", osc.md.guid.encode(), None, False, False, None, logger,
                                                     None, None, None)
    assert instance is None and "not Scheduled Execution" in messages[0][1]


def _run(fmu, vrs, t0, h, n) -> np.ndarray:
    rows, t = [], t0
    for _ in range(n):
        fmu.doStep(t, h)
        t += h
        rows.append(fmu.getFloat64(vrs))
    return np.array(rows)


def test_fmu_state_round_trip_continues_bit_for_bit(opened):
    """The ball with impacts (events inside the steps): from a restored state, serialized and read
    back, the run repeats bit for bit."""
    ball = opened(FMU_SRC / "bouncing_ball_restitution.py", 3)
    fmu = ball.slave()
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    vrs = [ball.vr["q"], ball.vr["v"], ball.vr["energy"]]
    _run(fmu, vrs, 0.0, 0.05, 8)
    state = fmu.getFMUState()
    data = fmu.serializeFMUState(state)
    first = _run(fmu, vrs, 0.4, 0.05, 16)
    restored = fmu.deserializeFMUState(data)
    fmu.setFMUState(restored)
    again = _run(fmu, vrs, 0.4, 0.05, 16)
    fmu.setFMUState(state)
    once_more = _run(fmu, vrs, 0.4, 0.05, 16)
    assert np.array_equal(first, again) and np.array_equal(first, once_more)
    assert np.min(first[:, 0]) < 0.01 and first[-1, 1] != first[0, 1]  # an impact happened in between
    fmu.freeFMUState(state)
    fmu.freeFMUState(restored)
    fmu.freeInstance()


def test_directional_derivatives_equal_the_fmi2_builds_and_the_adjoint_is_their_transpose(opened):
    """DeltaRobot in continuous-time mode: unknowns der(q), der(v) (18 values), knowns q, v, u
    (21): the array call equals the FMI 2.0 build's scalar call; the adjoint w -> J^T w equals the
    transpose product of the Jacobian built column by column from directional derivatives."""
    robot3, robot2 = opened(FMU_SRC / "delta_robot.py", 3), opened(FMU_SRC / "delta_robot.py", 2)
    three, two = robot3.model(), robot2.model()
    three.enterInitializationMode(startTime=0.0)
    two.setupExperiment(startTime=0.0)
    two.enterInitializationMode()
    three.exitInitializationMode()
    two.exitInitializationMode()
    while three.updateDiscreteStates()[0]:
        pass
    while two.newDiscreteStates()[0]:
        pass
    three.enterContinuousTimeMode()
    two.enterContinuousTimeMode()
    torques = [2.0, -1.0, 0.5]
    three.setFloat64([robot3.vr["u"]], torques)
    two.setReal([robot2.vr[f"u[{k}]"] for k in (1, 2, 3)], torques)
    unknowns, knowns = ["der(q)", "der(v)"], ["q", "v", "u"]

    def scalars(names: list[str]) -> list[int]:  # FMI 2.0 names: q[1], der(q[1])
        return [robot2.vr[f"der({n[4:-1]}[{k}])" if n.startswith("der(") else f"{n}[{k}]"]
                for n in names for k in range(1, robot3.size[n] + 1)]

    rng = np.random.default_rng(29)
    seed = rng.normal(size=21)
    d3 = np.array(three.getDirectionalDerivative([robot3.vr[n] for n in unknowns], [robot3.vr[n] for n in knowns],
                                                 list(seed), nSensitivity=18))
    d2 = np.array(two.getDirectionalDerivative(scalars(unknowns), scalars(knowns), list(seed)))
    assert d3.shape == (18,) and np.max(np.abs(d3)) > 0.0
    assert np.allclose(d3, d2, rtol=1e-12, atol=1e-12 * np.max(np.abs(d2)))
    jacobian = np.column_stack([three.getDirectionalDerivative([robot3.vr[n] for n in unknowns],
                                                               [robot3.vr[n] for n in knowns], list(e), 18)
                                for e in np.eye(21)])
    w = rng.normal(size=18)
    adjoint = np.array(three.getAdjointDerivative([robot3.vr[n] for n in unknowns], [robot3.vr[n] for n in knowns],
                                                  list(w), nSensitivity=21))
    expected = jacobian.T @ w
    assert adjoint.shape == (21,)
    assert np.allclose(adjoint, expected, rtol=1e-12, atol=1e-12 * np.max(np.abs(expected)))
    for fmu in (three, two):
        fmu.terminate()
        fmu.freeInstance()


def _events(rows: list[list[str]]) -> list[float]:
    return [float(row[1]) for row in rows if row[0] == "event"]


def test_cs_event_mode_stops_at_the_impacts_at_their_closed_form_times(opened, host3):
    """BouncingBallRestitution dropped from 1 m, in the C host with eventModeUsed and early return:
    each impact is a triple of events (contact, collision law, release). The first impact is at
    sqrt(2 h0 / g); after each release the ball flies 2 e^k v1 / g (v1 = sqrt(2 g h0)) before
    the next, up to what gravity takes from the rebound during each ~1e-4 s collision (about
    g * duration / v, below 1e-3 relative for these impacts)."""
    ball = opened(FMU_SRC / "bouncing_ball_restitution.py", 3)
    rows = ball.host(host3, "cs-events", 2.5, 0.1, str(ball.vr["q"]), str(ball.vr["v"]))
    events = _events(rows)
    g, e = 9.81, 0.8
    v1 = math.sqrt(2 * g)
    assert len(events) == 12
    impacts, releases = events[0::3], events[2::3]
    assert impacts[0] == pytest.approx(math.sqrt(2 / g), abs=1e-8)
    for k in range(1, 4):
        assert impacts[k] - releases[k - 1] == pytest.approx(2 * e ** k * v1 / g, rel=1e-3)
    grid = [row for row in rows if row[0] != "event"]
    assert [float(row[0]) for row in grid] == pytest.approx([0.1 * k for k in range(26)], abs=1e-12)
    # without event mode the same FMU handles the impacts inside its steps: the same trajectory
    plain = [row for row in ball.host(host3, "cs", 2.5, 0.1, str(ball.vr["q"]), str(ball.vr["v"]))]
    assert not _events(plain)
    assert np.allclose(np.array(plain, dtype=float), np.array(grid, dtype=float), atol=1e-6)


def test_model_exchange_in_the_c_host_equals_the_fmi2_binary(opened, host3, host2):
    """The same explicit Euler with event handling in host.c (FMI 2.0) and host3.c (FMI 3.0): the
    ball's rows are equal to the last bit."""
    ball3 = opened(FMU_SRC / "bouncing_ball_restitution.py", 3)
    ball2 = opened(FMU_SRC / "bouncing_ball_restitution.py", 2)
    rows3 = [row for row in ball3.host(host3, "me", 1.5, 1e-3, "0", "1") if row[0] != "event"]
    rows2 = ball2.host(host2, "me", 1.5, 1e-3, "0", "1", HOST_NX="2", HOST_NZ="2")
    assert len(rows3) == 1501 and rows3 == rows2


def test_a_null_resource_path_finds_the_resources_from_the_binary(opened, host3):
    osc = opened(FMU_SRC / "oscillator.py", 3)
    given = osc.host(host3, "cs", 1.0, 0.1, "0", "1")
    found = osc.host(host3, "cs", 1.0, 0.1, "0", "1", HOST_NULL_RESOURCES="1")
    assert given == found and len(given) == 11


@pytest.fixture(scope="module")
def chatty(tmp_path_factory) -> Opened:
    from deltafmi.builder import build_fmu
    out = tmp_path_factory.mktemp("chatty")
    return Opened(build_fmu(COMPONENTS / "chatty" / "model.py", out / "Chatty.fmu", fmi_version=3), out / "x")


def test_a_component_that_ends_the_simulation_returns_ok_with_terminate_simulation(chatty, host3):
    """Chatty ends the run at its time event t_end = 0.55 s: fmi3DoStep returns fmi3OK with
    terminateSimulation and lastSuccessfulTime 0.55, y = exp(-0.55); in event mode the step stops
    at 0.55 and fmi3UpdateDiscreteStates says terminateSimulation."""
    fmu = chatty.slave()
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    results = [fmu.doStep(0.1 * k, 0.1) for k in range(6)]
    assert [r[1] for r in results] == [False] * 5 + [True]
    event, terminate, early, reached = results[-1]
    assert not event and not early and reached == pytest.approx(0.55, abs=1e-12)
    assert fmu.getFloat64([chatty.vr["y"]])[0] == pytest.approx(math.exp(-0.55), rel=1e-6)
    fmu.terminate()
    fmu.freeInstance()
    rows = chatty.host(host3, "cs", 1.0, 0.1, str(chatty.vr["y"]))
    assert rows[-1] == ["terminated", "0.55000000000000004"] and float(rows[-2][0]) == pytest.approx(0.55)
    rows = chatty.host(host3, "cs-events", 1.0, 0.1, str(chatty.vr["y"]))
    assert _events(rows) == [pytest.approx(0.55, abs=1e-12)] and rows[-1][0] == "terminated"


def test_a_component_that_steps_itself_ends_the_simulation_in_its_step(tmp_path):
    """Stopper (its own do_step) ends the run in its third step: fmi3OK, terminateSimulation."""
    from deltafmi.builder import build_fmu
    stopper = Opened(build_fmu(COMPONENTS / "stopper" / "model.py", tmp_path / "Stopper.fmu", fmi_version=3),
                     tmp_path / "x")
    fmu = stopper.slave()
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    results = [fmu.doStep(0.1 * k, 0.1) for k in range(3)]
    assert [r[1] for r in results] == [False, False, True] and results[-1][3] == pytest.approx(0.3, abs=1e-12)
    assert fmu.getInt32([stopper.vr["n"]]) == [3]
    fmu.terminate()
    fmu.freeInstance()


def test_the_portable_fmi3_fmu_runs_where_no_python_exists(no_python, opened, host3, tmp_path):
    """``--portable`` for FMI 3.0: the Oscillator in host3 where no Python can be found equals the
    plain FMI 3.0 FMU in host3 here, in Co-Simulation and Model Exchange."""
    from deltafmi.builder.packager import build_cached
    portable = unzip(build_cached(FMU_SRC / "oscillator.py", portable=True, fmi_version=3), tmp_path / "portable")
    plain = opened(FMU_SRC / "oscillator.py", 3)
    for mode, step in (("cs", 1e-2), ("me", 1e-3)):
        args = [str(portable), plain.identifier, plain.md.guid, mode, "2.0", str(step), "0", "1"]
        hidden = subprocess.run([*no_python, str(host3), *args], capture_output=True, text=True, timeout=300,
                                env={"PATH": "/usr/bin:/bin"})
        assert hidden.returncode == 0, hidden.stderr[-3000:]
        rows = [line.split(",") for line in hidden.stdout.split()]
        here = plain.host(host3, mode, 2.0, step, "0", "1")
        assert len(rows) > 200 and np.allclose(np.array([r for r in rows if r[0] != "event"], dtype=float),
                                               np.array([r for r in here if r[0] != "event"], dtype=float),
                                               rtol=0, atol=1e-9)


def test_enumerations_are_got_and_set_as_int64_only(opened):
    """Gearbox's gear (an Enumeration parameter) and engaged (an Enumeration output) through
    fmi3Get/SetInt64, as FMI 3.0 defines Enumerations: gear REVERSE (3) makes y = -1 * u and engaged
    3. fmi3GetInt32 refuses them, naming what they are; fmi3SetInt64 refuses a value beyond the
    stored int32, names it, and changes nothing."""
    box = opened(COMPONENTS / "gearbox" / "model.py", 3)
    assert {v.name: v.type for v in box.md.modelVariables}["gear"] == "Enumeration"
    messages: list = []
    fmu = box.slave(logMessage=_collecting_logger(messages))
    gear, engaged, u, y = (box.vr[n] for n in ("gear", "engaged", "u", "y"))
    fmu.setInt64([gear], [3])
    with pytest.raises(Exception, match="status 3"):
        fmu.setInt64([gear], [2 ** 40])
    assert messages[-1] == (3, f"fmi3SetInt64: 1099511627776 (value 0, the Enumeration at value reference {gear}) "
                               "is out of this FMU's range of Enumeration values [-2147483648, 2147483647]")
    assert fmu.getInt64([gear]) == [3]  # the error state still reads: the value is the one set before
    fmu.freeInstance()
    fmu = box.slave(logMessage=_collecting_logger(messages))
    fmu.setInt64([gear], [3])
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    fmu.setFloat64([u], [2.5])
    fmu.doStep(0.0, 0.1)
    assert fmu.getInt64([gear, engaged]) == [3, 3] and fmu.getFloat64([y]) == [-2.5]
    with pytest.raises(Exception, match="status 3"):
        fmu.getInt32([engaged])
    assert messages[-1] == (3, f"fmi3GetInt32: {engaged} is not the value reference of an Int32 variable (it names "
                               "an Enumeration (Int64) variable)")
    fmu.freeInstance()
