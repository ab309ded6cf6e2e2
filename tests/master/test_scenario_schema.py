"""Scenario files that fail before any FMU is opened: YAML syntax, schema, numbers.

Every error must name the file, the line and the wrong thing, suggest the right spelling where
there is one, and exit with code 2.
"""
from __future__ import annotations

import json
import textwrap
from pathlib import Path

import jsonschema
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.scenario.spec import load_scenario, schema

GOOD = """\
experiment: {start: 0.0, stop: 1.0, step: 1e-3}
master:
  algorithm: jacobi
components:
  osc: {fmu: osc.fmu}
"""


def validate(tmp_path: Path, text: str):
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(text))
    return str(path), CliRunner().invoke(main, ["validate", str(path)])


def expect_error(result, where: str, *fragments: str) -> None:
    assert result.exit_code == 2, result.output
    lines = [l for l in result.output.splitlines() if l.removeprefix("Error: ").startswith(where + ": error")]
    assert lines, f"no error at {where} in:\n{result.output}"
    assert any(all(f in l for f in fragments) for l in lines), result.output
    assert "Error: " not in result.output  # each error once, as file:line: error: message


def test_schema_is_valid_json_schema_and_shipped_in_package():
    jsonschema.Draft202012Validator.check_schema(schema())
    shipped = Path(__file__).parents[2] / "deltafmi" / "master" / "scenario" / "scenario.schema.json"
    assert json.loads(shipped.read_text()) == schema()


def test_good_scenario_parses(tmp_path):
    (tmp_path / "s.yaml").write_text(GOOD)
    scenario = load_scenario(tmp_path / "s.yaml")
    assert scenario.experiment.step == 1e-3  # YAML 1.1 alone would read '1e-3' as a string
    assert scenario.master.algorithm == "jacobi"
    assert scenario.components[0].name == "osc" and scenario.components[0].line == 5
    assert scenario.result.file == Path("s.csv")


def test_unknown_top_level_key_suggests_spelling(tmp_path):
    path, result = validate(tmp_path, GOOD + "conections: []\n")
    expect_error(result, f"{path}:6", "unknown key 'conections'", "did you mean 'connections'")


def test_unknown_nested_key_and_missing_required(tmp_path):
    path, result = validate(tmp_path, """\
        experiment:
          start: 0
          stpo: 1
          step: 0.01
        components:
          osc: {fmu: osc.fmu}
        """)
    expect_error(result, f"{path}:3", "unknown key 'stpo' in experiment", "did you mean 'stop'")
    expect_error(result, f"{path}:2", "experiment", "'stop' is a required property")


def test_enum_value_suggests_spelling(tmp_path):
    path, result = validate(tmp_path, GOOD.replace("algorithm: jacobi", "algorithm: gauss-seidle"))
    expect_error(result, f"{path}:3", "master.algorithm", "'gauss-seidle' is not allowed",
                 "did you mean 'gauss-seidel'")


def test_interface_enum_lists_choices(tmp_path):
    path, result = validate(tmp_path, GOOD.replace("{fmu: osc.fmu}", "{fmu: osc.fmu, interface: XX}"))
    expect_error(result, f"{path}:5", "components.osc.interface", "one of ME, CS")


def test_component_needs_fmu_or_source(tmp_path):
    path, result = validate(tmp_path, GOOD.replace("{fmu: osc.fmu}", "{fmu: osc.fmu, source: osc.py}"))
    expect_error(result, f"{path}:5", "component 'osc' needs exactly one of 'fmu'")
    path, result = validate(tmp_path, GOOD.replace("{fmu: osc.fmu}", "{interface: ME}"))
    expect_error(result, f"{path}:5", "component 'osc' needs exactly one of 'fmu'")


def test_wrong_type_is_located(tmp_path):
    path, result = validate(tmp_path, GOOD.replace("step: 1e-3", "step: fast"))
    expect_error(result, f"{path}:1", "experiment.step", "'fast' is not of type 'number'")


def test_stop_before_start(tmp_path):
    path, result = validate(tmp_path, GOOD.replace("stop: 1.0", "stop: -1.0"))
    expect_error(result, f"{path}:1", "experiment.stop (-1.0) must be greater than start (0.0)")


def test_connection_reference_needs_component_dot_variable(tmp_path):
    path, result = validate(tmp_path, GOOD + "connections:\n  - from: osc\n    to: osc.F\n")
    expect_error(result, f"{path}:7", "connections[0].from", "'osc' is not a 'component.variable' reference")


def test_bad_component_name(tmp_path):
    path, result = validate(tmp_path, GOOD.replace("osc: {fmu", "2osc: {fmu"))
    expect_error(result, f"{path}:5", "component name '2osc' must be an identifier")


def test_yaml_syntax_error_has_line(tmp_path):
    path, result = validate(tmp_path, GOOD + "connections: [\n  - from: a\n")
    assert result.exit_code == 2
    assert f"{path}:" in result.output and "YAML syntax error" in result.output


def test_a_key_without_its_colon_is_pointed_at(tmp_path):
    """YAML reads `stop 1.0` as text running on into the next key and fails only there: the
    message names the line that lacks its ':'."""
    path, result = validate(tmp_path, "experiment:\n  stop 1.0\n  step: 0.01\n")
    expect_error(result, f"{path}:3", "YAML syntax error: mapping values are not allowed here "
                                      "(is the ':' missing on line 2, 'stop 1.0'?)")


def test_duplicate_key_is_an_error(tmp_path):
    path, result = validate(tmp_path, GOOD + "  osc: {fmu: other.fmu}\n")
    expect_error(result, f"{path}:6", "duplicate key 'osc'")


def test_missing_scenario_file(tmp_path):
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "nope.yaml")])
    assert result.exit_code == 2
    assert "nope.yaml: error: cannot read scenario" in result.output


@pytest.mark.parametrize("text", ["[]", "just a string", ""])
def test_scenario_must_be_a_mapping(tmp_path, text):
    path, result = validate(tmp_path, text)
    assert result.exit_code == 2
    assert "a scenario must be a YAML mapping" in result.output
