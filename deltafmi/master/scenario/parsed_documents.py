"""YAML documents parsed before, read back from the cache without importing or running a YAML parser.

A scenario or study read again unchanged (every ``deltafmi run`` of the same file) parses to the
same data and line map. Both are kept in the per-user cache as JSON, under a hash of the text and
of the parser's stamps (the files of :mod:`.yaml_lines` and PyYAML's, by size and modification
time: an edited or upgraded parser reads every document anew). Only documents made of JSON's own
types are kept (every mapping keyed by strings, no dates or binary): they come back equal, floats
bit for bit. A cache that cannot be written or read is skipped: the document is parsed.
"""
from __future__ import annotations

import hashlib
import importlib.util
import json
import os
from pathlib import Path
from typing import Any, Optional, Tuple

from deltafmi.files import keep_in_cache
from deltafmi.toolchain import cache_dir

from .line_map import LineMap

__all__ = ["plain", "recall", "remember"]

_HERE = Path(__file__).resolve().parent
_STAMP: list = []  # the parser's stamp, taken once per process


def plain(value: Any) -> bool:
    """Whether ``value`` is made of JSON's types only, every mapping keyed by strings."""
    if isinstance(value, dict):
        return all(isinstance(k, str) and plain(v) for k, v in value.items())
    if isinstance(value, list):
        return all(map(plain, value))
    return value is None or isinstance(value, (str, int, float, bool))


def recall(text: str) -> Optional[Tuple[Any, LineMap]]:
    """The data and line map ``text`` parsed to when it was last remembered (None: not kept)."""
    path = _entry(text)
    if path is None:
        return None
    try:
        with open(path, encoding="utf-8") as f:
            stored = json.load(f)
        lines = LineMap()
        lines.value_lines = {tuple(p): line for p, line in stored["values"]}
        lines.key_lines = {tuple(p): line for p, line in stored["keys"]}
        return stored["data"], lines
    except (OSError, ValueError, KeyError, TypeError):
        return None


def remember(text: str, data: Any, lines: LineMap) -> None:
    """Keep what ``text`` parsed to, when it is made of JSON's types."""
    path = _entry(text)
    if path is None or not plain(data):
        return
    stored = {"data": data, "values": [[list(p), line] for p, line in lines.value_lines.items()],
              "keys": [[list(p), line] for p, line in lines.key_lines.items()]}
    try:
        data = json.dumps(stored, allow_nan=True).encode("utf-8")
    except ValueError:  # a circular structure: parsed every time
        return
    keep_in_cache(path, data)  # a read-only cache: parsed every time


def _entry(text: str) -> Optional[Path]:
    stamp = _parser_stamp()
    if stamp is None:
        return None
    key = hashlib.sha256(f"{stamp}\0{text}".encode("utf-8", "surrogatepass")).hexdigest()[:32]
    return cache_dir() / "parsed-documents" / f"{key}.json"


def _parser_stamp() -> Optional[str]:
    """Size and modification time of the files that decide what a text parses to (None: unknown)."""
    if not _STAMP:
        try:
            spec = importlib.util.find_spec("yaml")
            files = [_HERE / "yaml_lines.py", _HERE / "line_map.py", Path(__file__)]
            if spec is not None and spec.origin:
                files.append(Path(spec.origin))
            stats = [os.stat(f) for f in files]
            _STAMP.append(";".join(f"{f}:{s.st_size}:{s.st_mtime_ns}" for f, s in zip(files, stats)))
        except (OSError, ImportError, ValueError):
            _STAMP.append(None)
    return _STAMP[0]
