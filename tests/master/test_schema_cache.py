"""A scenario found valid is remembered (by its data and the schema) and not validated again; an
invalid one is reported every time, at its line."""
from __future__ import annotations

import sys

import pytest

from deltafmi.errors import ScenarioError
from deltafmi.master.scenario.spec import parse_scenario

VALID = """\
experiment: {start: 0.0, stop: 0.5, step: 1.0e-3}
components:
  ball: {source: deltafmi.models:BouncingBall, parameters: {e: %s}}
outputs: [ball.h]
"""


def test_a_valid_scenario_is_validated_once(tmp_path, monkeypatch):
    text = VALID % "0.731"  # data of its own: no other test has validated it
    assert parse_scenario(text, tmp_path / "s.yaml").components[0].name == "ball"
    import jsonschema

    def refuse(*_args, **_kwargs):
        raise AssertionError("validated again")

    monkeypatch.setattr(jsonschema, "Draft202012Validator", refuse)
    assert parse_scenario(text, tmp_path / "t.yaml").components[0].name == "ball"
    with pytest.raises(AssertionError, match="validated again"):  # other data: validated
        parse_scenario(VALID % "0.732", tmp_path / "u.yaml")


def test_an_invalid_scenario_is_reported_every_time(tmp_path):
    text = (VALID % "0.5").replace("outputs", "outptus")
    for _ in range(2):
        with pytest.raises(ScenarioError) as raised:
            parse_scenario(text, tmp_path / "s.yaml")
        assert any(d.line == 4 and "outptus" in d.message for d in raised.value.diagnostics)


def test_yaml_errors_read_as_the_python_parser_says_them(tmp_path):
    with pytest.raises(ScenarioError) as raised:
        parse_scenario("experiment:\n  stop: 1\n  step 1e-3: x: y\n", tmp_path / "s.yaml")
    assert raised.value.diagnostics[0].line == 3
    assert "mapping values are not allowed" in raised.value.diagnostics[0].message
