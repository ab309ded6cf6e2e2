"""The error of a component source that cannot be built (its own module: the source finders and
the Modelica reader both raise it)."""
from __future__ import annotations

from deltafmi.errors import DeltaFmiError

__all__ = ["ComponentSourceError"]


class ComponentSourceError(DeltaFmiError, ValueError):
    """The source does not define a usable Component subclass, or the name finds none."""

    exit_code = 2  # bad input
