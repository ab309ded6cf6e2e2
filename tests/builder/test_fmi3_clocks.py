"""The sampled controller as an FMI 3.0 Clock (issue 29 item 3, export side).

DeltaController declares ``sample = Clock(period="sample_period")``: its FMI 3.0 build has a
periodic time-based input Clock (``fixed``: the interval comes from fmi3GetIntervalDecimal) and
provides Scheduled Execution. Verified here through real importers: fmpy (which ignores clocks in
simulate_fmu) gets the FMI 2.0 results; a clock-driving importer written with fmpy's FMU3Model /
FMU3Slave (fmi3SetClock in Event Mode at every tick) samples once per tick and gets the same
torques as the Co-Simulation build; a plain-C Scheduled Execution host (tests/c_host/host3.c, mode se)
activates the model partition at every tick with recorded plant inputs and gets those torques too.
"""
from __future__ import annotations

import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import (FMU3Model, FMU3ScheduledExecution, FMU3Slave, fmi3Float64, fmi3IntervalChanged,
                       fmi3IntervalQualifier, fmi3IntervalUnchanged, fmi3ValueReference)
from fmpy.validation import validate_fmu

from conftest import ROOT, clean_env
from deltafmi import simulate
from deltafmi.component import Clock, Component, Input, Output, Parameter
from deltafmi.runtime.model_description import model_description_xml
from deltafmi.runtime.model_description3 import model_description3_xml
from deltafmi.builder import build_cached
from test_fmi3_binary import host3  # noqa: F401 - the fixture: tests/c_host/host3.c compiled
from test_portable_fmus import no_python  # noqa: F401 - the fixture: a command prefix where no Python exists

INPUTS = ("y", "yd", "r", "rd", "rdd")  # the controller's inputs the flagship drives
TICKS = 300  # 0.3 s of the flagship at the controller's 1 kHz


@pytest.fixture(scope="module")
def fmu3() -> Path:
    return build_cached("DeltaController", fmi_version=3)


@pytest.fixture(scope="module")
def fmu2() -> Path:
    return build_cached("DeltaController")


@pytest.fixture(scope="module")
def unzipped(fmu3, tmp_path_factory) -> Path:
    return Path(fmpy.extract(str(fmu3), unzipdir=str(tmp_path_factory.mktemp("dc3"))))


@pytest.fixture(scope="module")
def md(fmu3):
    return fmpy.read_model_description(str(fmu3))


@pytest.fixture(scope="module")
def vr(md) -> dict:
    return {v.name: v.valueReference for v in md.modelVariables}


@pytest.fixture(scope="module")
def recorded() -> np.ndarray:
    """The controller's inputs y, yd, r, rd, rdd at each tick of the FMI 2.0 flagship: (TICKS, 15)."""
    names = [f"controller.{name}[{i}]" for name in INPUTS for i in (1, 2, 3)]
    result = simulate("delta_tracking", stop=(TICKS - 1) * 1e-3, record=[f"controller.{n}[*]" for n in INPUTS])
    rows = np.column_stack([np.asarray(result[n]) for n in names])
    assert rows.shape == (TICKS, 15) and np.ptp(rows[:, 0]) > 1e-3  # the plant moves
    return rows


def _instance(cls, md, unzipped):
    return cls(guid=md.guid, unzipDirectory=str(unzipped), modelIdentifier="DeltaController", instanceName="c")


def _interval(fmu, clock: int) -> tuple:
    vrs, intervals, qualifiers = (fmi3ValueReference * 1)(clock), (fmi3Float64 * 1)(), (fmi3IntervalQualifier * 1)()
    fmu.fmi3GetIntervalDecimal(fmu.component, vrs, 1, intervals, qualifiers)
    return intervals[0], qualifiers[0]


def _set_inputs(fmu, vr, row) -> None:
    fmu.setFloat64([vr[n] for n in INPUTS], list(row))


def _co_simulation_torques(md, unzipped, vr, recorded, period=1e-3) -> np.ndarray:
    """The reference: the CS build without event mode, one doStep per sample period; the torque
    after the step from t_k is the sample taken at t_k with the inputs of tick k (held)."""
    fmu = _instance(FMU3Slave, md, unzipped)
    fmu.instantiate()
    if period != 1e-3:
        fmu.setFloat64([vr["sample_period"]], [period])
    fmu.enterInitializationMode(startTime=0.0)
    _set_inputs(fmu, vr, recorded[0])  # the sample at t = 0 is taken as initialization ends
    fmu.exitInitializationMode()
    torques = []
    for k, row in enumerate(recorded):
        _set_inputs(fmu, vr, row)
        fmu.doStep(k * period, period)
        torques.append(fmu.getFloat64([vr["u"]], 3))
    fmu.terminate()
    fmu.freeInstance()
    return np.array(torques)


def test_the_sample_period_is_a_fixed_periodic_input_clock(fmu2, fmu3, md):
    assert validate_fmu(str(fmu3)) == []
    with zipfile.ZipFile(fmu3) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
        readme = archive.read("resources/README.txt").decode()
    assert "FMI 3.0 FMU (Model Exchange, Co-Simulation and Scheduled Execution)" in readme
    clocks = root.findall("ModelVariables/Clock")
    assert [c.attrib["name"] for c in clocks] == ["sample"]
    clock = clocks[0].attrib
    time_vr = int(root.find("ModelVariables/Float64[@name='time']").attrib["valueReference"])
    assert int(clock["valueReference"]) == time_vr + 1
    assert (clock["causality"], clock["variability"], clock["intervalVariability"]) == ("input", "discrete", "fixed")
    assert "intervalDecimal" not in clock and "shiftDecimal" not in clock  # the FMU gives the interval
    assert clock["priority"] == "0"  # mandatory in Scheduled Execution
    assert root.find("ScheduledExecution").attrib["modelIdentifier"] == "DeltaController"
    assert root.find("CoSimulation").attrib["hasEventMode"] == "true"  # where a CS importer sets a clock
    assert md.scheduledExecution is not None
    # the outputs stay unclocked: an importer that ignores the clock may read them at any time
    assert not any(v.clocks for v in md.modelVariables)
    with zipfile.ZipFile(fmu2) as archive:
        assert b"Clock" not in archive.read("modelDescription.xml")


def test_the_tactile_sensor_reads_on_a_clock_without_scheduled_execution():
    """The sensor's readings are sampled too, but it has continuous states (its lag): a Clock for
    Model Exchange and Co-Simulation importers, no Scheduled Execution."""
    fmu = build_cached("TactileSensor", fmi_version=3)
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    clocks = [v for v in md.modelVariables if v.type == "Clock"]
    assert [(c.name, c.causality, c.intervalVariability) for c in clocks] == [("sample", "input", "fixed")]
    assert md.scheduledExecution is None and md.coSimulation.hasEventMode
    assert clocks[0].priority is None  # a Scheduled Execution attribute

def test_a_numeric_period_is_a_constant_clock_and_fmi2_ignores_clocks():
    class Sampled(Component):
        """Samples x every 5 ms."""
        model_name = "Sampled"
        x = Input(0.0)
        held = Output(0.0, variability="discrete")
        tick = Clock(period=5e-3)

    xml = ET.fromstring(model_description3_xml(Sampled, "{token}"))
    clock = xml.find("ModelVariables/Clock").attrib
    assert (clock["intervalVariability"], float(clock["intervalDecimal"])) == ("constant", 5e-3)
    assert b"Clock" not in model_description_xml(Sampled, "{guid}")


@pytest.mark.parametrize("period, message", [
    ("gain", "is not a Parameter"), ("n", "must be a real scalar Parameter"),
    ("tuned", "must be a fixed (not tunable) Parameter"), ("ms", "a Clock interval is in s")])
def test_a_clock_period_must_be_a_fixed_parameter_in_seconds(period, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        type("Bad", (Component,), {"gain": Input(1.0), "n": Parameter(3, type=int),
                                   "tuned": Parameter(1.0, tunable=True), "ms": Parameter(1.0, unit="ms"),
                                   "tick": Clock(period=period)})
    with pytest.raises(ValueError, match="must be > 0"):
        Clock(period=0.0)


def test_two_clocks_of_one_name_are_refused():
    twins = type("Twins", (Component,), {"a": Clock(period=1e-3, name="tick"), "b": Clock(period=2e-3, name="tick")})
    with pytest.raises(ValueError, match="the Clock 'tick' has the name of another variable"):
        model_description3_xml(twins, "{token}")


@pytest.mark.parametrize("before_initialization", [False, True])
def test_the_interval_is_the_sample_period_changed_once_in_initialization(md, unzipped, vr, before_initialization):
    clock = vr["sample"]
    fmu = _instance(FMU3Slave, md, unzipped)
    fmu.instantiate(eventModeUsed=True, earlyReturnAllowed=True)
    if before_initialization:
        fmu.setFloat64([vr["sample_period"]], [2e-3])
    fmu.enterInitializationMode(startTime=0.0)
    period = 2e-3 if before_initialization else 1e-3
    assert _interval(fmu, clock) == (period, fmi3IntervalChanged)
    assert _interval(fmu, clock) == (period, fmi3IntervalUnchanged)  # reported already
    if not before_initialization:  # the parameter set in Initialization Mode: a new interval
        fmu.setFloat64([vr["sample_period"]], [2e-3])
        assert _interval(fmu, clock) == (2e-3, fmi3IntervalChanged)
    shifts = (fmi3Float64 * 1)(1.0)
    fmu.fmi3GetShiftDecimal(fmu.component, (fmi3ValueReference * 1)(clock), 1, shifts)
    assert shifts[0] == 0.0
    fmu.exitInitializationMode()  # Event Mode: the interval of a fixed clock is final
    assert _interval(fmu, clock) == (2e-3, fmi3IntervalUnchanged)
    with pytest.raises(FMICallException):  # the FMU gives this fixed clock's interval
        fmu.setIntervalDecimal((fmi3ValueReference * 1)(clock), (fmi3Float64 * 1)(5e-3))
    fmu.freeInstance()


@pytest.mark.parametrize("call, message", [
    (lambda fmu, clock: fmu.getClock([clock]), "is an input Clock, activated by the importer (fmi3SetClock); "
     "fmi3GetClock is for output and local Clocks"),
    (lambda fmu, clock: fmu.setClock([clock], [False]), "is active and cannot be deactivated (canBeDeactivated = false)")])
def test_an_active_input_clock_is_the_importers_to_know_and_stays_active(md, unzipped, vr, call, message):
    messages = []
    model = _instance(FMU3Model, md, unzipped)
    model.instantiate(logMessage=lambda env, status, category, text: messages.append(text.decode()))
    model.enterInitializationMode(startTime=0.0)
    model.exitInitializationMode()
    model.setClock([vr["sample"]], [True])
    with pytest.raises(FMICallException):
        call(model, vr["sample"])
    assert f"Clock {vr['sample']} {message}" in messages[-1]
    model.freeInstance()


def test_set_clock_outside_event_mode_is_refused(md, unzipped, vr):
    messages = []
    model = _instance(FMU3Model, md, unzipped)
    model.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
    model.enterInitializationMode(startTime=0.0)
    model.exitInitializationMode()
    model.setClock([vr["sample"]], [True])  # Event Mode: allowed
    model.setClock([vr["sample"]], [True])  # again: still active
    model.updateDiscreteStates()  # the sample at t = 0; the clock is inactive again
    model.setClock([vr["sample"]], [False])  # inactive: nothing to undo
    model.enterContinuousTimeMode()
    model.setTime(5e-4)
    model.enterEventMode()  # an event between the ticks: activating the clock here is a mistake
    model.setClock([vr["sample"]], [True])
    assert "activated at t = 0.00050000000000000001, between its ticks (every 0.001 s from 0)" in messages[-1]
    model.enterContinuousTimeMode()
    with pytest.raises(FMICallException):
        model.setClock([vr["sample"]], [True])
    assert "fmi3SetClock must not be called in state 'continuous-time mode'" in messages[-1]
    model.freeInstance()
    slave = _instance(FMU3Slave, md, unzipped)  # Co-Simulation without event mode: Step Mode only
    slave.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
    slave.enterInitializationMode(startTime=0.0)
    slave.exitInitializationMode()
    with pytest.raises(FMICallException):
        slave.setClock([vr["sample"]], [True])
    assert "fmi3SetClock must not be called in state 'step mode'" in messages[-1]
    slave.freeInstance()


@pytest.mark.parametrize("interface", ["ME", "CS", "CS without early return"])
def test_an_importer_that_activates_the_clock_samples_once_per_tick(md, unzipped, vr, recorded, interface):
    """ME, and CS with event mode: at each tick t_k (in ME a time event as well; in CS the step
    reports no event there, the tick is the importer's) the importer enters Event Mode, sets the
    inputs, activates the clock and updates the discrete states. One sample per tick:
    the torques are the CS build's exactly (a second sample at an instant would advance the
    controller's integral and its sample counter, and every later torque would differ). Without
    early return too: the ticks are events at the communication points, the importer's."""
    clock = vr["sample"]
    fmu = _instance(FMU3Model if interface == "ME" else FMU3Slave, md, unzipped)
    if interface == "ME":
        fmu.instantiate()
    else:
        fmu.instantiate(eventModeUsed=True, earlyReturnAllowed=interface == "CS")
    fmu.enterInitializationMode(startTime=0.0)
    period, _ = _interval(fmu, clock)
    fmu.exitInitializationMode()  # Event Mode at t = 0, the first tick
    torques, next_events = [], []
    for k, row in enumerate(recorded):
        t = k * period
        _set_inputs(fmu, vr, row)
        fmu.setClock([clock], [True])
        while True:
            update, terminate, _, _, defined, next_time = fmu.updateDiscreteStates()
            if not update:
                break
        assert defined and abs(next_time - (t + period)) < 1e-12
        next_events.append(next_time)
        torques.append(fmu.getFloat64([vr["u"]], 3))
        if interface == "ME":
            fmu.enterContinuousTimeMode()
            fmu.setTime(next_time)  # no continuous states: nothing to integrate
            fmu.enterEventMode()
        else:
            fmu.enterStepMode()
            event, terminate, early, last = fmu.doStep(t, period)
            # in event mode the ticks are the importer's to activate: the step reports none
            assert not event and not early and not terminate and last == pytest.approx(t + period, abs=1e-15)
            fmu.enterEventMode()
    fmu.freeInstance()
    reference = _co_simulation_torques(md, unzipped, vr, recorded)
    assert np.ptp(reference[:, 0]) > 1.0  # the torques move
    assert np.max(np.abs(np.array(torques) - reference)) == 0.0


@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_fmpy_ignoring_the_clock_gets_the_fmi2_results(fmu2, fmu3, recorded, fmi_type):
    signals = np.zeros(TICKS, dtype=[("time", float)] + [(f"{n}[{i}]", float) for n in INPUTS for i in (1, 2, 3)])
    signals["time"] = np.arange(TICKS) * 1e-3
    for j, name in enumerate(signals.dtype.names[1:]):
        signals[name] = recorded[:, j]
    inputs3 = np.zeros(TICKS, dtype=[("time", float)] + [(n, float, (3,)) for n in INPUTS])
    inputs3["time"] = signals["time"]
    for j, name in enumerate(INPUTS):
        inputs3[name] = recorded[:, 3 * j:3 * j + 3]
    options = dict(fmi_type=fmi_type, stop_time=0.25, output_interval=1e-3)
    r2 = fmpy.simulate_fmu(str(fmu2), input=signals, **options)
    r3 = fmpy.simulate_fmu(str(fmu3), input=inputs3, **options)
    u2 = np.column_stack([r2[f"u[{i}]"] for i in (1, 2, 3)])
    assert len(r2) == len(r3) and np.ptp(u2[:, 0]) > 1.0
    assert np.max(np.abs(r3["u"] - u2)) == 0.0


def _scheduled(host3, unzipped, md, vr, recorded, tmp_path, env=None, prefix=()) -> tuple:
    """host3's Scheduled Execution mode: (interval line, shift line, rows t_k,u, clock_updates line)."""
    table = tmp_path / "inputs.txt"
    np.savetxt(table, recorded, fmt="%.17g")
    args = [*prefix, str(host3), str(unzipped), "DeltaController", md.guid, "se", str(vr["sample"]), str(len(recorded)),
            str(table), *[f"{vr[n]}:3" for n in INPUTS], "--", f"{vr['u']}:3"]
    done = subprocess.run(args, capture_output=True, text=True, env=env or clean_env(), timeout=300)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.split()
    rows = np.array([[float(x) for x in line.split(",")] for line in lines[2:-1]])
    return lines[0], lines[1], rows, lines[-1]


def test_scheduled_execution_in_a_c_host_gives_the_co_simulation_torques(host3, unzipped, md, vr, recorded,
                                                                        tmp_path):
    """Scheduled Execution in plain C: the interval asked in Initialization Mode (Changed), the
    partition activated at every tick t_k = k * interval with the recorded plant inputs of tick k:
    the very torques of the Co-Simulation build, to the bit."""
    interval, shift, rows, updates = _scheduled(host3, unzipped, md, vr, recorded, tmp_path)
    assert interval == f"interval,0.001,{fmi3IntervalChanged}" and shift == "shift,0" and updates == "clock_updates,0"
    assert np.array_equal(rows[:, 0], np.arange(TICKS) * 1e-3)
    reference = _co_simulation_torques(md, unzipped, vr, recorded)
    assert np.max(np.abs(rows[:, 1:] - reference)) == 0.0


def test_scheduled_execution_follows_the_sample_period_parameter(host3, unzipped, md, vr, recorded, tmp_path):
    env = clean_env(HOST_PARAM=f"{vr['sample_period']}=0.002")
    interval, _, rows, _ = _scheduled(host3, unzipped, md, vr, recorded[:100], tmp_path, env)
    assert interval == f"interval,0.002,{fmi3IntervalChanged}" and rows[-1, 0] == 99 * 2e-3
    reference = _co_simulation_torques(md, unzipped, vr, recorded[:100], period=2e-3)
    assert np.max(np.abs(rows[:, 1:] - reference)) == 0.0


def test_scheduled_execution_state_machine(md, unzipped, vr):
    """fmpy's FMU3ScheduledExecution (fmpy cannot simulate SE, but it instantiates and calls):
    partitions only in Clock Activation Mode, at strictly increasing times, for Clocks only;
    fmi3SetClock and fmi3DoStep are not Scheduled Execution's."""
    messages = []
    fmu = _instance(FMU3ScheduledExecution, md, unzipped)
    fmu.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
    with pytest.raises(FMICallException):
        fmu.activateModelPartition(vr["sample"], 0.0)
    assert "must not be called in state 'instantiated'" in messages[-1]
    fmu.reset()
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    fmu.activateModelPartition(vr["sample"], 0.0)
    first = fmu.getFloat64([vr["u"]], 3)
    fmu.activateModelPartition(vr["sample"], 1e-3)
    assert fmu.getFloat64([vr["u"]], 3) != first  # the integral moved on
    saved = fmu.getFMUState()  # no partition is active: allowed
    fmu.activateModelPartition(vr["sample"], 2e-3)
    later = fmu.getFloat64([vr["u"]], 3)
    fmu.setFMUState(saved)  # back to t = 1e-3: the tick at 2e-3 may come again, the same
    fmu.activateModelPartition(vr["sample"], 2e-3)
    assert fmu.getFloat64([vr["u"]], 3) == later
    fmu.freeFMUState(saved)
    for call, text in [(lambda: fmu.activateModelPartition(vr["sample"], 1e-3), "must increase strictly"),
                       (lambda: fmu.setClock([vr["sample"]], [True]), "with fmi3ActivateModelPartition"),
                       (lambda: fmu.activateModelPartition(vr["u"], 2e-3), "is not a Clock")]:
        fmu.reset()
        fmu.enterInitializationMode(startTime=0.0)
        fmu.exitInitializationMode()
        fmu.activateModelPartition(vr["sample"], 1e-3)
        with pytest.raises(FMICallException):
            call()
        assert text in messages[-1]
    fmu.freeInstance()


def test_fmus_without_clocks_refuse_the_clock_functions(tmp_path):
    oscillator = build_cached("Oscillator", fmi_version=3)
    md = fmpy.read_model_description(str(oscillator))
    fmu = FMU3Model(guid=md.guid, unzipDirectory=fmpy.extract(str(oscillator), unzipdir=str(tmp_path)),
                    modelIdentifier="Oscillator", instanceName="o")
    messages = []
    fmu.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    with pytest.raises(FMICallException):
        fmu.setClock([0], [True])
    assert "is not a Clock (this FMU has no Clocks)" in messages[-1]
    fmu.freeInstance()
    with pytest.raises(Exception, match="Failed to instantiate"):
        FMU3ScheduledExecution(guid=md.guid, unzipDirectory=str(tmp_path), modelIdentifier="Oscillator",
                               instanceName="o").instantiate()



def test_portable_scheduled_execution_runs_where_no_python_exists(no_python, host3, md, vr, recorded, unzipped,
                                                                 tmp_path):
    """``--portable``: the same Scheduled Execution in the C host where no Python can be found."""
    portable = build_cached("DeltaController", portable=True, fmi_version=3)
    directory = Path(fmpy.extract(str(portable), unzipdir=str(tmp_path / "portable")))
    interval, _, rows, _ = _scheduled(host3, directory, md, vr, recorded[:100], tmp_path, prefix=no_python)
    assert interval == f"interval,0.001,{fmi3IntervalChanged}"
    reference = _co_simulation_torques(md, unzipped, vr, recorded[:100])
    assert np.max(np.abs(rows[:, 1:] - reference)) == 0.0


def test_info_names_the_scheduled_execution_interface_and_the_clock(fmu3):
    from click.testing import CliRunner

    from deltafmi.apps.cli import main
    shown = CliRunner().invoke(main, ["info", str(fmu3)]).output
    assert "(FMI 3.0, Model Exchange, Co-Simulation, Scheduled Execution)" in shown
    assert "clocks: sample (input, fixed)" in shown


TICKER = ROOT / "tests" / "components" / "ticker" / "model.py"


@pytest.mark.parametrize("fmi_version", [2, 3])
@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_a_clock_changes_nothing_for_importers_without_event_mode(tmp_path, fmi_version, fmi_type):
    """A clock-driven component that does not step itself, in fmpy (no event mode, no clocks):
    the same samples with and without its Clock declared, FMI 2.0 and 3.0 builds."""
    from deltafmi.builder import build_fmu
    counts = {}
    for clocked in (False, True):
        fmu = build_fmu(TICKER, tmp_path / f"ticker{clocked}.fmu", class_name="ClockedTicker" if clocked else "Ticker",
                        fmi_version=fmi_version)
        result = fmpy.simulate_fmu(str(fmu), fmi_type=fmi_type, stop_time=0.006, output_interval=1e-3,
                                   output=["n"])
        counts[clocked] = result["n"].tolist()
    assert counts[True] == counts[False] and counts[False][-1] >= 6
