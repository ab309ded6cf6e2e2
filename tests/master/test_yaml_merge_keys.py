"""YAML merge keys (``<<: *a``, ``<<: [*a, *b]``) in a scenario read as YAML 1.1 defines them:
the data equal PyYAML's own SafeLoader's (an independent reader of the same document), explicit
keys winning over merged ones, an earlier merged mapping over a later one; a merged value keeps
the line where it is written. ``<<`` on something else than mappings is a one-line error."""
from __future__ import annotations

import pytest
import yaml

from deltafmi.errors import ScenarioError
from deltafmi.master.scenario.schema_check import load_mapping
from deltafmi.master.scenario.yaml_lines import YamlSyntaxError, load_yaml

TEXT = """\
base: &base {e: 0.8, F: 0.0}
extra: &extra {F: 2.0, h: 1.5}
components:
  one:
    parameters: {<<: *base, e: 0.5}
  two:
    parameters:
      <<: [*base, *extra]
      h: 3.0
"""


def test_merge_keys_read_as_pyyaml_reads_them():
    data, lines = load_yaml(TEXT)
    assert data == yaml.safe_load(TEXT)
    parameters = {name: c["parameters"] for name, c in data["components"].items()}
    assert parameters["one"] == {"e": 0.5, "F": 0.0}
    assert parameters["two"] == {"e": 0.8, "F": 0.0, "h": 3.0}  # *base before *extra: base's F
    assert lines.line(("components", "one", "parameters", "e")) == 5  # written here
    assert lines.line(("components", "one", "parameters", "F")) == 1  # merged from the anchor


@pytest.mark.parametrize("merge, message", [("<<: 3", "'<<' merges a mapping"),
                                            ("<<: [*a, 3]", "'<<' merges a mapping"),
                                            ("<<: *a, <<: *a", "duplicate key '<<'")])
def test_a_bad_merge_is_a_one_line_error_at_its_line(merge, message):
    text = f"a: &a {{x: 1}}\nb: {{{merge}}}\n"
    with pytest.raises(YamlSyntaxError, match=message) as caught:
        load_yaml(text)
    assert caught.value.line == 2
    with pytest.raises(ScenarioError, match=message):
        load_mapping(text, "s.yaml", "scenario")
