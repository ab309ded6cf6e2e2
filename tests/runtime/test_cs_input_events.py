"""Co-Simulation events that no solver can find: an input set at a communication point that moves
an event indicator across zero (a `when` on an input), and the indicators of a component without
states (no CVODE, no root finding). Each is an event at the step where it happens, in the C step
and the Python step alike; an equation component without states builds and runs, with a when
clause too."""
from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest
from fmpy import simulate_fmu

from deltafmi.builder.packager import build_cached

SOURCE = textwrap.dedent('''
    """Test components: events on inputs and on time without states."""
    import math

    from deltafmi.component import Component, Experiment, Input, Output, Parameter
    from deltafmi.runtime.equations import EquationComponent, Real, assign, der, pre, when


    class RisingCounter(EquationComponent):
        """Counts the rising crossings of u over level (a when on an input); x integrates u."""
        default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3)
        level = Parameter(0.5)
        u = Input(0.0)
        count = Output(0, type=int)
        x = Real(0.0)

        def equations(self):
            return [der(self.x) == self.u, when(self.u > self.level, assign(self.count, pre(self.count) + 1))]


    class StatelessCounter(EquationComponent):
        """RisingCounter without its state: the when clause alone."""
        default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3)
        level = Parameter(0.5)
        u = Input(0.0)
        count = Output(0, type=int)

        def equations(self):
            return [when(self.u > self.level, assign(self.count, pre(self.count) + 1))]


    class Gain(EquationComponent):
        """y = k u: equations without states."""
        default_experiment = Experiment(start=0.0, stop=1.0, step=1e-2)
        k = Parameter(2.0)
        u = Input(1.0)
        y = Output()

        def equations(self):
            return [self.y == self.k * self.u]


    class SignFlips(Component):
        """Counts the sign changes of cos(2 pi f t): no states, one event indicator in time."""
        default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3)
        n_event_indicators = 1
        f = Parameter(2.3, unit="Hz")
        flips = Output(0, type=int)

        def setup(self):
            self._positive = None

        def event_indicators(self, t):
            return [math.cos(2.0 * math.pi * self.f * t)]

        def update(self, t):
            positive = math.cos(2.0 * math.pi * self.f * t) > 0.0
            if self._positive is not None and positive != self._positive:
                self.flips += 1
            self._positive = positive
''')


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    path = tmp_path_factory.mktemp("input_events") / "input_event_parts.py"
    path.write_text(SOURCE)
    return path


def _sine_input(f: float = 3.0):
    t = np.round(np.arange(0, 1001) * 1e-3, 12)
    return np.array(list(zip(t, np.sin(2 * np.pi * f * t))), dtype=[("time", float), ("u", float)])


@pytest.mark.parametrize("native_cs", ["1", "0"])
def test_a_when_on_an_input_fires_at_the_step_whose_input_crossed(source, monkeypatch, native_cs):
    monkeypatch.setenv("DELTAFMI_NATIVE_CS", native_cs)  # the C step, then the Python step
    fmu = build_cached(source, class_name="RisingCounter")
    signal = _sine_input()
    result = simulate_fmu(fmu, fmi_type="CoSimulation", input=signal, output=["count", "x"], stop_time=1.0,
                          output_interval=1e-3)
    # independent count: the communication points t_k where the held input first exceeds 0.5
    u = signal["u"]
    crossed = signal["time"][1:][(u[1:] > 0.5) & (u[:-1] <= 0.5)]
    assert len(crossed) == 3  # 3 Hz over 1 s
    # the event is at t_k, before the step from t_k moves: the row at t_k + h shows it
    steps_up = result["time"][1:][np.diff(result["count"]) > 0]
    assert np.allclose(steps_up, crossed + 1e-3, atol=1e-12)
    assert result["count"][-1] == 3
    # the event did not disturb the integral of the held input (a rectangle rule on the grid)
    assert result["x"][-1] == pytest.approx(np.sum(u[:-1]) * 1e-3, abs=1e-9)


def test_model_exchange_counts_the_same_crossings(source):
    fmu = build_cached(source, class_name="RisingCounter")
    result = simulate_fmu(fmu, fmi_type="ModelExchange", solver="Euler", step_size=1e-3, input=_sine_input(),
                          output=["count"], stop_time=1.0, output_interval=1e-3)
    assert result["count"][-1] == 3


@pytest.mark.parametrize("fmi_type, native_cs", [("CoSimulation", "1"), ("CoSimulation", "0"),
                                                 ("ModelExchange", "1")])
def test_a_when_on_an_input_without_states(source, monkeypatch, fmi_type, native_cs):
    """Equations with a when clause and no state (no state vector to pass the event pass) count the
    crossings RisingCounter counts."""
    monkeypatch.setenv("DELTAFMI_NATIVE_CS", native_cs)
    fmu = build_cached(source, class_name="StatelessCounter")
    signal = _sine_input()
    options = dict(solver="Euler", step_size=1e-3) if fmi_type == "ModelExchange" else {}
    result = simulate_fmu(fmu, fmi_type=fmi_type, input=signal, output=["count"], stop_time=1.0,
                          output_interval=1e-3, **options)
    u = signal["u"]
    crossed = signal["time"][1:][(u[1:] > 0.5) & (u[:-1] <= 0.5)]
    assert result["count"][-1] == len(crossed) == 3


@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_a_component_without_states_sees_its_indicators_cross_in_time(source, fmi_type):
    fmu = build_cached(source, class_name="SignFlips")
    result = simulate_fmu(fmu, fmi_type=fmi_type, output=["flips"], stop_time=1.0, output_interval=1e-3)
    zeros = (np.arange(5) + 0.5) / (2 * 2.3)  # cos(2 pi f t) = 0 at (k + 1/2) / (2 f): none on the 1 ms grid
    assert result["flips"][-1] == len(zeros) == 5
    if fmi_type == "CoSimulation":  # found at the end of the step that crossed
        first = [result["time"][np.argmax(result["flips"] >= k)] for k in range(1, 6)]
        assert np.allclose(first, np.ceil(zeros * 1e3) * 1e-3, atol=1e-12)


@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_equations_without_states_build_and_run(source, fmi_type):
    fmu = build_cached(source, class_name="Gain")
    signal = np.array([(0.0, 1.0), (1.0, 2.0)], dtype=[("time", float), ("u", float)])
    result = simulate_fmu(fmu, fmi_type=fmi_type, start_values={"k": 3.0}, input=signal, output=["y"],
                          stop_time=1.0, output_interval=0.25)
    # fmpy holds the input of a step at its start in Co-Simulation, interpolates it in Model Exchange
    t = result["time"] - (0.25 if fmi_type == "CoSimulation" else 0.0)
    assert np.allclose(result["y"][1:], 3.0 * (1.0 + t[1:]), rtol=0, atol=1e-12)
    assert math.isclose(result["y"][0], 3.0)
