"""``deltafmi run`` options: --set (parameters, start values, vectors), --step, --tolerance, --stop,
``run Model.fmu`` on its own, and the NaN check (--allow-nan, ``master.allow_nan``).

Results are checked against closed forms: the Oscillator's (tests/oscillator_analytic.py) with
another stiffness or start, the Lags' x_i = x0_i exp(-k_i t), and the Fragile component's
y = sqrt(t_nan - t) (tests/components/fragile), NaN after t_nan.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns
from deltafmi.master.scenario.overrides import Text, with_overrides
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.errors import SimulationError
from oscillator_analytic import P, solution

COMPONENTS = Path(__file__).parents[1] / "components"


@pytest.fixture(scope="module")
def fmus(build_fmu_from_src, tmp_path_factory) -> dict:
    from deltafmi.builder import build_fmu
    folder = tmp_path_factory.mktemp("run_options")
    return {"osc": build_fmu_from_src("oscillator.py"),
            "lags": build_fmu(COMPONENTS / "first" / "model.py", folder / "Lags.fmu"),
            "fragile": build_fmu(COMPONENTS / "fragile" / "model.py", folder / "Fragile.fmu"),
            "gain": build_fmu(COMPONENTS / "gain" / "model.py", folder / "Gain.fmu")}


@pytest.fixture()
def oscillator(fmus, tmp_path) -> Path:
    path = tmp_path / "osc.yaml"
    path.write_text(f"experiment: {{stop: 2.0, step: 0.01}}\n"
                    f"components:\n  osc: {{fmu: {fmus['osc']}, interface: CS, solver: {{rtol: 1.0e-10}}}}\n"
                    "outputs: [osc.x, osc.v]\n")
    return path


def run(*args: str):
    return CliRunner().invoke(main, ["run", *map(str, args)])


def test_set_a_parameter_changes_the_physics(oscillator, tmp_path):
    out = tmp_path / "k.csv"
    result = run(oscillator, "--set", "osc.k=100", "-o", out, "-q")
    assert result.exit_code == 0, result.output
    c = columns(out)
    x, v, impacts = solution(c["time"], p={**P, "k": 100.0})
    assert len(impacts) >= 1  # the stiffer spring still reaches the wall
    assert np.max(np.abs(c["osc.x"] - x)) < 1e-6
    # and the default stiffness gives another motion: the option made the difference
    default, _, _ = solution(c["time"])
    assert np.max(np.abs(c["osc.x"] - default)) > 0.5


def test_set_start_values_of_states(oscillator, tmp_path):
    out = tmp_path / "x0.csv"
    result = run(oscillator, "--set", "osc.x=0.3", "--set", "osc.v=-0.5", "-o", out, "-q")
    assert result.exit_code == 0, result.output
    c = columns(out)
    x, v, _ = solution(c["time"], x0=0.3, v0=-0.5)
    assert c["osc.x"][0] == 0.3 and c["osc.v"][0] == -0.5
    assert np.max(np.abs(c["osc.x"] - x)) < 1e-6 and np.max(np.abs(c["osc.v"] - v)) < 1e-5


def test_set_vectors_elements_and_strings(fmus, tmp_path):
    scenario = tmp_path / "lags.yaml"
    scenario.write_text(f"experiment: {{stop: 1.0, step: 0.05}}\n"
                        f"components:\n  lags: {{fmu: {fmus['lags']}, parameters: {{x: [1.0, 1.0, 1.0]}}}}\n"
                        "outputs: ['lags.y[1:3]']\n")
    out = tmp_path / "lags.csv"
    # a comma list for the whole vector, one element after the YAML's value, a String, an Integer
    result = run(scenario, "--set", "lags.k=0.5,1,3", "--set", "lags.x[2]=2", "--set", "lags.label=other",
                 "--set", "lags.n_steps=7", "--set", "lags.gain=1.5", "-o", out, "-q")
    assert result.exit_code == 0, result.output
    c = columns(out)
    t = c["time"]
    for i, (k, x0) in enumerate([(0.5, 1.0), (1.0, 2.0), (3.0, 1.0)], start=1):
        np.testing.assert_allclose(c[f"lags.y[{i}]"], 1.5 * x0 * np.exp(-k * t), rtol=1e-6)
    # the scenario with the values from the Python API gives the same start values
    system = resolve_system(with_overrides(load_scenario(scenario), {"lags.k": np.array([0.5, 1, 3]),
                                                                     "lags.x[2]": 2, "lags.label": "other"}))
    start = {port.ref: value for port, value in system.components[0].start_values}
    assert start["lags.k[3]"] == 3 and start["lags.x[2]"] == 2 and start["lags.label"] == "other"


def test_step_changes_the_sample_times(oscillator, tmp_path):
    out = tmp_path / "step.csv"
    result = run(oscillator, "--step", "0.05", "--stop", "1", "-o", out, "-q")
    assert result.exit_code == 0, result.output
    t = columns(out)["time"]
    np.testing.assert_allclose(t, np.arange(21) * 0.05, atol=1e-12)


def test_tolerance_reaches_the_me_solver(fmus, tmp_path):
    scenario = tmp_path / "me.yaml"
    scenario.write_text(f"experiment: {{stop: 2.0, step: 0.01}}\n"
                        f"components:\n  osc: {{fmu: {fmus['osc']}, interface: ME}}\n"
                        "outputs: [osc.x]\n")
    errors = {}
    for tolerance in ("1e-3", "1e-9"):
        out = tmp_path / f"tol{tolerance}.csv"
        result = run(scenario, "--tolerance", tolerance, "-o", out, "-q")
        assert result.exit_code == 0, result.output
        c = columns(out)
        regular = np.diff(c["time"], append=np.inf) > 0  # leave out the rows before an event
        x, _, _ = solution(c["time"][regular])
        errors[tolerance] = np.max(np.abs(c["osc.x"][regular] - x))
    # CVODE's error follows the relative tolerance: looser by 1e6, larger by far
    assert errors["1e-9"] < 1e-6 < errors["1e-3"]
    assert errors["1e-3"] > 100 * errors["1e-9"]


def test_the_scenarios_tolerance_is_each_components_unless_it_gives_its_own(fmus, tmp_path):
    """experiment.tolerance (the name --tolerance and simulate(tolerance=) use) sets the rtol of
    the components without solver.rtol; a component's own rtol wins; --tolerance sets them all."""
    def error(scenario: Path, *args: str) -> dict:
        out = tmp_path / "tol.csv"
        result = run(scenario, "-o", out, "-q", *args)
        assert result.exit_code == 0, result.output
        c = columns(out)
        regular = np.diff(c["time"], append=np.inf) > 0  # leave out the rows before an event
        x, _, _ = solution(c["time"][regular])
        return {name: np.max(np.abs(c[f"{name}.x"][regular] - x)) for name in ("a", "b")}

    scenario = tmp_path / "two.yaml"
    scenario.write_text(f"experiment: {{stop: 0.3, step: 0.01, tolerance: 1.0e-3}}\n"  # before the first bounce
                        f"components:\n  a: {{fmu: {fmus['osc']}, interface: ME}}\n"
                        f"  b: {{fmu: {fmus['osc']}, interface: ME, solver: {{rtol: 1.0e-9}}}}\n"
                        "outputs: [a.x, b.x]\n")
    loose_a = error(scenario)
    assert loose_a["b"] < 1e-6 < loose_a["a"]  # b keeps its own rtol, a takes the scenario's
    tight = error(scenario, "--tolerance", "1e-9")
    assert max(tight.values()) < 1e-6
    assert load_scenario(scenario).experiment.tolerance == 1e-3


@pytest.mark.parametrize("args, message", [
    (["--step", "0"], "communication step 0 s: must be greater than 0"),
    (["--step", "-0.01"], "communication step -0.01 s: must be greater than 0"),
    (["--step", "nan"], "communication step nan: must be a finite number (--step)"),
    (["--step", "inf"], "communication step inf: must be a finite number (--step)"),
    (["--stop", "inf"], "stop time inf: must be a finite number (--stop)"),
    (["--stop", "nan"], "stop time nan: must be a finite number (--stop)"),
    (["--stop", "-1"], "stop time -1 s is not after the start time 0 s"),
    (["--tolerance", "0"], "tolerance 0: a relative tolerance must be greater than 0"),
    (["--tolerance", "nan"], "tolerance nan: must be a finite number (--tolerance)"),
    (["--set", "osc.kk=3"], "--set osc.kk: error: component 'osc': parameter 'kk': no such variable in the FMU "
                            "(did you mean 'k'?)"),
    (["--set", "osc.K=3"], "no such variable in the FMU (did you mean 'k'?)"),
    (["--set", "oscc.k=3"], "--set oscc.k: the scenario has no component 'oscc' (did you mean 'osc'?)"),
    (["--set", "osc.k"], "--set 'osc.k': expected NAME=VALUE"),
    (["--set", "osc.k=stiff"], "--set osc.k: error: component 'osc': parameter 'k': 'k' is Real: 'stiff' is not a number"),
    (["--set", "osc.impacts=1.5"], "'impacts' is an output (calculated) and cannot be set"),
    (["--set", "osc.energy=1"], "'energy' is an output (calculated) and cannot be set"),
    # the modelDescription's min/max (e: 0 ... 1) and finite Reals
    (["--set", "osc.e=1.5"], "--set osc.e: error: component 'osc': parameter 'e': 'e' = 1.5 is outside its "
                             "declared range [0, 1]"),
    (["--set", "osc.m=-1"], "'m' = -1.0 is outside its declared range [0, inf]"),
    (["--set", "osc.k=inf"], "--set osc.k: error: component 'osc': parameter 'k': 'k' = inf is not a finite number"),
    (["--set", "osc.k=-inf"], "'k' = -inf is not a finite number"),
    (["--record", "osc.zz"], "--record osc.zz: error: output pattern 'osc.zz' matches no variable"),
    (["--record", "Oscillator.*"], "--record Oscillator.*: error: output pattern 'Oscillator.*' matches no variable "
                                   "(no component 'Oscillator': the components are osc)"),
])
def test_bad_run_options_exit_2_with_one_line(oscillator, tmp_path, args, message):
    result = run(oscillator, *args, "-o", tmp_path / "bad.csv")
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert "Traceback" not in result.output and len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "bad.csv").exists()


def test_bad_values_in_two_component_scenarios(fmus, tmp_path):
    scenario = tmp_path / "two.yaml"
    scenario.write_text(f"experiment: {{stop: 0.1, step: 0.01}}\n"
                        f"components:\n  lags: {{fmu: {fmus['lags']}}}\n  gain: {{fmu: {fmus['gain']}}}\n")
    result = run(scenario, "--set", "k=1")
    assert result.exit_code == 2 and "--set k: expected component.variable (components: lags, gain)" in result.output
    result = run(scenario, "--set", "lags.n_steps=2.5")
    assert result.exit_code == 2 and "'n_steps' is Integer: '2.5' is not an integer" in result.output
    result = run(scenario, "--set", "lags.k=1,2")
    assert result.exit_code == 2 and "has 3 element(s) but 2 value(s) were given" in result.output


def test_run_one_fmu_on_its_default_experiment(fmus, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = run(fmus["osc"])
    assert result.exit_code == 0, result.output
    assert "warning" not in result.output  # its unconnected input F stays at its start value, silently
    c = columns(tmp_path / f"{fmus['osc'].stem}.csv")  # named after the file, in the current folder
    t = c["time"]
    # the default experiment: 0 ... 4 s in steps of 1 ms; every output recorded
    assert len(t) == 4001 and t[-1] == pytest.approx(4.0) and t[1] == pytest.approx(1e-3)
    assert set(c) == {"time", "Oscillator.energy", "Oscillator.impacts", "Oscillator.force_on"}
    x, v, impacts = solution(t)
    energy = 0.5 * P["m"] * v ** 2 + 0.5 * P["k"] * x ** 2
    np.testing.assert_allclose(c["Oscillator.energy"], energy, rtol=1e-4, atol=1e-5)
    assert c["Oscillator.impacts"][-1] == len(impacts)
    # the options work the same on an FMU: a bare name sets a variable of its only component
    result = run(fmus["osc"], "--set", "x=0.3", "--set", "Oscillator.k=100", "--stop", "1", "--step", "0.1",
                 "-o", tmp_path / "o.csv", "-q")
    assert result.exit_code == 0, result.output
    c = columns(tmp_path / "o.csv")
    x, v, _ = solution(c["time"], x0=0.3, p={**P, "k": 100.0})
    assert len(c["time"]) == 11
    np.testing.assert_allclose(c["Oscillator.energy"], 0.5 * v ** 2 + 50 * x ** 2, rtol=1e-4, atol=1e-6)


def test_run_a_file_that_is_no_fmu(tmp_path):
    junk = tmp_path / "junk.fmu"
    junk.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe not an fmu")
    result = run(junk)
    assert result.exit_code == 2 and "junk.fmu: error: cannot read it as an FMU" in result.output
    assert "Traceback" not in result.output
    result = run(tmp_path / "missing.fmu")
    assert result.exit_code == 2 and "missing.fmu: error: no such FMU file" in result.output


def _nan_scenario(fmus, tmp_path, extra: str = "") -> Path:
    # gain is listed first but steps after fragile (it reads fragile.y): the NaN is fragile's
    scenario = tmp_path / "nan.yaml"
    scenario.write_text(f"experiment: {{stop: 1.0, step: 0.01}}\n{extra}"
                        f"components:\n  gain: {{fmu: {fmus['gain']}, parameters: {{a: 2.0}}}}\n"
                        f"  fragile: {{fmu: {fmus['fragile']}}}\n"
                        "connections:\n  - {from: fragile.y, to: gain.u}\n"
                        "outputs: [gain.y, fragile.*]\n")
    return scenario


def _check_rows_up_to_the_nan(path: Path) -> None:
    c = columns(path)
    t = c["time"]
    assert t[-1] == pytest.approx(0.42) and len(t) == 43  # 0, 0.01, ..., 0.42: the first NaN row last
    assert np.isnan(c["fragile.y"][-1]) and np.isnan(c["gain.y"][-1])
    np.testing.assert_allclose(c["fragile.y"][:-1], np.sqrt(0.415 - t[:-1]), rtol=1e-12)
    np.testing.assert_allclose(c["gain.y"][:-1], 2 * np.sqrt(0.415 - t[:-1]), rtol=1e-12)


def test_nan_stops_the_run_naming_variable_and_time(fmus, tmp_path):
    scenario = _nan_scenario(fmus, tmp_path)
    out = tmp_path / "nan.csv"
    result = run(scenario, "-o", out, "-q")
    assert result.exit_code == 1, result.output
    assert ("fragile.y is NaN at t = 0.42 s (and 1 other variable); the rows up to there are in "
            f"{tmp_path / 'nan.failed.csv'}") in result.output.replace("\n", "")
    assert "Traceback" not in result.output
    _check_rows_up_to_the_nan(tmp_path / "nan.failed.csv")  # a failed run's rows, under a name that says so
    # the same without the master's C loop (rows recorded one by one)
    python = tmp_path / "python.csv"
    with pytest.raises(SimulationError, match=r"fragile.y is NaN at t = 0.42 s"):
        Master(resolve_system(load_scenario(scenario)), result=python, native=False).run()
    _check_rows_up_to_the_nan(tmp_path / "python.failed.csv")


def test_allow_nan_records_to_the_end(fmus, tmp_path):
    out = tmp_path / "allowed.csv"
    result = run(_nan_scenario(fmus, tmp_path), "--allow-nan", "-o", out, "-q")
    assert result.exit_code == 0, result.output
    c = columns(out)
    assert c["time"][-1] == pytest.approx(1.0) and np.isnan(c["fragile.y"][-1]) and c["fragile.ok"][-1] == 1.0
    # the same from the scenario file
    result = run(_nan_scenario(fmus, tmp_path, "master: {allow_nan: true}\n"), "-o", out, "-q")
    assert result.exit_code == 0, result.output
    assert columns(out)["time"][-1] == pytest.approx(1.0)


def test_allow_nan_travels_through_an_ssp_archive(fmus, tmp_path):
    archive = tmp_path / "nan.ssp"
    result = CliRunner().invoke(main, ["export-ssp", str(_nan_scenario(fmus, tmp_path, "master: {allow_nan: true}\n")),
                                       "-o", str(archive)])
    assert result.exit_code == 0, result.output
    result = run(archive, "-o", tmp_path / "ssp.csv", "-q")
    assert result.exit_code == 0, result.output
    assert columns(tmp_path / "ssp.csv")["time"][-1] == pytest.approx(1.0)


def test_booleans_from_text_and_from_python(build_fmu_from_src, tmp_path):
    scenario = tmp_path / "ball.yaml"
    scenario.write_text(f"experiment: {{stop: 0.1, step: 0.01}}\n"
                        f"components:\n  ball: {{fmu: {build_fmu_from_src('bouncing_ball.py')}}}\n")
    loaded = load_scenario(scenario)
    for value, expected in [(Text("true"), True), (Text("0"), False), (True, True)]:
        system = resolve_system(with_overrides(loaded, {"ball.linFlag": value}))
        assert dict((p.ref, v) for p, v in system.components[0].start_values)["ball.linFlag"] is expected
    result = run(scenario, "--set", "ball.linFlag=maybe")
    assert result.exit_code == 2 and "'linFlag' is Boolean: 'maybe' is not a Boolean (true or false)" in result.output
    result = CliRunner().invoke(main, ["run", str(scenario), "--set", "ball.linFlag=1", "-q", "-o",
                                       str(tmp_path / "b.csv")])
    assert result.exit_code == 0, result.output


def test_record_replaces_what_a_run_records(fmus, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    # an FMU on its own records its outputs; --record names the variables instead (its state x, v)
    result = run(fmus["osc"], "--record", "Oscillator.x", "--record", "Oscillator.v", "--stop", "1", "-q")
    assert result.exit_code == 0, result.output
    c = columns(tmp_path / f"{fmus['osc'].stem}.csv")
    assert list(c) == ["time", "Oscillator.x", "Oscillator.v"]
    x, v, _ = solution(c["time"])
    assert np.max(np.abs(c["Oscillator.x"] - x)) < 1e-5 and np.max(np.abs(c["Oscillator.v"] - v)) < 1e-4


def test_a_run_failing_before_its_first_row_leaves_the_earlier_result_as_it_was(tmp_path, monkeypatch):
    """The flagship's controller refuses pole = 0 in its initialize (inside initialization mode):
    the earlier result file stays, the reason prints once, no FMU is terminated out of order."""
    monkeypatch.chdir(tmp_path)
    good = run("delta_tracking", "--stop", "0.01", "-q", "-o", "r.csv")
    assert good.exit_code == 0, good.output
    before = (tmp_path / "r.csv").read_bytes()
    assert len(before.splitlines()) == 12  # header and 11 rows
    failed = run("delta_tracking", "--stop", "0.01", "--set", "controller.pole=0", "-o", "r.csv")
    assert failed.exit_code == 1, failed.output
    assert (tmp_path / "r.csv").read_bytes() == before
    assert failed.output.strip().splitlines()[-1].endswith("(no rows computed; r.csv left as it was)")
    assert failed.output.count("pole must be > 0") == 1, failed.output
    assert "fmi2Terminate" not in failed.output and "Traceback" not in failed.output
    # without an earlier file none is made
    failed = run("delta_tracking", "--stop", "0.01", "--set", "controller.pole=0", "-o", "new.csv")
    assert failed.exit_code == 1 and not (tmp_path / "new.csv").exists()


def test_nan_of_a_connected_variable_not_recorded_stops_the_c_loop_as_the_python_loop(fmus, tmp_path):
    # fragile.y feeds gain.u; only fragile.ok (always finite) is recorded
    scenario = tmp_path / "hidden.yaml"
    scenario.write_text(_nan_scenario(fmus, tmp_path).read_text().replace("outputs: [gain.y, fragile.*]",
                                                                           "outputs: [fragile.ok]"))
    for native in (True, False):
        with pytest.raises(SimulationError, match=r"^fragile.y is NaN at t = \S+ s; the rows up to") as raised:
            Master(resolve_system(load_scenario(scenario)), result=tmp_path / f"{native}.csv", native=native).run()
        # the Python loop stops at the first NaN step; the C loop at the end of its batch (64 steps)
        t = float(str(raised.value).split("t = ")[1].split()[0])
        assert (t == pytest.approx(0.42)) if not native else (0.42 - 1e-9 <= t <= 0.42 + 0.64 + 1e-9)
