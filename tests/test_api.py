"""deltafmi.simulate and its Result: real FMUs, results against closed forms, units from the
modelDescription, overrides seen in the physics, pandas, result files, errors and FMU messages."""
from __future__ import annotations

import logging
import sys
from pathlib import Path

import numpy as np
import pytest

import deltafmi
from deltafmi.errors import BadInput, ScenarioError, SimulationError

sys.path.insert(0, str(Path(__file__).parent))
from oscillator_analytic import P, solution  # noqa: E402

SCENARIO = """\
experiment: {start: 0.0, stop: 4.0, step: 1.0e-3}
components:
  osc: {source: 'deltafmi.models:Oscillator', interface: ME, solver: {rtol: 1.0e-10}}
outputs: ['osc.x', 'osc.v', 'osc.energy', 'osc.impacts', 'osc.force_on']
"""


@pytest.fixture(scope="module")
def scenario(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("api") / "osc.yaml"
    path.write_text(SCENARIO)
    return path


@pytest.fixture(scope="module")
def oscillator(scenario):
    return deltafmi.simulate(scenario)


def test_result_follows_the_closed_form(oscillator):
    r = oscillator
    x, v, impacts = solution(r.time)
    # rtol 1e-10 with events located to CVODE's root tolerance: far below 1e-6 m (the swing is 1 m)
    assert np.max(np.abs(r["osc.x"] - x)) < 1e-6
    at_event = np.isin(r.time, r.time[1:][np.diff(r.time) == 0])  # v jumps there: before and after
    assert np.max(np.abs(r["osc.v"] - v)[~at_event]) < 1e-5
    assert len(impacts) == 3 and int(r["osc.impacts"][-1]) == 3
    # an event is two rows at one time; the force step comes on at t_step
    assert np.count_nonzero(np.diff(r.time) == 0) == r.summary.events
    assert not r["osc.force_on"][r.time < P["t_step"]].any() and r["osc.force_on"][-1]
    energy = 0.5 * P["m"] * r["osc.v"] ** 2 + 0.5 * P["k"] * r["osc.x"] ** 2
    assert r["osc.energy"] == pytest.approx(energy, rel=1e-12, abs=1e-12)


def test_result_columns_keep_types_and_units(oscillator):
    r = oscillator
    assert r.names == ["osc.x", "osc.v", "osc.energy", "osc.impacts", "osc.force_on"]
    assert r["osc.impacts"].dtype == np.int64 and r["osc.force_on"].dtype == bool
    assert r.units == {"time": "s", "osc.x": "m", "osc.v": "m/s", "osc.energy": "J", "osc.impacts": "",
                       "osc.force_on": ""}
    assert r.match("osc.?") == ["osc.x", "osc.v"]
    assert len(r) == len(r.time) == r.summary.rows
    with pytest.raises(KeyError, match="no variable 'osc.xx' in the result .did you mean 'osc.x'"):
        r["osc.xx"]


def test_array_names_and_units_of_the_flagship():
    r = deltafmi.simulate("delta_tracking", stop=0.2)
    assert r.units["plant.z[3]"] == "m" and r.units["controller.u[1]"] == "N.m"
    assert r.unit("plant.z") == "m"
    z = r["plant.z"]
    assert z.shape == (len(r.time), 3)
    assert np.array_equal(z[:, 2], r["plant.z[3]"])
    assert float(r.time[-1]) == pytest.approx(0.2)


def test_parameters_and_start_values_change_the_physics(scenario):
    p = dict(P, k=4 * P["k"], wall=-0.3)
    r = deltafmi.simulate(scenario, parameters={"osc.k": p["k"], "osc.wall": p["wall"]},
                          start_values={"osc.x": 0.6}, stop=2.0)
    x, _, impacts = solution(r.time, x0=0.6, p=p)
    assert np.max(np.abs(r["osc.x"] - x)) < 1e-6
    assert int(r["osc.impacts"][-1]) == len(impacts) > 0
    assert float(r.time[-1]) == 2.0


def test_step_and_tolerance_reach_the_run(scenario):
    r = deltafmi.simulate(scenario, stop=1.0, step=0.01, tolerance=1e-4)
    grid = r.time[np.concatenate([[True], np.diff(r.time) > 0])]
    assert r.summary.steps == 100
    # a loose tolerance is seen in the physics: further from the closed form than rtol 1e-10 is
    loose = np.max(np.abs(r["osc.x"] - solution(r.time)[0]))
    assert 1e-6 < loose < 1e-2
    assert len(grid) >= 101


def test_to_pandas(oscillator):
    df = oscillator.to_pandas()
    assert df.index.name == "time" and list(df.columns) == oscillator.names
    assert np.array_equal(df.index.to_numpy(), oscillator.time)
    assert np.array_equal(df["osc.x"].to_numpy(), oscillator["osc.x"])
    assert df.attrs["units"]["osc.v"] == "m/s"


def test_to_pandas_without_pandas_says_what_to_install(oscillator, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match=r"needs pandas, which is not installed: pip install pandas"):
        oscillator.to_pandas()


def test_output_file_and_save_carry_the_same_rows_and_units(scenario, tmp_path):
    r = deltafmi.simulate(scenario, stop=1.0, output=tmp_path / "run.parquet")
    written = deltafmi.read_result(tmp_path / "run.parquet")
    assert written.names == r.names and written.units == r.units
    for name in ["time", *r.names]:
        assert np.array_equal(written[name], r[name])
    r.save(tmp_path / "again.mat")
    matlab = deltafmi.read_result(tmp_path / "again.mat")
    assert matlab.units["osc.v"] == "m/s" and np.array_equal(matlab["osc.x"], r["osc.x"])
    r.save(tmp_path / "again.csv")
    text = deltafmi.read_result(tmp_path / "again.csv")
    assert text.units == r.units and np.array_equal(text["osc.x"], r["osc.x"])  # from again.csv.units.json
    assert str(r.summary.result) == str(tmp_path / "run.parquet")


def test_simulate_one_fmu_on_its_default_experiment(caplog):
    from deltafmi.builder.packager import build_cached
    from deltafmi.builder.sources import find_component

    source = find_component("Oscillator")
    caplog.set_level(logging.DEBUG, logger="deltafmi")
    fmu = build_cached(source.path, class_name=source.class_name)
    r = deltafmi.simulate(fmu)
    assert float(r.time[-1]) == 4.0  # the Oscillator's default experiment
    assert {"Oscillator.energy", "Oscillator.impacts"} <= set(r.names)
    assert int(r["Oscillator.impacts"][-1]) == 3
    # its input F has nothing to connect to: no warning (as `deltafmi run X.fmu`)
    assert not [rec for rec in caplog.records if rec.name == "deltafmi.scenario"]
    # record= replaces the recorded variables (the YAML's outputs:, run --record)
    r = deltafmi.simulate(fmu, stop=1.0, record=["Oscillator.x", "Oscillator.energy"])
    assert r.names == ["Oscillator.x", "Oscillator.energy"] and r.units["Oscillator.x"] == "m"
    assert np.max(np.abs(r["Oscillator.x"] - solution(r.time)[0])) < 1e-5


def test_a_loaded_scenario_is_taken_as_it_is(scenario):
    loaded = deltafmi.load_scenario(scenario)
    r = deltafmi.simulate(loaded, stop=0.5)
    assert float(r.time[-1]) == 0.5 and loaded.experiment.stop == 4.0


@pytest.mark.parametrize("call, error, message", [
    (dict(parameters={"osc.kk": 1.0}), ScenarioError,
     "parameters osc.kk: error: component 'osc': parameter 'kk': no such variable in the FMU (did you mean 'k'?)"),
    (dict(parameters={"osc.k": "stiff"}), ScenarioError, "type mismatch: 'k' is Real"),
    (dict(parameters={"osc.k": 1.0}, start_values={"osc.k": 2.0}), BadInput,
     "osc.k: given in both parameters and start_values; give each name once"),
    (dict(parameters=[("osc.k", 1.0)]), BadInput, "parameters must be a mapping of names to values"),
    (dict(step=0), BadInput, "communication step 0 s: must be greater than 0"),
    (dict(stop=float("inf")), BadInput, "stop time inf: must be a finite number"),
    (dict(output="r.txt"), BadInput, "result file 'r.txt': unknown format '.txt'"),
    (dict(algorithm="foo"), BadInput, "algorithm 'foo': use 'gauss-seidel' or 'jacobi'"),
    (dict(algorithm="jacobbi"), BadInput, "(did you mean 'jacobi'?)"),
    # one variable under two names (a one-component scenario takes a bare name) is given twice
    (dict(parameters={"osc.k": 1.0}, start_values={"k": 2.0}), BadInput,
     "k: given in both parameters and start_values; give each name once"),
    (dict(parameters={"osc.e": 2.0}), ScenarioError, "'e' = 2.0 is outside its declared range [0, 1]"),
    (dict(start_values={"osc.x": float("nan")}), ScenarioError, "'x' = nan is not a finite number"),
    (dict(record=["osc.zz"]), ScenarioError, "record 'osc.zz': error: output pattern 'osc.zz' matches no variable"),
])
def test_bad_input_is_an_exception_with_the_cli_message(scenario, call, error, message, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(error) as raised:
        deltafmi.simulate(scenario, **call)
    assert message in str(raised.value)
    assert "--" not in str(raised.value)  # the API's messages name no command-line option
    assert not (tmp_path / "r.txt").exists()


def test_unknown_scenario_name():
    with pytest.raises(BadInput, match="no example called 'delta_trackin' .did you mean 'delta_tracking'"):
        deltafmi.simulate("delta_trackin")
    with pytest.raises(BadInput, match="takes a scenario name, a file or a Scenario, not int"):
        deltafmi.simulate(3)


def test_a_failed_run_keeps_its_rows_in_the_error(scenario):
    with pytest.raises(SimulationError) as raised:
        deltafmi.simulate(scenario, parameters={"osc.F_step": 1.0e308, "osc.t_step": 0.5})
    partial = raised.value.result
    assert "simulation failed at t = 0.5 s" in str(raised.value)
    assert str(raised.value).endswith("(results up to the failure in the error's .result)")
    assert float(partial.time[-1]) == pytest.approx(0.5)
    assert np.max(np.abs(partial["osc.x"] - solution(partial.time)[0])) < 1e-6


def test_fmu_messages_go_to_logging_once_each(scenario, caplog):
    caplog.set_level(logging.DEBUG, logger="deltafmi")
    deltafmi.simulate(scenario, stop=3.0, verbose=True)
    events = [rec for rec in caplog.records if rec.name == "deltafmi.fmu.osc" and "event at" in rec.getMessage()]
    # three impacts (each with its restart) and the force step at 2.5 s, plus the initial event
    assert len(events) >= 5
    assert all(rec.getMessage().startswith("event at t = ") for rec in events)
    assert any("t = 2.5" in rec.getMessage() for rec in events)
    warnings = [rec for rec in caplog.records if rec.name == "deltafmi.scenario"]
    assert all(rec.levelno == logging.WARNING for rec in warnings)


def test_quiet_without_verbose(scenario, caplog, capsys):
    caplog.set_level(logging.DEBUG, logger="deltafmi")
    deltafmi.simulate(scenario, stop=1.0)
    assert not [rec for rec in caplog.records if rec.name.startswith("deltafmi.fmu")]
    assert capsys.readouterr().out == ""


def test_on_message_gets_every_message_between_steps(scenario):
    said = []
    deltafmi.simulate(scenario, stop=1.0, verbose=True,
                      on_message=lambda component, status, category, text: said.append((component, category, text)))
    assert ("osc", "logEvents") in {(c, cat) for c, cat, _ in said}
    assert all(not text.startswith("deltafmi.fmu") for _, _, text in said)


def test_an_ssp_archive_runs_as_its_scenario(scenario, oscillator, tmp_path):
    system = deltafmi.resolve_system(deltafmi.load_scenario(scenario))
    archive = deltafmi.export_ssp(system, tmp_path / "osc.ssp")
    r = deltafmi.simulate(archive, stop=1.0)
    rows = oscillator.time <= 1.0
    assert r.names == oscillator.names and r.units == oscillator.units
    assert np.array_equal(r["osc.x"], oscillator["osc.x"][rows])


def test_every_error_simulate_and_build_raise_is_public(tmp_path):
    """docs/api.md names them; a user catches them from deltafmi."""
    from deltafmi.errors import Interrupted, ResultWriteError
    from deltafmi.toolchain import BuildError, NoCompilerError

    assert (deltafmi.ResultWriteError, deltafmi.Interrupted, deltafmi.BuildError) == \
        (ResultWriteError, Interrupted, BuildError) and issubclass(NoCompilerError, deltafmi.BuildError)
    with pytest.raises(deltafmi.ComponentSourceError, match="'DeltaRobott' is neither a file nor a packaged model"):
        deltafmi.build_fmu("DeltaRobott", tmp_path / "x.fmu")
    api = (Path(__file__).parent.parent / "docs" / "api.md").read_text()
    for name in ("DeltaFmiError", "ScenarioError", "BadInput", "SimulationError", "Interrupted", "ResultWriteError",
                 "ComponentSourceError", "BuildError"):
        assert f"`{name}`" in api, name


def test_save_and_read_round_trip_booleans_and_strings(tmp_path):
    """Booleans go to a CSV as 0/1, as a run writes them (a CSV with 'True' did not read back)."""
    r = deltafmi.Result({"time": np.array([0.0, 0.5, 1.0]), "a.on": np.array([True, False, True]),
                         "a.label": np.array(["x", "y,\"z\"", ""], dtype=object), "a.n": np.array([3, -1, 7])})
    for suffix in ("csv", "parquet", "mat"):
        again = deltafmi.read_result(r.save(tmp_path / f"r.{suffix}"))
        assert again.names == r.names, suffix
        assert list(again["a.on"]) == [1, 0, 1] and list(again["a.n"]) == [3, -1, 7], suffix
        assert list(again["a.label"]) == ["x", "y,\"z\"", ""] and list(again.time) == [0.0, 0.5, 1.0], suffix
    assert (tmp_path / "r.csv").read_text().splitlines()[1] == '0.0,1,"x",3'
