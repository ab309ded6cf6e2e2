"""The root of deltafmi's errors, and the diagnostics and exceptions shared by its commands.

Every error deltafmi raises derives from :class:`DeltaFmiError`, so ``except DeltaFmiError`` catches
all of them. Each class carries the exit code the command line gives it (``exit_code``: 2 for bad
input, 1 for a failure, 128 + the signal for :class:`Interrupted`); the command line alone turns an
error into a message and that code (``deltafmi.apps.cli``), the library only raises.

A :class:`Diagnostic` is one finding about an input file (a scenario or a study), located at
``file:line``. Errors abort with :class:`ScenarioError` (exit code 2: bad input), other wrong input
with :class:`BadInput` (2); failures while simulating raise :class:`SimulationError` (exit code 1).

The base class lives in the FMU runtime (:mod:`deltafmi.runtime.errors`), the bottom layer, whose own
errors derive from it too; this module adds the rest and imports nothing else of deltafmi.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, List, Optional

from deltafmi.runtime.errors import DeltaFmiError

__all__ = ["BadInput", "DeltaFmiError", "Diagnostic", "FmuSourceError", "Interrupted", "ResultWriteError",
           "ScenarioError", "SimulationError", "did_you_mean", "file_hint"]


@dataclass(frozen=True)
class Diagnostic:
    """One problem found in a scenario: ``severity`` is ``"error"`` or ``"warning"``."""

    file: str
    line: Optional[int]
    message: str
    severity: str = "error"

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}" if self.line is not None else self.file
        return f"{where}: {self.severity}: {self.message}"


class ScenarioError(DeltaFmiError):
    """The scenario (or an FMU it names) is invalid; carries every error found. Exit code 2.

    The CLI shows every error, one per line, as ``file:line: error: message`` (the way compilers
    do) and nothing else: no ``Error:`` prefix, which would say "error" twice on one line.
    """

    exit_code = 2

    def __init__(self, diagnostics: Iterable[Diagnostic]) -> None:
        self.diagnostics = [d for d in diagnostics if d.severity == "error"]
        first = str(self.diagnostics[0]) if self.diagnostics else "invalid scenario"
        more = len(self.diagnostics) - 1
        super().__init__(first + (f" (and {more} more error{'s' * (more > 1)})" if more > 0 else ""))

    def lines(self) -> List[str]:
        """Every error, one per line (``file:line: error: message``)."""
        return [str(d) for d in self.diagnostics] or [f"error: {self.format_message()}"]


class BadInput(DeltaFmiError):
    """Wrong input outside a scenario file: an option value, a signal name, a result file. Exit code 2."""

    exit_code = 2


class SimulationError(DeltaFmiError):
    """A run failed after it started (an FMU returned an error, the solver failed). Exit code 1."""

    exit_code = 1


class ResultWriteError(DeltaFmiError):
    """The result file could not take more rows (a full disk, a quota, a file size limit). The
    rows already in it are complete; the message says how many and up to which time. Exit code 1."""

    exit_code = 1

    def __init__(self, path: Any, rows: int, time: Optional[float], error: OSError, whole_file: bool = False) -> None:
        """``whole_file``: the format cannot keep part of the rows (a .mat file, a Parquet file
        whose footer did not fit): the file was removed and ``rows`` is what was lost."""
        import errno

        reason = {errno.ENOSPC: "disk full", errno.EDQUOT: "disk quota exceeded",
                  errno.EFBIG: "file size limit reached"}.get(error.errno or 0, f"cannot write: {error.strerror or error}")
        until = f" (t = {time:.9g} s)" if time is not None else ""
        counted = f"{rows} row{'s' * (rows != 1)}{until}"
        if whole_file:
            message = f"{path}: {reason}: its {counted} did not fit and the file was removed"
        else:
            message = f"{path}: {reason} after {counted}; the rows written are complete"
        super().__init__(message)
        self.path, self.rows, self.time, self.error = path, rows, time, error


class Interrupted(DeltaFmiError):
    """A run stopped by Ctrl-C (SIGINT), SIGTERM or SIGHUP; the message says when and what is on
    disk. Exit code 128 + the signal number (130 for Ctrl-C), the shell's convention."""

    #: 128 + SIGINT; an instance carries its own signal's code
    exit_code = 130

    def __init__(self, message: str, signum: int) -> None:
        super().__init__(message)
        self.signum = signum
        self.exit_code = 128 + signum  # type: ignore[misc]  # the class's is the default

    def lines(self) -> List[str]:
        """The message alone: an interruption is not an error."""
        return [self.format_message()]


def did_you_mean(word: str, candidates: Iterable[str], n: int = 3) -> str:
    """`` (did you mean 'x'?)`` for the closest candidates to ``word``, or ``""`` when none is close."""
    candidates = list(candidates)
    same_letters = [c for c in candidates if c.lower() == word.lower() and c != word]  # kp -> kP
    matches = same_letters + [m for m in difflib.get_close_matches(word, candidates, n=n, cutoff=0.6)
                              if m not in same_letters]
    matches = matches[:n]
    if not matches:
        return ""
    return " (did you mean " + " or ".join(f"'{m}'" for m in matches) + "?)"


def file_hint(path: Path, glob: str) -> str:
    """`` (did you mean 'x'?)`` naming a file beside ``path`` (matching ``glob``) with a close name, or ``""``."""
    for folder in [path.parent.resolve(), *path.parent.resolve().parents]:
        if folder.is_dir() and folder.name == path.parent.name:
            return did_you_mean(path.name, [p.name for p in folder.glob(glob)])
    return ""


class FmuSourceError(DeltaFmiError):
    """A scenario component's ``source:`` cannot be made into an FMU (not found, not a component,
    its build failed); the message says which and why, without naming the component."""
