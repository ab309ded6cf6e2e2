"""FMI 3.0 Co-Simulation event mode of our FMUs, driven as the Reference FMUs' fmusim drives it
(tests/c_host/fmi3_cs_events.c, flags from the command line) and through fmpy's simulate_fmu.

The reference for the bouncing ball's events is independent of Co-Simulation: fmpy's Model
Exchange run of the FMI 2.0 build (its own CVODE locating the roots of the event indicators at
rtol 1e-10), and the closed form of the first impact, sqrt(2 h0 / g). The values at the
communication points are compared with the FMI 2.0 Co-Simulation run (fmpy), which handles the
events inside its steps."""
from __future__ import annotations

import math
import subprocess
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy import extract, read_model_description

from conftest import FMU_SRC, NATIVE, ROOT

STOP, H = 3.0, 0.01
BALL_OUTPUTS = ["q", "v", "contact"]


def _build(source: Path, version: int, class_name: str | None = None) -> Path:
    from deltafmi.builder.packager import build_cached
    return build_cached(source, fmi_version=version, class_name=class_name)


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    exe = tmp_path_factory.mktemp("fmi3_cs_events") / "fmi3_cs_events"
    subprocess.run(["cc", "-O2", "-Wall", "-Wextra", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "fmi3_cs_events.c"),
                    "-o", str(exe), "-ldl", "-lm"], check=True)
    return exe


class Unzipped:
    def __init__(self, fmu: Path, directory: Path) -> None:
        self.fmu = fmu
        self.md = read_model_description(str(fmu))
        self.dir = Path(extract(str(fmu), str(directory)))
        self.vr = {v.name: (v.valueReference, v.type) for v in self.md.modelVariables}

    def run(self, host: Path, event_mode_used: bool, early_return_allowed: bool, stop: float, step: float,
            *names: str) -> tuple[np.ndarray, np.ndarray]:
        """The host's step rows (t, eventHandlingNeeded, earlyReturn, values...) and event rows
        (t, values after Event Mode...)."""
        variables = [("i" if self.vr[n][1] in ("Int32", "Boolean") else "") + str(self.vr[n][0]) for n in names]
        run = subprocess.run([str(host), str(self.dir), self.md.coSimulation.modelIdentifier, self.md.guid,
                              str(int(event_mode_used)), str(int(early_return_allowed)), str(stop), str(step),
                              *variables], capture_output=True, text=True, timeout=300,
                             env={"PATH": "/usr/bin:/bin"})
        assert run.returncode == 0, run.stderr
        lines = [line.split(",") for line in run.stdout.split()]
        steps = np.array([[float(x) for x in line[1:]] for line in lines if line[0] == "step"])
        events = np.array([[float(x) for x in line[1:]] for line in lines if line[0] == "event"])
        return steps, events.reshape(-1, len(names) + 1)


@pytest.fixture(scope="module")
def ball3(tmp_path_factory) -> Unzipped:
    return Unzipped(_build(FMU_SRC / "bouncing_ball.py", 3), tmp_path_factory.mktemp("ball3"))


@pytest.fixture(scope="module")
def ball2() -> Path:
    return _build(FMU_SRC / "bouncing_ball.py", 2)


@pytest.fixture(scope="module")
def me_events(ball2) -> np.ndarray:
    """The impacts' state events in fmpy's Model Exchange run of the FMI 2.0 build, from the rows
    it records before and after each event (the same time stamp twice): time, contact state
    before, contact state after."""
    result = fmpy.simulate_fmu(str(ball2), fmi_type="ModelExchange", stop_time=STOP, output_interval=H,
                               relative_tolerance=1e-10, output=BALL_OUTPUTS)
    t = result["time"]
    at = np.flatnonzero(np.diff(t) == 0)  # the row before each event; the next one is after it
    assert len(at) == 14
    return np.column_stack([t[at], result["contact"][at], result["contact"][at + 1]])


@pytest.fixture(scope="module")
def fmi2_cs(ball2) -> np.ndarray:
    """The FMI 2.0 Co-Simulation run on the grid: t, q, v, contact."""
    result = fmpy.simulate_fmu(str(ball2), fmi_type="CoSimulation", stop_time=STOP, output_interval=H,
                               output=BALL_OUTPUTS)
    return np.column_stack([result[name] for name in ["time", *BALL_OUTPUTS]])


def test_with_early_return_every_impact_comes_back_at_its_model_exchange_time(ball3, host, me_events,
                                                                               fmi2_cs):
    """eventModeUsed and earlyReturnAllowed: fmi3DoStep returns at each of the 14 state events
    with eventHandlingNeeded, earlyReturn and lastSuccessfulTime at the event, within 1e-6 s of
    the Model Exchange event times (the first impact also at its closed form sqrt(2 h0 / g),
    h0 = 1 m, to 1e-8 s). Event Mode there changes the contact state, so the FMU left each event
    to the importer. On the grid the values equal the FMI 2.0 CS run's: the same CVODE restarted
    at the same events."""
    steps, events = ball3.run(host, True, True, STOP, H, *BALL_OUTPUTS)
    early = steps[steps[:, 2] == 1]
    np.testing.assert_allclose(early[:, 0], me_events[:, 0], rtol=0, atol=1e-6)
    assert early[0, 0] == pytest.approx(math.sqrt(2 * 1.0 / 9.81), abs=1e-8)
    assert np.all(early[:, 1] == 1)  # every early return asks for event handling
    np.testing.assert_array_equal(events[:, 0], early[:, 0])  # and the host handled each there
    # the contact state before each Event Mode and after it, as around the Model Exchange events:
    # the step left each event to the importer, whose Event Mode handled it
    np.testing.assert_array_equal(early[:, 5], me_events[:, 1])
    np.testing.assert_array_equal(events[:, 3], me_events[:, 2])
    assert np.any(me_events[:, 1] != me_events[:, 2])  # Event Mode has something to show
    grid = steps[steps[:, 2] == 0]
    assert np.all(grid[:, 1] == 0)  # no event at a communication point
    np.testing.assert_array_equal(grid[:, 0], fmi2_cs[:, 0])
    np.testing.assert_allclose(grid[:, 3:], fmi2_cs[:, 1:], rtol=0, atol=1e-12)


def _step_ends(event_times: np.ndarray) -> np.ndarray:
    """The communication points that end the steps holding these events."""
    return np.ceil(event_times / H - 1e-9) * H


def test_without_early_return_the_impacts_are_handled_inside_and_reported_at_the_step_end(
        ball3, host, me_events, fmi2_cs):
    """eventModeUsed without earlyReturnAllowed: the FMU must reach each communication point, so
    an impact inside a step is over when the step returns; the FMU handles it at its time inside
    the step and returns eventHandlingNeeded at the step's end (no earlyReturn). The importer's
    Event Mode there finds nothing left (the contact state is the same after it), and the values
    equal the FMI 2.0 CS run's, and the early-return run's on the grid, where the importer
    handled each event at its time."""
    steps, events = ball3.run(host, True, False, STOP, H, *BALL_OUTPUTS)
    reported = steps[steps[:, 1] == 1]
    np.testing.assert_allclose(reported[:, 0], _step_ends(me_events[:, 0]), rtol=0, atol=1e-12)
    assert len(reported) == 14 and not steps[:, 2].any()
    np.testing.assert_array_equal(events[:, 0], reported[:, 0])  # the host's Event Mode at each
    np.testing.assert_array_equal(events[:, 3], reported[:, 5])  # which had nothing left to do
    np.testing.assert_array_equal(steps[:, 0], fmi2_cs[:, 0])
    np.testing.assert_allclose(steps[:, 3:], fmi2_cs[:, 1:], rtol=0, atol=1e-12)
    # the same trajectory as where the importer handled each event at its time
    with_early_return, _ = ball3.run(host, True, True, STOP, H, *BALL_OUTPUTS)
    np.testing.assert_array_equal(steps[:, 3:], with_early_return[with_early_return[:, 2] == 0, 3:])


def test_without_early_return_an_event_at_the_communication_point_is_the_importers(host, tmp_path):
    """A sampled counter with a time event at every communication point (sample_period = step):
    with eventModeUsed and no early return each fmi3DoStep reaches its point and asks for event
    handling there (not an early return); the count before Event Mode is the samples up to the
    last point, after it the FMI 3.0 run without event mode's, which samples inside its steps."""
    ticker = Unzipped(_build(ROOT / "tests" / "components" / "ticker" / "model.py", 3, "Ticker"), tmp_path / "t")
    steps, events = ticker.run(host, True, False, 0.006, 1e-3, "n")
    plain, no_events = ticker.run(host, False, False, 0.006, 1e-3, "n")
    assert len(no_events) == 0 and not plain[:, 1:3].any()
    assert np.all(steps[1:, 1] == 1) and not steps[:, 2].any()  # eventHandlingNeeded, no earlyReturn
    np.testing.assert_array_equal(events[:, 0], steps[1:, 0])
    np.testing.assert_array_equal(steps[1:, 3], plain[:-1, 3])  # before the sample at the point
    np.testing.assert_array_equal(events[:, 1], plain[1:, 3])  # after it
    assert list(events[:, 1]) == [2, 3, 4, 5, 6, 7]


@pytest.mark.parametrize("early_return_allowed", [False, True])
def test_a_clock_driven_component_samples_only_at_the_ticks_the_importer_activates(host, tmp_path,
                                                                                   early_return_allowed):
    """The counter declaring its sample instants as a Clock, in event mode: its steps only move
    time and report nothing (the ticks are the importer's to activate in Event Mode; this host
    activates none), with or without early return. Without event mode it samples in its steps."""
    fmu = _build(ROOT / "tests" / "components" / "ticker" / "model.py", 3, "ClockedTicker")
    ticker = Unzipped(fmu, tmp_path / "t")
    steps, events = ticker.run(host, True, early_return_allowed, 0.006, 1e-3, "n")
    assert len(events) == 0 and not steps[:, 1:3].any()
    assert len(set(steps[:, 3])) == 1  # no sample in any step
    plain, _ = ticker.run(host, False, False, 0.006, 1e-3, "n")
    assert list(plain[:, 3]) == [1, 2, 3, 4, 5, 6, 7]


@pytest.mark.parametrize("early_return_allowed", [False, True])
def test_without_event_mode_nothing_changes(ball3, host, fmi2_cs, early_return_allowed):
    """eventModeUsed = false: every event is handled inside the steps, with or without early
    return allowed; no flag is set and the values are the FMI 2.0 CS run's."""
    steps, events = ball3.run(host, False, early_return_allowed, STOP, H, *BALL_OUTPUTS)
    assert len(events) == 0 and not steps[:, 1:3].any()
    np.testing.assert_array_equal(steps[:, 0], fmi2_cs[:, 0])
    np.testing.assert_allclose(steps[:, 3:], fmi2_cs[:, 1:], rtol=0, atol=1e-12)


@pytest.mark.parametrize("early_return_allowed", [True, False])
def test_fmpy_simulate_fmu_with_event_mode(ball3, me_events, fmi2_cs, early_return_allowed):
    """fmpy's simulate_fmu runs FMI 3.0 Co-Simulation with event mode (use_event_mode,
    early_return_allowed) in fmusim's loop and records a row before and after each Event Mode.
    With early return: a pair at each Model Exchange event time (to 1e-6 s); without it a pair
    at the end of each step that handled an impact inside. The rows on the grid (after any Event
    Mode there) are the FMI 2.0 CS run's."""
    result = fmpy.simulate_fmu(str(ball3.fmu), fmi_type="CoSimulation", stop_time=STOP, output_interval=H,
                               output=BALL_OUTPUTS, use_event_mode=True, early_return_allowed=early_return_allowed)
    t = result["time"]
    events = t[1:][np.diff(t) == 0]
    if early_return_allowed:
        np.testing.assert_allclose(events, me_events[:, 0], rtol=0, atol=1e-6)
    else:
        np.testing.assert_allclose(events, _step_ends(me_events[:, 0]), rtol=0, atol=1e-12)
    on_grid = np.isin(t, fmi2_cs[:, 0]) & np.r_[t[1:] != t[:-1], True]  # the row after an Event Mode
    assert on_grid.sum() == len(fmi2_cs)
    table = np.column_stack([result[name] for name in BALL_OUTPUTS])[on_grid]
    np.testing.assert_allclose(table, fmi2_cs[:, 1:], rtol=0, atol=1e-12)
