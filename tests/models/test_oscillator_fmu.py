"""The example FMU through fmpy (ME and CS) and through a plain C host, against the closed form."""
from __future__ import annotations

import subprocess

import fmpy
import numpy as np
import pytest
from fmpy.fmi2 import FMU2Model
from fmpy.validation import validate_fmu

import deltafmi

from conftest import clean_env, start_model_exchange, unzip
from host_loops import as_pointer, co_simulation, host_rows, me_env, model_exchange_euler, run_c_host
from oscillator_analytic import solution

VR = {"x": 0, "v": 1, "F": 11, "energy": 12}


@pytest.fixture(scope="module")
def oscillator(build_fmu_from_src):
    return build_fmu_from_src("oscillator.py")


@pytest.fixture(scope="module")
def oscillator_dir(oscillator, tmp_path_factory):
    return unzip(oscillator, tmp_path_factory.mktemp("osc"))


def _last_row_per_time(result):
    """fmpy records event instants twice (before/after): keep the value after the event."""
    t = result["time"]
    keep = np.r_[t[1:] != t[:-1], True]
    return result[keep]


def test_validates_with_zero_problems(oscillator):
    assert validate_fmu(str(oscillator)) == []
    md = fmpy.read_model_description(str(oscillator))
    assert md.modelExchange and md.coSimulation
    assert not md.modelExchange.needsCompletedIntegratorStep  # nothing to project: no bridge call
    assert md.coSimulation.canGetAndSetFMUstate and not md.coSimulation.needsExecutionTool
    assert md.numberOfContinuousStates == 2 and md.numberOfEventIndicators == 1
    assert [u.variable.name for u in md.derivatives] == ["der(x)", "der(v)"]
    assert {u.variable.name for u in md.initialUnknowns} >= {"der(x)", "der(v)", "energy", "impacts"}


@pytest.mark.parametrize("fmi_type", ["ModelExchange", "CoSimulation"])
def test_matches_closed_form(oscillator, fmi_type):
    # rtol 1e-10: the closed form is exact, so the remaining error is the solver's and the event
    # location's; three impacts and a force step must all be located.
    result = fmpy.simulate_fmu(str(oscillator), fmi_type=fmi_type, relative_tolerance=1e-10,
                               output_interval=1e-3, output=["x", "v", "impacts", "force_on"])
    r = _last_row_per_time(result)
    x, v, impacts = solution(r["time"])
    assert np.max(np.abs(r["x"] - x)) < 1e-6
    assert np.max(np.abs(r["v"] - v)) < 1e-5
    assert r["impacts"][-1] == len(impacts) == 3
    assert r["force_on"][-1] and not r["force_on"][r["time"] < 2.5].any()
    if fmi_type == "ModelExchange":  # event rows sit at the impact instants
        jumps = result["time"][1:][np.diff(result["impacts"]) > 0]
        np.testing.assert_allclose(jumps, impacts, atol=1e-8)


def test_c_host_co_simulation_equals_fmpy(c_host, oscillator_dir):
    """No Python in the host process: the binary loads libpython itself, same numbers as fmpy."""
    rows = host_rows(run_c_host(c_host, oscillator_dir, "cs", 4.0, 1e-3, VR["x"], VR["v"]).stdout)
    expected = co_simulation(oscillator_dir, 4.0, 1e-3, [VR["x"], VR["v"]])
    np.testing.assert_allclose(rows, expected, rtol=0, atol=1e-12)
    x, _, _ = solution(rows[:, 0])
    assert np.max(np.abs(rows[:, 1] - x)) < 1e-5  # default tolerance 1e-8


def test_c_host_model_exchange_equals_python_host(c_host, oscillator_dir):
    rows = host_rows(run_c_host(c_host, oscillator_dir, "me", 3.0, 1e-4, VR["x"], VR["v"],
                                env=me_env(oscillator_dir)).stdout)
    expected = model_exchange_euler(oscillator_dir, 3.0, 1e-4, [VR["x"], VR["v"]])
    np.testing.assert_allclose(rows, expected, rtol=0, atol=1e-12)
    # explicit Euler at h = 1e-4 over three impacts: first-order accurate, about 1e-2 m here
    x, _, _ = solution(rows[:, 0])
    assert np.max(np.abs(rows[:, 1] - x)) < 3e-2


def test_c_host_errors_do_not_crash(c_host, oscillator_dir):
    out = run_c_host(c_host, oscillator_dir, "error")
    assert "getReal_before_init=3" in out.stdout and "doStep_negative=3" in out.stdout
    assert "alive" in out.stdout
    assert "must not be called in state 'instantiated'" in out.stderr


def test_c_host_missing_python_library_is_a_clear_error(c_host, oscillator_dir):
    md = fmpy.read_model_description(str(oscillator_dir))
    out = subprocess.run([str(c_host), str(oscillator_dir), "Oscillator", md.guid, "cs", "0.1", "0.01", "0"],
                         capture_output=True, text=True, env=clean_env(DELTAFMI_LIBPYTHON="/nonexistent/libpython.so"))
    assert out.returncode == 4 and out.stdout == ""
    logged, host_line = out.stderr.splitlines()  # one logger message, then the host's own line
    assert host_line == "fmi2Instantiate failed"
    assert "the Python library /nonexistent/libpython.so (DELTAFMI_LIBPYTHON) does not exist" in logged
    assert "DELTAFMI_PYTHON " in logged and "deltafmi build oscillator.py --portable" in logged


@pytest.mark.parametrize("step", [1e-4, 0.5])
def test_time_event_on_a_communication_point(oscillator, step):
    """The force step at 2.5 s falls on a step end (up to round-off): no CVODE 'too close'."""
    result = fmpy.simulate_fmu(str(oscillator), fmi_type="CoSimulation", relative_tolerance=1e-10,
                               output_interval=step, output=["x", "v", "force_on"])
    x, v, _ = solution(result["time"])
    assert np.max(np.abs(result["x"] - x)) < 1e-6
    assert result["force_on"][-1]


def test_getters_after_new_states_are_fresh(oscillator_dir):
    """Outputs read without derivatives (the loader then skips them) and derivatives read later
    both reflect the states last set."""
    md = fmpy.read_model_description(str(oscillator_dir))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Model(guid=md.guid, unzipDirectory=str(oscillator_dir), modelIdentifier="Oscillator")
    start_model_exchange(fmu)
    k, m, c = 39.47841760435743, 1.0, 0.2
    for x, v in [(0.3, -1.0), (-0.2, 2.0)]:
        fmu.setContinuousStates(as_pointer(np.array([x, v])), 2)
        assert fmu.getReal([vr["energy"]])[0] == pytest.approx(0.5 * m * v * v + 0.5 * k * x * x, rel=1e-15)
        assert fmu.getReal([vr["der(v)"], vr["der(x)"]]) == pytest.approx([(-k * x - c * v) / m, v], rel=1e-15)
    fmu.terminate()
    fmu.freeInstance()


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_a_massless_oscillator_is_refused_at_initialization(tmp_path, interface):
    # m = 0 passes the declared min (inclusive) but divides the force: initialization names it
    # instead of the first derivative raising ZeroDivisionError (Python) or returning inf (C).
    scenario = tmp_path / "massless.yaml"
    scenario.write_text("experiment: {start: 0.0, stop: 0.01, step: 1.0e-3}\n"
                        "components:\n  osc: {source: deltafmi.models:Oscillator, interface: %s,"
                        " parameters: {m: 0.0, F: 0.0}}\n" % interface)
    with pytest.raises(deltafmi.DeltaFmiError, match=r"m must be > 0 \(the mass divides the force\), got 0\.0"):
        deltafmi.simulate(scenario)
