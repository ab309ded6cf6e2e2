"""Event rows hold one consistent instant: the event unit's values at its event, every other
unit's as of the start of the communication step (a co-simulation knows them only at its
communication points), never a value of a time after the row's own.

A textbook ball (Model Exchange, or FMI 3.0 Co-Simulation in Event Mode) dropped from 1 m hits
the floor at t_e = sqrt(2 h0 / g) = 0.4515 s, inside the step [0.45, 0.46]. Beside it a clock
(x' = 1, y = x) steps before it in the Gauss-Seidel order, a follower takes the ball's height
(y = u), and in one variant two units close an algebraic loop (y = x + u / 2 with u = y: y = 2 t).
Before, in a Gauss-Seidel step the clock showed 0.46 s in the rows at 0.4515 s.
"""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from deltafmi import resolve_system
from deltafmi.master.results.csv_file import columns
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master

ROOT = Path(__file__).resolve().parents[2]
PARTS = Path(__file__).parent / "event_row_parts"
G, H0, E, H = 9.81, 1.0, 0.8, 0.01
T_IMPACT = math.sqrt(2 * H0 / G)
T_STEP = math.floor(T_IMPACT / H) * H  # the start of the step the impact falls in: 0.45 s


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    here = tmp_path_factory.mktemp("event_rows")
    for part in PARTS.glob("*.py"):
        shutil.copy(part, here / part.name)
    shutil.copy(ROOT / "fmu_src" / "bouncing_ball_reinit.py", here)
    return here


def _scenario(folder: Path, name: str, algorithm: str, ball: str, clock: str = "CS", fmi: int = 2,
              loop: bool = False, adaptive: bool = False) -> Path:
    text = f"""\
experiment: {{start: 0.0, stop: 0.6, step: {H}}}
fmi_version: {fmi}
master: {{algorithm: {algorithm}, adaptive: {{enabled: {str(adaptive).lower()}, max_step: {H}}}}}
components:
  clock: {{source: clock.py:Clock, interface: {clock}}}
{"  head: {source: loophead.py:LoopHead, interface: CS}" if loop else ""}
{"  echo: {source: follower.py:Follower, interface: CS}" if loop else ""}
  ball: {{source: bouncing_ball_reinit.py:BouncingBallReinit, {ball}}}
  follower: {{source: follower.py:Follower, interface: CS}}
connections:
  - {{from: ball.height, to: follower.u}}
{"  - {from: head.y, to: echo.u, factor: 1.0}" if loop else ""}
{"  - {from: echo.y, to: head.u, factor: 1.0}" if loop else ""}
outputs: [clock.y, ball.height, ball.v, follower.u, follower.y{", head.y, echo.y" if loop else ""}]
"""
    path = folder / f"{name}.yaml"
    path.write_text(text)
    return path


def _run(path: Path, native: bool) -> dict:
    result = path.with_suffix(f".{native}.csv")
    Master(resolve_system(load_scenario(path)), result=result, native=native).run()
    return columns(result)


ME_CVODE = "interface: ME"
ME_RK4 = "interface: ME, solver: {method: rk4, max_step: 0.001}"
CASES = {
    "gauss_seidel": dict(algorithm="gauss-seidel", ball=ME_CVODE),
    "jacobi": dict(algorithm="jacobi", ball=ME_CVODE),
    "gauss_seidel_rk4": dict(algorithm="gauss-seidel", ball=ME_RK4),
    "jacobi_rk4": dict(algorithm="jacobi", ball=ME_RK4),
    "clock_me": dict(algorithm="gauss-seidel", ball=ME_CVODE, clock="ME"),
    "cs_event_mode": dict(algorithm="gauss-seidel", ball="interface: CS", fmi=3),
    "cs_event_mode_jacobi": dict(algorithm="jacobi", ball="interface: CS", fmi=3),
    "loop": dict(algorithm="gauss-seidel", ball=ME_CVODE, loop=True),
    "adaptive": dict(algorithm="gauss-seidel", ball=ME_CVODE, adaptive=True),
}


@pytest.mark.parametrize("native", [True, False], ids=["c_loop", "python_loop"])
@pytest.mark.parametrize("name", list(CASES))
def test_an_event_row_shows_the_others_at_the_start_of_its_step(folder, name, native):
    case = CASES[name]
    if not native and case["ball"] != ME_RK4 and not case.get("fmi") == 3:
        pytest.skip("runs in Python either way")
    c = _run(_scenario(folder, name, **case), native)
    t = c["time"]
    # no row shows a value of a later time than its own (the clock's value is its time)
    assert np.all(c["clock.y"] <= t + 1e-9)
    repeated = np.flatnonzero(np.diff(t) == 0)
    assert len(repeated), "the impact gives rows at its time"
    before, after = repeated[0], repeated[0] + 1  # the rows just before and after the first impact
    t_e = t[before]
    assert t_e == pytest.approx(T_IMPACT, abs=1e-6)
    # the ball at its event: v = -g t_e falling, -e times that rebounding
    assert c["ball.v"][before] == pytest.approx(-G * t_e, rel=1e-6)
    assert c["ball.v"][after] == pytest.approx(E * G * t_e, rel=1e-6)
    assert abs(c["ball.height"][before]) < 1e-9
    if case.get("adaptive"):  # steps of their own size: the row before the impact starts its step
        start = before - 1
        assert t[start] < t_e
    else:
        start = int(np.flatnonzero(np.isclose(t, T_STEP, rtol=0, atol=1e-12))[0])
    for row in (before, after):
        # the clock steps before the ball: the start of the step, not its end (0.46 s) nor t_e
        assert c["clock.y"][row] == pytest.approx(t[start], abs=1e-9)
        # the follower as it was when the step began (the ball's height at that row's time)
        assert c["follower.u"][row] == c["follower.u"][start] == c["follower.y"][row]
        if case.get("loop"):
            assert c["head.y"][row] == pytest.approx(2 * t[start], abs=1e-9)  # the loop's solution there
            assert c["echo.y"][row] == c["head.y"][row]
    # the follower's input at a grid row is the ball's height at that row's time (Gauss-Seidel:
    # the ball stepped before it) or a step before (Jacobi: every unit takes the last step's)
    lag = H if case["algorithm"] == "jacobi" else 0.0
    if not case.get("adaptive"):
        assert c["follower.u"][start] == pytest.approx(H0 - G * (t[start] - lag) ** 2 / 2, abs=1e-7)


def test_an_event_at_the_end_of_a_step_shows_the_units_that_reached_it(folder):
    """A time event on the grid (the oscillator's force step at 0.45 s) ends the step [0.44, 0.45]:
    the clock, stepped before the oscillator, is there too (0.45 s, no later than the rows), in
    the row before the event and in the step's own row after it."""
    shutil.copy(ROOT / "fmu_src" / "oscillator.py", folder)
    path = folder / "time_event.yaml"
    path.write_text(f"""\
experiment: {{start: 0.0, stop: 0.6, step: {H}}}
components:
  clock: {{source: clock.py:Clock, interface: CS}}
  osc: {{source: oscillator.py:Oscillator, interface: ME, parameters: {{t_step: 0.45}}}}
outputs: [clock.y, osc.force_on]
""")
    c = _run(path, native=True)
    t = c["time"]
    at = np.flatnonzero(t == 0.45)
    assert len(at) == 2  # the row before the event, then the step's own row (after it)
    np.testing.assert_allclose(c["clock.y"][at], 0.45, rtol=0, atol=1e-9)
    assert list(c["osc.force_on"][at]) == [0, 1]
