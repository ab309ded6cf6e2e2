"""The master honours the Clocks of FMI 3.0 FMUs (FMI 3.0, 2.2.9 "Clocks").

Sampler3 (tests/third_party, plain C) is driven ONLY by its two input Clocks, with no time
events: ``sample`` (fixed: interval T and shift from fmi3GetIntervalDecimal/fmi3GetShiftDecimal)
integrates y := y + T u, ``slow`` (constant: 0.25 s from 0.05 s, in the XML) holds u; its output
Clock ``overflow`` ticks with every 4th tick of sample. An importer
that ignores clocks never sees it sample, so every number here shows the master activating the
clocks at their ticks: alone and fed by StateSpace3 against closed forms (to 1e-12), ticks inside
communication steps, two clocks with different intervals (and at one instant together), the Clocks
the master refuses, and the flagship with its FMUs built as FMI 3.0, the controller's Clock
driven by the master, against the FMI 2.0 flagship.

Where a tick lands at a communication point: Model Exchange takes it as a time event at the end
of the step that reaches it (inputs held over that step), Co-Simulation at the start of the step
from it (the inputs given there), as FMI 2.0 FMUs take their own samples.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.errors import ScenarioError, SimulationError
from conftest import ROOT
from test_master_loops import _with_attribute as with_attribute
from third_party.build import build_fmu

#: StateSpace3's A and x0 (its start values): with u = 0, y[1] = x[1](t) = (expm(A t) x0)[1]
A = np.array([[-1.0, 2.0, 0.0], [-2.0, -1.0, 0.0], [0.0, 0.0, -0.5]])
X0 = np.array([1.0, 0.0, 0.5])
EPS = 1e-12


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("clocked")
    return {model: build_fmu(model, out) for model in ("Sampler3", "StateSpace3")}


def run(tmp_path: Path, text: str, name: str = "run"):
    """Run the scenario ``text``: (the master, after the run; the result columns)."""
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    master = Master(resolve_system(load_scenario(path)), result=tmp_path / f"{name}.csv")
    master.run()
    return master, columns(tmp_path / f"{name}.csv")


def ticks(first: float, interval: float, stop: float) -> np.ndarray:
    """A periodic Clock's ticks up to ``stop``, as first + i * interval."""
    n = int(np.floor((stop - first) / interval + 1e-9)) + 1
    return first + interval * np.arange(n)


def taken(tick_times: np.ndarray, t: float, at_t: bool) -> int:
    """How many ticks were taken when a row at ``t`` is written (those at t too when ``at_t``)."""
    return int(np.sum(tick_times <= t + EPS) if at_t else np.sum(tick_times < t - EPS))


def on_grid(t: float, h: float) -> bool:
    return abs(t / h - round(t / h)) < 1e-9


@pytest.mark.parametrize("interface", ["ME", "CS"])
@pytest.mark.parametrize("kind", ["fixed", "tunable"])
def test_clock_only_fmu_alone_samples_at_every_tick(fmus, tmp_path, interface, kind):
    """u = 2 held, T = 0.07 s from 0.02 s (ticks inside the 0.1 s steps and at 0.3 s, where
    slow ticks too: both together), slow every 0.25 s from 0.05 s. Each row shows exactly the
    ticks taken before it: y = T u (ticks of sample), held = u once slow ticked; a tick inside a
    step gets a row before and after it; the FMU counted every activation the master made.
    Declared tunable, sample is asked for its interval after every Event Mode too (unchanged)."""
    h, T, u, stop = 0.1, 0.07, 2.0, 1.0
    fmu = with_attribute(fmus["Sampler3"], tmp_path / "Sampler3.fmu", 'intervalVariability="fixed"',
                         f'intervalVariability="{kind}"')
    master, c = run(tmp_path, f"""experiment: {{stop: {stop}, step: {h}}}
components:
  s: {{fmu: {fmu}, interface: {interface}, parameters: {{u: {u}, T: {T}, delay: 0.02}}}}
outputs: [s.y, s.held, s.ticks, s.slow_ticks]
""")
    sample, slow = ticks(0.02, T, stop), ticks(0.05, 0.25, stop)
    times = c["time"]
    assert np.all(np.diff(times) >= 0)
    for t in np.unique(times):
        rows = np.flatnonzero(times == t)
        grid = on_grid(t, h)
        is_tick = np.any(np.abs(sample - t) < EPS) or np.any(np.abs(slow - t) < EPS)
        # a tick inside a step, or (ME) at its end: a row before and one after it
        assert len(rows) == (2 if is_tick and not (grid and interface == "CS") else 1), t
        at_t = [False, True] if len(rows) == 2 else [interface == "ME" or not grid]
        for row, after in zip(rows, at_t):
            n, m = taken(sample, t, after), taken(slow, t, after)
            assert c["s.ticks"][row] == n and c["s.slow_ticks"][row] == m, (t, after)
            assert abs(c["s.y"][row] - n * T * u) <= 1e-12
            assert c["s.held"][row] == (u if m else 0.0)
    # Model Exchange takes the tick at the stop time, Co-Simulation leaves it to a next step
    expected = {"sample": taken(sample, stop, interface == "ME"), "slow": len(slow)}
    assert master.units[0].clocks.activations == expected
    assert c["s.ticks"][-1] == expected["sample"] == 15 - (interface == "CS")
    # the output Clock overflow, read in every Event Mode, ticked with every 4th tick of sample
    assert master.units[0].clocks.output_ticks == {"overflow": expected["sample"] // 4}


@pytest.mark.parametrize("interface", ["ME", "CS"])
def test_clock_only_fmu_fed_by_a_continuous_fmu_samples_its_closed_form(fmus, tmp_path, interface):
    """StateSpace3 (Co-Simulation, exact steps) drives Sampler3's u with y[1] = x1(t); Jacobi, so
    the input over the step from t_n is x1(t_n). sample every 0.03 s from 0 (ticks at and
    between the 0.1 s communication points): y = sum of T x1(t_n) over the ticks taken, t_n the
    step whose input the tick saw (Model Exchange: ticks in (t_n, t_n + h] and the first in
    the initial event; Co-Simulation: ticks in [t_n, t_n + h)). slow holds x1 likewise."""
    h, T, stop = 0.1, 0.03, 1.0
    _, c = run(tmp_path, f"""experiment: {{stop: {stop}, step: {h}}}
master: {{algorithm: jacobi}}
components:
  ss: {{fmu: {fmus['StateSpace3']}, interface: CS}}
  s: {{fmu: {fmus['Sampler3']}, interface: {interface}, parameters: {{T: {T}}}}}
connections:
  - {{from: 'ss.y[1]', to: s.u}}
outputs: ['ss.y[1]', s.y, s.held, s.ticks]
""")

    def x1(t: float) -> float:
        return float((expm(A * t) @ X0)[0])

    def seen(tick: float) -> float:
        """x1 at the communication point whose input the tick saw."""
        n = np.floor((tick + EPS) / h) if interface == "CS" else max(np.ceil((tick - EPS) / h) - 1, 0)
        return x1(n * h)

    sample, slow = ticks(0.0, T, stop), ticks(0.05, 0.25, stop)
    times = c["time"]
    last_rows = np.r_[np.flatnonzero(np.diff(times) > 0), len(times) - 1]  # each time's last row
    checked = 0
    for row in last_rows:
        t = times[row]
        at_t = interface == "ME" or not on_grid(t, h)
        taken_sample = sample[sample <= t + EPS] if at_t else sample[sample < t - EPS]
        taken_slow = slow[slow <= t + EPS] if at_t else slow[slow < t - EPS]
        assert c["s.ticks"][row] == len(taken_sample)
        assert abs(c["s.y"][row] - sum(T * seen(tick) for tick in taken_sample)) <= 1e-12
        assert abs(c["s.held"][row] - (seen(taken_slow[-1]) if len(taken_slow) else 0.0)) <= 1e-12
        checked += 1
    assert checked > 20 and c["s.ticks"][-1] >= 33


def test_sampler_answers_the_clock_functions_as_fmi3_says(fmus, tmp_path):
    """Sampler3 itself, through fmpy's FMU3Model: the fixed Clock's interval and shift come from
    its parameters (fmi3IntervalChanged at the first query in Initialization Mode, then
    fmi3IntervalUnchanged), the constant one's are the XML's; fmi3SetClock is refused outside
    Event Mode; an activated Clock runs its partition once and fmi3UpdateDiscreteStates
    deactivates it. fmpy.simulate_fmu, which does not activate clocks, never sees it sample."""
    import ctypes

    import fmpy
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi3 import FMU3Model, fmi3IntervalChanged, fmi3IntervalUnchanged, fmi3ValueReference

    fmu_path = str(fmus["Sampler3"])
    md = fmpy.read_model_description(fmu_path)
    fmu = FMU3Model(guid=md.guid, unzipDirectory=fmpy.extract(fmu_path, unzipdir=str(tmp_path / "x")),
                    modelIdentifier="Sampler3", instanceName="s")
    fmu.instantiate()
    fmu.setFloat64([1, 2, 3], [0.04, 0.01, 3.0])  # T, delay, u
    fmu.enterInitializationMode()
    refs = (fmi3ValueReference * 2)(8, 9)

    def timing():
        intervals, qualifiers, shifts = (ctypes.c_double * 2)(), (ctypes.c_int * 2)(), (ctypes.c_double * 2)()
        fmu.getIntervalDecimal(refs, intervals, qualifiers)
        fmu.getShiftDecimal(refs, shifts)
        return list(intervals), list(qualifiers), list(shifts)

    assert timing() == ([0.04, 0.25], [fmi3IntervalChanged, fmi3IntervalUnchanged], [0.01, 0.05])
    assert timing()[1] == [fmi3IntervalUnchanged] * 2
    with pytest.raises(FMICallException):
        fmu.setClock([8], [True])
    fmu.exitInitializationMode()
    fmu.setClock([8], [True])
    assert fmu.getClock([8, 9, 10]) == [True, False, False]  # overflow: with the 4th tick
    with pytest.raises(FMICallException):
        fmu.setClock([10], [True])  # an output Clock
    fmu.updateDiscreteStates()
    assert fmu.getClock([8, 9]) == [False, False]
    fmu.updateDiscreteStates()
    assert fmu.getFloat64([4]) == [0.04 * 3.0] and fmu.getInt32([6, 7]) == [1, 0]
    fmu.terminate()
    fmu.freeInstance()
    for fmi_type in ("ModelExchange", "CoSimulation"):
        result = fmpy.simulate_fmu(fmu_path, fmi_type=fmi_type, stop_time=1.0, output_interval=0.1,
                                   start_values={"u": 2.0}, output=["y", "ticks"])
        assert np.all(result["y"] == 0.0) and np.all(result["ticks"] == 0)


SLOW = 'intervalVariability="constant" intervalDecimal="0.25" shiftDecimal="0.05"'


REFUSED = [
    ("ME", SLOW, 'intervalVariability="triggered"',
     "its input Clock 'slow' is triggered (intervalVariability), which the master cannot activate"),
    ("CS", SLOW, 'intervalVariability="countdown"',
     "its input Clock 'slow' is countdown (intervalVariability), which the master cannot activate"),
    ("ME", 'intervalVariability="fixed"', 'intervalVariability="changing"',
     "its input Clock 'sample' is changing (intervalVariability), which the master cannot activate"),
    ("CS", 'hasEventMode="true"', 'hasEventMode="false"',
     "it has Clocks (sample, slow, overflow) but its <CoSimulation> has no Event Mode (hasEventMode)"),
]


@pytest.mark.parametrize("interface, old, new, message", REFUSED)
def test_clocks_the_master_cannot_drive_are_refused_by_name(fmus, tmp_path, interface, old, new, message):
    """The scenario check names the scenario line, component, FMU and Clock; the unit refuses the
    same when given it anyway (a System resolved before the FMU changed)."""
    good = tmp_path / "refused.yaml"
    good.write_text(f"experiment: {{stop: 1.0, step: 0.1}}\ncomponents:\n"
                    f"  s: {{fmu: {tmp_path / 'Sampler3.fmu'}, interface: {interface}}}\n")
    with_attribute(fmus["Sampler3"], tmp_path / "Sampler3.fmu", old, old)
    system = resolve_system(load_scenario(good))
    with_attribute(fmus["Sampler3"], tmp_path / "Sampler3.fmu", old, new)
    with pytest.raises(ScenarioError) as caught:
        resolve_system(load_scenario(good))
    assert f"refused.yaml:3: error: component 's': FMU 'Sampler3.fmu': {message}" in str(caught.value)
    with pytest.raises(SimulationError) as failed:
        Master(system, result=tmp_path / "refused.csv").run()
    assert f"s: {message}" in str(failed.value) and "Traceback" not in str(failed.value)


def test_flagship_built_as_fmi3_with_the_controllers_clock_equals_fmi2(tmp_path):
    """delta_tracking with its three FMUs built as FMI 3.0: the controller declares its 1 kHz
    sampling as a periodic input Clock, which the master activates at every tick (3500, from
    t = 0; Co-Simulation in event mode, the step itself reports no event); the wrist follows the
    FMI 2.0 flagship to 1e-9 m, one row per step. The C loop takes the ticks (CLOCK_TICK) with
    the same calls as the Python loop: the same rows, bit for bit."""
    from dataclasses import replace

    from deltafmi import simulate
    from deltafmi.master.stepping import c_loop as native_loop
    fmi2 = simulate("delta_tracking", record=["plant.z[*]", "controller.status"])
    scenario = load_scenario("delta_tracking")
    scenario = replace(scenario, components=tuple(replace(spec, fmi_version=3) for spec in scenario.components))
    text, ran_in_c = {}, []
    original = native_loop.NativeLoop.run

    def counting(loop, k, k_end):
        ran_in_c.append(k_end - k)
        return original(loop, k, k_end)

    for native in (True, False):
        master = Master(resolve_system(scenario), result=tmp_path / f"fmi3{native}.csv", native=native)
        native_loop.NativeLoop.run = counting
        try:
            master.run()
        finally:
            native_loop.NativeLoop.run = original
        controller = next(unit for unit in master.units if unit.name == "controller")
        assert controller.clocks is not None and controller.clocks.names == ["sample"]
        assert controller.clocks.interval.tolist() == [1e-3] and controller.clocks.activations == {"sample": 3500}
        text[native] = master.result_path.read_text()
    assert text[True] == text[False] and sum(ran_in_c) == 3500  # every step in C, and the same rows
    c = columns(tmp_path / "fmi3True.csv")
    assert np.array_equal(c["time"], np.asarray(fmi2["time"]))
    for i in (1, 2, 3):
        assert np.max(np.abs(c[f"plant.z[{i}]"] - np.asarray(fmi2[f"plant.z[{i}]"]))) <= 1e-9
    assert np.array_equal(c["controller.status"], np.asarray(fmi2["controller.status"]))


@pytest.mark.parametrize("period, ticks, inside, some_in_c", [(1.5e-3, 33, 16, True), (0.6e-3, 83, 66, False)])
def test_ticks_inside_steps_hand_the_step_from_c_to_python(tmp_path, period, ticks, inside, some_in_c):
    """The controller alone (FMI 3.0, Co-Simulation) sampled every 1.5 ms (0.6 ms) on a 1 ms grid:
    ticks at communication points are taken in C (CLOCK_TICK) unless another tick follows inside
    the step, and steps with a tick inside go to Python (the step is split at it, a row before and
    after); at 0.6 ms every step has one, also those whose start is a tick. Both loops: the same
    activations (one per tick before the stop) and the same rows, bit for bit."""
    from deltafmi.master.stepping import c_loop as native_loop
    path = tmp_path / "controller.yaml"
    path.write_text(f"""fmi_version: 3
experiment: {{stop: 0.0495, step: 1.0e-3}}
components:
  controller:
    source: deltafmi.models:DeltaController
    interface: CS
    parameters: {{sample_period: {period}, y: [0.1, 0.2, 0.3], yd: [0.5, 0.0, -0.5], r: [0.01, 0.0, -0.95]}}
outputs: ['controller.u', controller.status]
""")
    text, in_c = {}, []
    original = native_loop.NativeLoop.run

    def counting(loop, k, k_end):
        found = original(loop, k, k_end)
        in_c.append(found[1] - k)
        return found

    for native in (True, False):
        master = Master(resolve_system(load_scenario(path)), result=tmp_path / f"{native}.csv", native=native)
        native_loop.NativeLoop.run = counting
        try:
            master.run()
        finally:
            native_loop.NativeLoop.run = original
        assert master.units[0].clocks.activations == {"sample": ticks}
        text[native] = master.result_path.read_text()
    assert text[True] == text[False]
    assert (0 < sum(in_c) < 50) if some_in_c else sum(in_c) == 0
    c = columns(tmp_path / "True.csv")
    times = c["time"]
    assert np.all(np.diff(times) >= 0) and len(times) == 51 + 2 * inside
    assert np.ptp(c["controller.u[1]"]) > 0.1


def test_a_sample_that_fails_at_a_tick_taken_in_c_is_one_line(tmp_path):
    """A clock-driven component's sample raises at a tick the C loop takes (fmi3UpdateDiscreteStates
    fails): the run ends with the failure the Python loop reports, naming the unit and the
    component's message, no traceback."""
    from deltafmi.errors import SimulationError
    path = tmp_path / "failing.yaml"
    path.write_text(f"""fmi_version: 3
experiment: {{stop: 0.01, step: 1.0e-3}}
components:
  f: {{source: '{ROOT / "tests" / "components" / "ticker" / "model.py"}:ClockedTicker', interface: CS,
      parameters: {{fail_after: 3.5e-3}}}}
outputs: [f.n]
""")
    messages = {}
    for native in (True, False):
        with pytest.raises(SimulationError) as failed:
            Master(resolve_system(load_scenario(path)), result=tmp_path / f"{native}.csv", native=native).run()
        messages[native] = str(failed.value).replace(f"{native}.failed.csv", "result.csv")  # a failed run's rows
    assert "the sample at t = 0.004 failed" in messages[True] and "Traceback" not in messages[True]
    assert messages[True] == messages[False]
