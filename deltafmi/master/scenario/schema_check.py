"""Reading a YAML document (scenario or study file) as a mapping, and its JSON Schema violations
as diagnostics at their file and line, with did-you-mean suggestions."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Optional, Tuple

from deltafmi.errors import Diagnostic, ScenarioError, did_you_mean
from deltafmi.toolchain import cache_dir

from .line_map import LineMap, YamlSyntaxError
from .parsed_documents import plain, recall, remember

if TYPE_CHECKING:
    import jsonschema

__all__ = ["dotted", "load_mapping", "read_document", "schema_diagnostics"]

#: a document's own wording for some errors: None to fall back to the generic one
Special = Callable[["jsonschema.ValidationError", LineMap, str], Optional[List[Diagnostic]]]


def read_document(path: Path, document: str) -> str:
    """The text of ``path``; :class:`ScenarioError` naming the file if it cannot be read."""
    if path.suffix.lower() == ".py":  # YAML would read it and fail at a line of Python
        raise ScenarioError([Diagnostic(str(path), None, f"not a {document}: a Python file (a component's source: "
                                                         f"build it with `deltafmi build {path}`, or name it as "
                                                         "`source:` of a component in a scenario)")])
    try:
        return path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError([Diagnostic(str(path), None, f"cannot read {document}: {exc.strerror}")]) from None
    except UnicodeDecodeError as exc:
        raise ScenarioError([Diagnostic(str(path), None, f"not a {document}: not text (byte {exc.start} is not "
                                                         "UTF-8); a scenario or study is a YAML file")]) from None


def load_mapping(text: str, file: str, document: str) -> Tuple[Dict[str, Any], LineMap]:
    """``text`` parsed as a YAML mapping with its line map; :class:`ScenarioError` at the line of a
    syntax error, or if the top level is not a mapping. A text parsed before comes from the
    parsed-document cache (:mod:`.parsed_documents`), without the YAML parser."""
    cached = recall(text)
    if cached is not None:
        data, lines = cached
    else:
        from .yaml_lines import load_yaml  # here: a document parsed before needs no YAML
        try:
            data, lines = load_yaml(text)
        except YamlSyntaxError as exc:
            raise ScenarioError([Diagnostic(file, exc.line, str(exc))])
        remember(text, data, lines)
    if not isinstance(data, dict):
        raise ScenarioError([Diagnostic(file, lines.line(()), f"a {document} must be a YAML mapping")])
    return data, lines


def schema_diagnostics(data: Any, lines: LineMap, file: str, schema: Dict[str, Any], document: str,
                       special: Optional[Special] = None) -> List[Diagnostic]:
    """Every violation of ``schema`` in ``data`` (read from ``file``), one diagnostic each, sorted
    by line; ``document`` names the whole ("scenario") in messages about its top level.

    A document found valid is remembered in the cache by a hash of its data and the schema:
    found again, it is not validated again (importing and running jsonschema costs more than
    the rest of reading a scenario)."""
    valid = _valid_mark(data, schema)
    if valid is not None and valid.exists():
        return []
    import jsonschema  # here: a document already found valid never needs it

    validator = jsonschema.Draft202012Validator(schema)
    found: List[Diagnostic] = []
    for error in sorted(validator.iter_errors(data), key=lambda e: list(map(str, e.absolute_path))):
        own = special(error, lines, file) if special else None
        found.extend(own if own is not None else _describe(error, lines, file, document))
    if not found and valid is not None:
        try:
            valid.parent.mkdir(parents=True, exist_ok=True)
            valid.touch()
        except OSError:
            pass  # a read-only cache: validated every time
    return sorted(set(found), key=lambda d: (d.line or 0, d.message))


def _valid_mark(data: Any, schema: Dict[str, Any]) -> Optional[Path]:
    """The cache file that says ``data`` is valid under ``schema`` (None: data JSON cannot hold,
    never remembered: a date, a key that is not a string, which JSON would write as another value)."""
    if not plain(data):
        return None
    try:
        text = json.dumps([schema, data], sort_keys=True, allow_nan=True)
    except (TypeError, ValueError):
        return None
    return cache_dir() / "valid-documents" / hashlib.sha256(text.encode()).hexdigest()[:32]


def _describe(error: "jsonschema.ValidationError", lines: LineMap, file: str, document: str) -> List[Diagnostic]:
    path = tuple(error.absolute_path)
    where = dotted(path) or f"the {document}"
    if error.validator == "additionalProperties" and isinstance(error.instance, dict):
        allowed = list(error.schema.get("properties", {}))
        extra = [k for k in error.instance if k not in allowed]
        return [Diagnostic(file, lines.key_line(path + (k,)),
                           f"unknown key '{k}' in {where}{did_you_mean(str(k), allowed)}") for k in extra]
    if error.validator == "enum":
        choices = [str(c) for c in error.validator_value]
        hint = did_you_mean(str(error.instance), choices) or f" (one of {', '.join(choices)})"
        return [Diagnostic(file, lines.line(path), f"{where}: '{error.instance}' is not allowed{hint}")]
    return [Diagnostic(file, lines.line(path), f"{where}: {error.message}")]


def dotted(path: Tuple[Any, ...]) -> str:
    """``('components', 'plant', 'solver')`` -> ``components.plant.solver``, list indices in brackets."""
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text
