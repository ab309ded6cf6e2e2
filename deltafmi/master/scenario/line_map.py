"""The line of every value of a YAML document (:class:`LineMap`) and its syntax error, apart from
the parser (:mod:`.yaml_lines`): a document read from the parsed-document cache needs no YAML."""
from __future__ import annotations

from typing import Any, Dict, Optional, Tuple

from deltafmi.errors import DeltaFmiError

__all__ = ["LineMap", "Path", "YamlSyntaxError"]

Path = Tuple[Any, ...]


class LineMap:
    """Line numbers (1-based) of the values and keys of a YAML document, by key path."""

    def __init__(self) -> None:
        self.value_lines: Dict[Path, int] = {}
        self.key_lines: Dict[Path, int] = {}

    def line(self, path: Path) -> Optional[int]:
        """Line of the value at ``path``, or of its nearest ancestor that has one."""
        path = tuple(path)
        while True:
            if path in self.value_lines:
                return self.value_lines[path]
            if not path:
                return None
            path = path[:-1]

    def key_line(self, path: Path) -> Optional[int]:
        """Line of the mapping key that ends ``path`` (falls back to :meth:`line`)."""
        return self.key_lines.get(tuple(path)) or self.line(path)


class YamlSyntaxError(DeltaFmiError, ValueError):
    """The text is not YAML (or repeats a key); ``line`` is 1-based."""

    exit_code = 2  # bad input

    def __init__(self, message: str, line: Optional[int]) -> None:
        super().__init__(message)
        self.line = line
