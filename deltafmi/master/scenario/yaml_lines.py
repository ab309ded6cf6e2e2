"""Load YAML and remember the line of every value, so diagnostics can say ``file:line``.

:func:`load_yaml` returns plain Python data plus a :class:`LineMap` from key paths such as
``("connections", 2, "from")`` to 1-based line numbers.
"""
from __future__ import annotations

import re
from typing import Any, Dict, List, Optional, Tuple

import yaml

from .line_map import LineMap, Path, YamlSyntaxError

__all__ = ["LineMap", "YamlSyntaxError", "load_yaml"]

#: values a document may expand to: YAML aliases (``*a`` repeats what ``&a`` names) let a few
#: lines stand for billions of values ("billion laughs"), which no scenario or study needs
MAX_VALUES = 200_000


class _Loader(yaml.SafeLoader):
    """SafeLoader that also reads ``1e-3`` as a float (YAML 1.1 insists on ``1.0e-3``)."""


#: the same loader on libyaml, when PyYAML has it: it composes a document several times faster
_FastLoader = type("_FastLoader", (getattr(yaml, "CSafeLoader", _Loader),), {"__doc__": _Loader.__doc__})

for _loader in {_Loader, _FastLoader}:
    _loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
        list("-+0123456789"),
    )


def _missing_colon(lines: list, line: int) -> str:
    """A hint when the key line above ``line`` (1-based) lacks its ':': YAML reads it as text
    running on into ``line`` and notices only there."""
    previous = next((n for n in range(line - 1, 0, -1) if lines[n - 1].strip() and
                     not lines[n - 1].lstrip().startswith("#")), None)
    if previous is None or ":" in lines[previous - 1]:
        return ""
    return f" (is the ':' missing on line {previous}, '{lines[previous - 1].strip()}'?)"


def load_yaml(text: str) -> Tuple[Any, LineMap]:
    """Parse ``text``; return its data and the :class:`LineMap`. Raises :class:`YamlSyntaxError`."""
    try:
        node = yaml.compose(text, Loader=_FastLoader)
    except yaml.YAMLError:  # said as the Python parser says it (its messages and marks are the ones documented)
        node = None
    try:
        node = node if node is not None else yaml.compose(text, Loader=_Loader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        hint = (" (inside {...} or [...], quote references that contain brackets: 'plant.y[1:3]')"
                if "'['" in str(exc.problem) or "']'" in str(exc.problem) else "")
        if line is not None and "mapping values are not allowed" in str(exc.problem):
            hint = _missing_colon(text.splitlines(), line) or hint
        raise YamlSyntaxError(f"YAML syntax error: {exc.problem or exc}{hint}", line) from None
    except yaml.reader.ReaderError as exc:  # UTF-8, yet characters YAML never holds (NUL, most controls)
        line = text.count("\n", 0, exc.position) + 1
        code = exc.character if isinstance(exc.character, int) else ord(exc.character)
        raise YamlSyntaxError(f"not text: character #x{code:04x} is not allowed in YAML; a scenario or study is a "
                              "YAML file", line) from None
    lines = LineMap()
    if node is None:
        return None, lines
    try:
        return _build(node, (), lines, [MAX_VALUES]), lines
    except RecursionError:
        raise YamlSyntaxError("YAML nested too deeply to be a scenario or a study", None) from None
    except _TooMany as exc:
        if _written_values(node) > MAX_VALUES:  # a long file, no alias needed
            raise YamlSyntaxError(f"the YAML holds more than {MAX_VALUES:,} values: not a scenario or a study",
                                  exc.line) from None
        raise YamlSyntaxError(f"the YAML expands to more than {MAX_VALUES:,} values (aliases such as *a repeat "
                              "what &a names, again and again): not a scenario or a study", exc.line) from None


class _TooMany(Exception):
    def __init__(self, line: int) -> None:
        super().__init__(line)
        self.line = line


def _written_values(root: yaml.Node) -> int:
    """How many values the document writes out, as :func:`_build` counts them (keys not): its
    distinct value nodes (an alias is the node it names)."""
    seen, todo = {id(root)}, [root]
    while todo:
        node = todo.pop()
        children = [v for _, v in node.value] if isinstance(node, yaml.MappingNode) else \
            node.value if isinstance(node, yaml.SequenceNode) else []
        for child in children:
            if id(child) not in seen:
                seen.add(id(child))
                todo.append(child)
    return len(seen)


def _build(node: yaml.Node, path: Path, lines: LineMap, left: List[int]) -> Any:
    left[0] -= 1
    if left[0] < 0:
        raise _TooMany(node.start_mark.line + 1)
    lines.value_lines[path] = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        out: Dict[Any, Any] = {}
        pairs = [(k, v) for k, v in node.value if k.tag != _MERGE]
        merges = [(k, v) for k, v in node.value if k.tag == _MERGE]
        if len(merges) > 1:
            raise YamlSyntaxError("duplicate key '<<' (merge several mappings as <<: [*a, *b])",
                                  merges[1][0].start_mark.line + 1)
        merged = _merged_pairs([v for _, v in merges])
        explicit = {_scalar(k) for k, _ in pairs}
        for key_node, value_node in merged:  # merged first, as PyYAML orders them; explicit keys win
            key = _scalar(key_node)
            if key not in out and key not in explicit:
                lines.key_lines[path + (key,)] = key_node.start_mark.line + 1
                out[key] = _build(value_node, path + (key,), lines, left)
        for key_node, value_node in pairs:
            key = _scalar(key_node)
            if key in out:
                raise YamlSyntaxError(f"duplicate key '{key}'", key_node.start_mark.line + 1)
            lines.key_lines[path + (key,)] = key_node.start_mark.line + 1
            out[key] = _build(value_node, path + (key,), lines, left)
        return out
    if isinstance(node, yaml.SequenceNode):
        items: List[Any] = []
        for i, item in enumerate(node.value):
            items.append(_build(item, path + (i,), lines, left))
        return items
    return _scalar(node)


_MERGE = "tag:yaml.org,2002:merge"


def _merged_pairs(sources: List[yaml.Node]) -> List[Tuple[yaml.Node, yaml.Node]]:
    """The (key, value) nodes a mapping's merge keys (``<<: *a`` or ``<<: [*a, *b]``) bring in,
    the earlier source's first (YAML's merge key type: an earlier mapping's key wins)."""
    pairs: List[Tuple[yaml.Node, yaml.Node]] = []
    for source in sources:
        for mapping in source.value if isinstance(source, yaml.SequenceNode) else [source]:
            if not isinstance(mapping, yaml.MappingNode):
                raise YamlSyntaxError("'<<' merges a mapping or a list of mappings (<<: *name, <<: [*a, *b])",
                                      mapping.start_mark.line + 1)
            pairs += [(k, v) for k, v in mapping.value if k.tag != _MERGE]
            pairs += _merged_pairs([v for k, v in mapping.value if k.tag == _MERGE])
    return pairs


def _scalar(node: yaml.Node) -> Any:
    if not isinstance(node, yaml.ScalarNode):
        raise YamlSyntaxError("mapping keys must be plain scalars", node.start_mark.line + 1)
    return _construct(node)


def _construct(node: yaml.ScalarNode) -> Any:
    # a constructor alone: a whole loader per scalar (reader, scanner, parser) cost most of reading a scenario
    return yaml.constructor.SafeConstructor().construct_object(node, deep=True)
