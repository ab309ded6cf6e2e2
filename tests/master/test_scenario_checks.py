"""Scenario errors found against the FMUs' modelDescriptions, through ``deltafmi validate``.

Each error must carry ``file:line``, the wrong thing and (where one exists) a suggestion, and the
command must exit with code 2. Unconnected inputs are warnings (exit code 0).
"""
from __future__ import annotations

import shutil
import textwrap
from pathlib import Path

import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.scenario.modelinfo import model_info
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario


@pytest.fixture(scope="module")
def fmu_dir(build_fmu_from_src, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("checks")
    shutil.copy(build_fmu_from_src("oscillator.py"), folder / "osc.fmu")
    shutil.copy(build_fmu_from_src("delta_robot.py"), folder / "robot.fmu")
    return folder


HEAD = """\
experiment: {stop: 1.0, step: 0.01}
components:
  a: {fmu: osc.fmu}
  b: {fmu: osc.fmu}
  robot: {fmu: robot.fmu, interface: ME}
connections:
"""
# line numbers: the first connection line below HEAD is line 7


def validate(fmu_dir: Path, text: str, name: str = "s.yaml"):
    path = fmu_dir / name
    path.write_text(textwrap.dedent(text))
    return str(path), CliRunner().invoke(main, ["validate", str(path)])


def expect_error(result, where: str, *fragments: str) -> None:
    assert result.exit_code == 2, result.output
    lines = [l.removeprefix("Error: ") for l in result.output.splitlines()]
    hits = [l for l in lines if l.startswith(where + ": error: ")]
    assert hits, f"no error at {where} in:\n{result.output}"
    assert any(all(f in l for f in fragments) for l in hits), result.output


def test_valid_scenario_passes_and_runs_fmpy_validation(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - {from: a.energy, to: b.F, factor: 0.01}\n")
    assert result.exit_code == 0, result.output
    assert f"{path}: OK" in result.output
    assert "stepping order (gauss-seidel): a -> b -> robot" in result.output


def test_unknown_component_suggests_name(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - {from: aa.energy, to: b.F}\n")
    expect_error(result, f"{path}:7", "'from: aa.energy'", "unknown component 'aa'", "did you mean 'a'")


def test_unknown_variable_suggests_name(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - from: a.enrgy\n    to: b.F\n")
    expect_error(result, f"{path}:7", "component 'a' has no variable 'enrgy'", "did you mean 'energy'")
    path, result = validate(fmu_dir, HEAD + "  - from: robot.z[1:3]\n    to: robot.uu[1:3]\n")
    expect_error(result, f"{path}:8", "'to: robot.uu[1:3]'", "has no variable 'uu'", "did you mean 'u'")


def test_array_range_out_of_bounds(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - from: robot.y[2:4]\n    to: robot.u\n")
    expect_error(result, f"{path}:7", "component 'robot' has no variable 'y[4]'")


def test_range_length_mismatch(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - {from: 'robot.y[1:3]', to: 'robot.u[1:2]', factor: 2.0}\n")
    expect_error(result, f"{path}:7", "3 source variable(s) but 2 target variable(s)")


def test_output_to_output(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - from: a.energy\n    to: b.energy\n")
    expect_error(result, f"{path}:8", "'to: b.energy' is an output (output -> output)")


def test_from_must_be_an_output(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - from: a.F\n    to: b.F\n")
    expect_error(result, f"{path}:7", "'from: a.F' is an input", "must start at an output")
    path, result = validate(fmu_dir, HEAD + "  - from: a.energy\n    to: b.k\n")
    expect_error(result, f"{path}:8", "'to: b.k' is a parameter", "must end at an input")


def test_type_mismatch(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - {from: a.impacts, to: b.F}\n")
    expect_error(result, f"{path}:7", "type mismatch: 'a.impacts' is Integer but 'b.F' is Real")


def test_unit_mismatch_unless_converted(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - {from: a.energy, to: b.F}\n")
    expect_error(result, f"{path}:7", "unit mismatch: 'a.energy' is in 'J' but 'b.F' expects 'N'",
                 "convert with factor/offset")
    path, result = validate(fmu_dir, HEAD + "  - {from: a.energy, to: b.F, factor: 0.5}\n")
    assert result.exit_code == 0, result.output


def test_input_driven_twice(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - {from: a.energy, to: b.F, factor: 0.1}\n"
                                            "  - {from: robot.energy, to: b.F, factor: 0.1}\n")
    expect_error(result, f"{path}:8", "input 'b.F' is driven twice: by 'a.energy' (line 7) and by 'robot.energy'")


def test_unconnected_inputs_are_warnings(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - {from: a.energy, to: b.F, factor: 0.5}\n")
    assert result.exit_code == 0, result.output
    warnings = [line for line in result.output.splitlines() if "warning" in line]
    assert warnings == [f"{path}: warning: input(s) not connected, kept at their start values: a.F, robot.u[1:3], "
                        "robot.f[1:3] (connect them, or give them a value under the component's parameters:)"]


def test_algebraic_loop_is_named_with_how_it_is_solved(fmu_dir):
    # the oscillator declares no direct_feedthrough, so its outputs depend on its input F
    path, result = validate(fmu_dir, HEAD + "  - {from: a.energy, to: b.F, factor: 0.01}\n"
                                            "  - {from: b.energy, to: a.F, factor: 0.01}\n")
    assert result.exit_code == 0, result.output
    assert ("algebraic loop a.energy -> b.F, b.energy -> a.F (a, b; line 7): solved at initialization and at "
            "every step, iterating on b.energy") in result.output


def test_feedback_without_feedthrough_is_no_loop(fmu_dir):
    # the robot's y depends on its states only: robot.y -> robot.u closes no algebraic loop
    assert model_info(str(fmu_dir / "robot.fmu")).feedthrough["y[1]"] == set()
    path, result = validate(fmu_dir, HEAD + "  - {from: robot.y, to: robot.u, factor: -100.0}\n")
    assert result.exit_code == 0, result.output


def test_parameter_errors(fmu_dir):
    path, result = validate(fmu_dir, """\
        experiment: {stop: 1.0, step: 0.01}
        components:
          a:
            fmu: osc.fmu
            parameters:
              kk: 3.0
              k: yes
              energy: 1.0
          robot:
            fmu: robot.fmu
            parameters: {z0: [0.0, 0.1]}
        """)
    expect_error(result, f"{path}:6", "parameter 'kk': no such variable", "did you mean 'k'")
    expect_error(result, f"{path}:7", "type mismatch: 'k' is Real but the value True is bool")
    expect_error(result, f"{path}:8", "'energy' is an output (calculated) and cannot be set")
    expect_error(result, f"{path}:11", "parameter 'z0': has 3 element(s) but 2 value(s)")


def test_output_pattern_matching_nothing(fmu_dir):
    path, result = validate(fmu_dir, HEAD + "  - {from: a.energy, to: b.F, factor: 0.5}\n"
                                            "outputs:\n  - robot.z[*]\n  - robot.zz[*]\n")
    expect_error(result, f"{path}:10", "output pattern 'robot.zz[*]' matches no variable", "did you mean")


def test_a_component_that_cannot_be_read_is_the_only_error_of_the_patterns_it_could_match(fmu_dir):
    """`*.energy` may name the missing component's variable: no 'matches no variable' besides."""
    path, result = validate(fmu_dir, HEAD.replace("a: {fmu: osc.fmu}", "a: {fmu: oscc.fmu}")
                            + "outputs:\n  - '*.energy'\n  - 'a*.x'\n  - b.zz\n")
    expect_error(result, f"{path}:3", "component 'a': FMU 'oscc.fmu' not found")
    expect_error(result, f"{path}:10", "output pattern 'b.zz' matches no variable")  # b is there: its error stays
    assert result.output.count("error:") == 2, result.output


def test_missing_fmu_suggests_file(fmu_dir):
    path, result = validate(fmu_dir, HEAD.replace("a: {fmu: osc.fmu}", "a: {fmu: oscc.fmu}"))
    expect_error(result, f"{path}:3", "component 'a': FMU 'oscc.fmu' not found", "did you mean 'osc.fmu'")


def test_missing_source(fmu_dir):
    path, result = validate(fmu_dir, HEAD.replace("a: {fmu: osc.fmu}", "a: {source: fmu_src/oscilator.py}"))
    expect_error(result, f"{path}:3", "component 'a': source 'fmu_src/oscilator.py' not found")


def test_source_is_built_on_demand_and_cached(tmp_path, monkeypatch):
    monkeypatch.setenv("DELTAFMI_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "project" / "scenarios"
    folder.mkdir(parents=True)
    shutil.copytree(Path(__file__).parents[2] / "fmu_src", tmp_path / "project" / "fmu_src")
    scenario = folder / "s.yaml"
    scenario.write_text("experiment: {stop: 1.0, step: 0.01}\n"
                        "components:\n  osc: {source: fmu_src/oscillator.py}\n")
    first = resolve_system(load_scenario(scenario)).components[0].fmu
    assert first.is_file() and str(first).startswith(str(tmp_path / "cache"))
    mtime = first.stat().st_mtime_ns
    assert resolve_system(load_scenario(scenario)).components[0].fmu == first
    assert first.stat().st_mtime_ns == mtime  # cached, not rebuilt
    source = tmp_path / "project" / "fmu_src" / "oscillator.py"
    source.write_text(source.read_text() + "\n# edited\n")
    assert resolve_system(load_scenario(scenario)).components[0].fmu != first
