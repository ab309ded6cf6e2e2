"""The error of a component source that cannot be built (its own module: the source finders and
the Modelica reader both raise it)."""
from __future__ import annotations

from deltafmi.errors import DeltaFmiError

__all__ = ["ComponentSourceError", "import_failure"]


class ComponentSourceError(DeltaFmiError, ValueError):
    """The source does not define a usable Component subclass, or the name finds none."""

    exit_code = 2  # bad input


def import_failure(exc: BaseException) -> str:
    """Why importing a source failed, in one line: ``file:line: message`` for a syntax error,
    else the exception's type and message."""
    if isinstance(exc, SyntaxError):
        where = f"{exc.filename}:{exc.lineno}: " if exc.filename and exc.lineno else ""
        return f"{where}{exc.msg}"
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
