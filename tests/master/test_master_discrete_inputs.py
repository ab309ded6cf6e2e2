"""Boolean and Integer signals into a Model Exchange unit: FMI 2.0 lets discrete inputs change in
event mode only, so the master sets them inside an event at the communication point where they
change. A valve (Boolean) and a gain (Integer) drive a tank level whose exact solution is a ramp."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master

SCHEDULE = '''from deltafmi.component import Component, Output, Parameter


class Schedule(Component):
    """Opens the valve at t_open and doubles the gain at t_double (sampled at step ends)."""

    t_open = Parameter(0.25)
    t_double = Parameter(0.6)
    valve = Output(False, type=bool)
    gain = Output(1, type=int)

    def do_step(self, t, h):
        self.valve = t + h >= self.t_open - 1e-12
        self.gain = 2 if t + h >= self.t_double - 1e-12 else 1
'''

TANK = '''from deltafmi.component import Component, Input, Output, State


class Tank(Component):
    """Level rises at gain m/s while the valve is open."""

    level = State(0.0)
    valve = Input(False, type=bool)
    gain = Input(1, type=int)
    inflow = Output(0.0)

    def derivatives(self, t):
        return [self.gain * float(self.valve)]

    def outputs(self, t):
        self.inflow = self.gain * float(self.valve)
'''

SCENARIO = '''experiment: {{start: 0.0, stop: 1.0, step: 0.05}}
master: {{algorithm: {algorithm}}}
components:
  schedule: {{source: {schedule}, interface: CS}}
  tank: {{source: {tank}, interface: ME, solver: {{method: {method}}}}}
connections:
  - {{from: schedule.valve, to: tank.valve}}
  - {{from: schedule.gain, to: tank.gain}}
outputs: [tank.level, tank.inflow, schedule.valve, schedule.gain]
'''


@pytest.mark.parametrize("method", ["bdf", "rk4"])
@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_discrete_inputs_reach_a_model_exchange_unit(tmp_path: Path, algorithm: str, method: str):
    (tmp_path / "schedule.py").write_text(SCHEDULE)
    (tmp_path / "tank.py").write_text(TANK)
    path = tmp_path / "tank.yaml"
    path.write_text(SCENARIO.format(algorithm=algorithm, method=method, schedule=tmp_path / "schedule.py",
                                    tank=tmp_path / "tank.py"))
    Master(resolve_system(load_scenario(path)), result=tmp_path / "tank.csv").run()
    c = columns(tmp_path / "tank.csv")
    # The schedule's step from t to t + h outputs its values at t + h. Gauss-Seidel steps it first
    # and hands those to the tank for the same step, so the tank's valve opens at 0.25 - h;
    # Jacobi hands over values from the start of the step: it opens at 0.25. Likewise the gain.
    h = 0.05
    lag = 0.0 if algorithm == "gauss-seidel" else h
    t_open, t_double = 0.25 - h + lag, 0.6 - h + lag
    t = c["time"]
    exact = np.clip(t - t_open, 0.0, None) + np.clip(t - t_double, 0.0, None)
    np.testing.assert_allclose(c["tank.level"], exact, atol=1e-9)
    assert c["tank.inflow"][-1] == 2.0


@pytest.mark.parametrize("method", ["bdf", "rk4"])
def test_discrete_inputs_survive_a_rejected_adaptive_step(tmp_path: Path, method: str):
    """The adaptive master redoes steps from a saved FMU state: the state brings back the tank's
    old valve and gain, so the redone step must see their change again and set them."""
    (tmp_path / "schedule.py").write_text(SCHEDULE)
    (tmp_path / "tank.py").write_text(TANK)
    path = tmp_path / "tank.yaml"
    text = SCENARIO.format(algorithm="gauss-seidel", method=method, schedule=tmp_path / "schedule.py",
                           tank=tmp_path / "tank.py")
    path.write_text(text.replace("master: {algorithm: gauss-seidel}",
                                 "master: {algorithm: gauss-seidel, adaptive: {enabled: true, tolerance: 1e-6}}"))
    Master(resolve_system(load_scenario(path)), result=tmp_path / "tank.csv").run()
    c = columns(tmp_path / "tank.csv")
    # Gauss-Seidel: over each step the tank sees the schedule's values from that step's end
    t, level = c["time"], c["tank.level"]
    rate = c["schedule.valve"] * c["schedule.gain"]
    advancing = np.diff(t) > 0
    expected = rate[1:][advancing] * np.diff(t)[advancing]
    np.testing.assert_allclose(np.diff(level)[advancing], expected, atol=1e-9)
    assert level[-1] > 0.5  # the valve opened before 0.6 s and the gain doubled
