"""The root of every error deltafmi raises, here because the FMU runtime, the bottom layer, raises
errors of its own (a failing CVODE, a missing SUNDIALS) and imports nothing else of deltafmi.
Everything above takes it from :mod:`deltafmi.errors`."""
from __future__ import annotations

from typing import Any, ClassVar, List

__all__ = ["DeltaFmiError"]


class DeltaFmiError(Exception):
    """The base of every deltafmi error. ``message`` is the one-line text the command line shows
    (``str(error)`` is the same), ``exit_code`` the code it exits with (1: a failure)."""

    exit_code: ClassVar[int] = 1

    def __init__(self, message: Any = "") -> None:
        super().__init__(message)
        self.message = str(message)

    def __str__(self) -> str:
        return self.message

    def format_message(self) -> str:
        """The message the command line shows (after ``Error: ``)."""
        return self.message

    def lines(self) -> List[str]:
        """What the command line prints, one item a line (``Error: message`` unless overridden)."""
        return [f"Error: {self.format_message()}"]
