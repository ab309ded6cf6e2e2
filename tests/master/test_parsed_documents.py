"""A YAML document read again unchanged comes from the parsed-document cache: the same data (floats
bit for bit) and the same lines, without the YAML parser; a document with values JSON cannot
hold (a date, a key that is not a string) is parsed every time."""
from __future__ import annotations

import math
import struct

import pytest

from deltafmi.master.scenario import yaml_lines
from deltafmi.master.scenario.schema_check import load_mapping

TEXT = """\
# a comment, then values JSON holds
experiment: {start: 0.0, stop: 0.1, step: 1e-3}
gains: [0.1, 3.3333333333333335, -0.0, .inf, 1e-310, 12345678901234567890]
flags: {up: true, down: false, none: null}
name: "plant %s"
nested:
  - {a: 1, b: [x, y]}
  - 2.5
"""


def bits(value):
    """Floats compared by their bits (NaN and -0.0 included), everything else as it is."""
    if isinstance(value, float):
        return ("float", struct.pack("<d", value))
    if isinstance(value, dict):
        return {k: bits(v) for k, v in value.items()}
    if isinstance(value, list):
        return [bits(v) for v in value]
    return (type(value).__name__, value)


def refuse(*_args, **_kwargs):
    raise AssertionError("parsed again")


def test_a_document_read_again_comes_back_equal_without_the_parser(monkeypatch):
    text = TEXT % "0.4731"  # a text of its own: no other test has parsed it
    data, lines = load_mapping(text, "s.yaml", "scenario")
    monkeypatch.setattr(yaml_lines, "load_yaml", refuse)
    again, lines_again = load_mapping(text, "s.yaml", "scenario")
    assert bits(again) == bits(data)
    assert math.copysign(1.0, again["gains"][2]) == -1.0 and again["gains"][3] == math.inf
    assert again["gains"][5] == 12345678901234567890 and isinstance(again["gains"][5], int)
    assert lines_again.value_lines == lines.value_lines and lines_again.key_lines == lines.key_lines
    assert lines_again.line(("nested", 0, "b", 1)) == 7 and lines_again.key_line(("flags", "none")) == 4
    with pytest.raises(AssertionError, match="parsed again"):  # another text: parsed
        load_mapping(TEXT % "0.4732", "s.yaml", "scenario")


@pytest.mark.parametrize("value", ["2026-12-07", "{1: one}"])
def test_values_json_cannot_hold_are_parsed_every_time(monkeypatch, value):
    text = f"when: {value}\nwhy: not JSON 0.4733\n"
    data, _ = load_mapping(text, "s.yaml", "scenario")
    assert not isinstance(data["when"], (str, float))  # a date, a mapping keyed by an int
    monkeypatch.setattr(yaml_lines, "load_yaml", refuse)
    with pytest.raises(AssertionError, match="parsed again"):
        load_mapping(text, "s.yaml", "scenario")
