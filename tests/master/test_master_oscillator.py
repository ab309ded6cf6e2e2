"""The master on fmu_src/oscillator.py, checked against its closed-form solution.

ME through the master's own CVODE (state events at the wall, a time event at t_step), CS through
the FMU's doStep, and the recording of events as repeated time stamps.
"""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.errors import SimulationError
from oscillator_analytic import solution


@pytest.fixture(scope="module")
def osc_fmu(build_fmu_from_src) -> Path:
    return build_fmu_from_src("oscillator.py")


def simulate(tmp_path: Path, text: str, **master_args):
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(text))
    summary = Master(resolve_system(load_scenario(path)), result=tmp_path / "r.csv", **master_args).run()
    return summary, columns(tmp_path / "r.csv")


def oscillator(osc_fmu, interface: str, solver: str, step: float = 0.01, stop: float = 4.0) -> str:
    return f"""\
        experiment: {{stop: {stop}, step: {step}}}
        components:
          osc: {{fmu: {osc_fmu}, interface: {interface}, solver: {solver}}}
        outputs: [osc.x, osc.v, osc.impacts, osc.force_on]
        """


def test_model_exchange_matches_closed_form_with_events(tmp_path, osc_fmu):
    summary, c = simulate(tmp_path, oscillator(osc_fmu, "ME", "{rtol: 1.0e-10, atol: 1.0e-12}"))
    t = c["time"]
    x, v, impacts = solution(t)
    assert len(impacts) == 3
    # every impact is a pair of rows at the same instant: before (v < 0) and after (v = -e v)
    for t_hit in impacts:
        rows = np.nonzero(np.abs(t - t_hit) < 1e-8)[0]
        assert len(rows) >= 2, t_hit
        before, after = rows[0], rows[1]
        assert t[before] == t[after]
        assert c["osc.v"][before] < 0 < c["osc.v"][after]
        assert c["osc.v"][after] == pytest.approx(-0.8 * c["osc.v"][before], rel=1e-12)
        assert c["osc.impacts"][after] == c["osc.impacts"][before] + 1
    # the time event at t_step = 2.5 falls on a communication point: one row before, one after
    at_step = np.nonzero(t == 2.5)[0]
    assert len(at_step) == 2 and c["osc.force_on"][at_step].tolist() == [0.0, 1.0]
    # the solution itself: CVODE at rtol 1e-10 across three impacts
    regular = np.isin(np.arange(len(t)), np.nonzero(np.diff(t) == 0)[0], invert=True)
    assert np.max(np.abs(c["osc.x"][regular] - x[regular])) < 1e-7
    assert np.max(np.abs(c["osc.v"][regular] - v[regular])) < 1e-6
    assert summary.steps == 400 and summary.events >= 4 and summary.rejected == 0


def test_co_simulation_matches_closed_form(tmp_path, osc_fmu):
    summary, c = simulate(tmp_path, oscillator(osc_fmu, "CS", "{rtol: 1.0e-10}"))
    t = c["time"]
    assert np.all(np.diff(t) > 0)  # CS events happen inside doStep: no repeated stamps
    x, v, _ = solution(t)
    assert np.max(np.abs(c["osc.x"] - x)) < 1e-6
    assert c["osc.impacts"][-1] == 3.0


def test_record_every_and_stop_override(tmp_path, osc_fmu):
    text = oscillator(osc_fmu, "CS", "{rtol: 1.0e-8}", step=0.01) + "result: {every: 10}\n"
    summary, c = simulate(tmp_path, text, stop=0.25)
    assert c["time"].tolist() == pytest.approx([0.0, 0.1, 0.2, 0.25], abs=1e-15)
    assert summary.steps == 25 and summary.simulated == pytest.approx(0.25)


def test_failure_keeps_results_up_to_it(tmp_path, osc_fmu):
    # an absurd force step at t = 1 s makes CVODE fail there; everything before stays on disk
    text = oscillator(osc_fmu, "ME", "{rtol: 1.0e-8}").replace(
        "solver:", "parameters: {F_step: 1.0e+308, t_step: 1.0}, solver:")
    with pytest.raises(SimulationError) as failure:
        simulate(tmp_path, text)
    message = str(failure.value.message)
    assert message.startswith("simulation failed at t = 1 s: osc: CVODE failed")
    assert f"results up to the failure in {tmp_path / 'r.failed.csv'}" in message and "\n" not in message
    c = columns(tmp_path / "r.failed.csv")
    assert c["time"][-1] == pytest.approx(1.0) and len(c["time"]) >= 101
    x, _, _ = solution(c["time"][:100])
    assert np.max(np.abs(c["osc.x"][:100] - x)) < 1e-5


@pytest.mark.parametrize("method, order", [("rk4", 4), ("rk3", 3)])
def test_explicit_runge_kutta_converges_at_its_order_through_events(tmp_path, osc_fmu, method, order):
    """Fixed-step Runge-Kutta in the master: three wall impacts located by bisection and the
    time event at 2.5 s; halving the step divides the error against the closed form by 2^order."""
    errors = []
    for h in (2e-3, 1e-3):  # both divide the 10 ms communication step
        summary, c = simulate(tmp_path, oscillator(osc_fmu, "ME", f"{{method: {method}, max_step: {h}}}"))
        t = c["time"]
        x, _, impacts = solution(t)
        pairs = np.nonzero(np.diff(t) == 0)[0]
        located = t[pairs][c["osc.impacts"][pairs + 1] > c["osc.impacts"][pairs]]
        assert np.max(np.abs(located - impacts)) < 50 * h ** order  # event time error ~ h^order
        regular = np.isin(np.arange(len(t)), pairs, invert=True)
        errors.append(np.max(np.abs(c["osc.x"][regular] - x[regular])))
        assert summary.steps == 400 and c["osc.impacts"][-1] == 3.0
    assert 0.7 * 2 ** order < errors[0] / errors[1] < 1.4 * 2 ** order
    assert errors[1] < {4: 1e-7, 3: 1e-5}[order]
