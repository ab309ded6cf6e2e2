"""Diagnostics and exceptions shared by deltafmi's commands (scenarios, runs, studies, plots).

A :class:`Diagnostic` is one finding about an input file (a scenario or a study), located at
``file:line``. Errors abort with :class:`ScenarioError` (exit code 2: bad input), other wrong input
with :class:`BadInput` (2); failures while simulating raise :class:`SimulationError` (exit code 1).
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import IO, Any, Iterable, Optional

import click


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


class ScenarioError(click.ClickException):
    """The scenario (or an FMU it names) is invalid; carries every error found. Exit code 2."""

    exit_code = 2

    def __init__(self, diagnostics: Iterable[Diagnostic]) -> None:
        self.diagnostics = [d for d in diagnostics if d.severity == "error"]
        first = str(self.diagnostics[0]) if self.diagnostics else "invalid scenario"
        more = len(self.diagnostics) - 1
        super().__init__(first + (f" (and {more} more error{'s' * (more > 1)})" if more > 0 else ""))


class BadInput(click.ClickException):
    """Wrong input outside a scenario file: an option value, a signal name, a result file. Exit code 2."""

    exit_code = 2


class SimulationError(click.ClickException):
    """A run failed after it started (an FMU returned an error, the solver failed). Exit code 1."""

    exit_code = 1


class Interrupted(click.ClickException):
    """A run stopped by Ctrl-C (SIGINT) or SIGTERM; the message says when and what is on disk.
    Exit code 128 + the signal number (130 for Ctrl-C), the shell's convention."""

    def __init__(self, message: str, signum: int) -> None:
        super().__init__(message)
        self.exit_code = 128 + signum  # type: ignore[misc]  # click's is a class variable

    def show(self, file: Optional[IO[Any]] = None) -> None:
        """The message alone: an interruption is not an error."""
        click.echo(self.format_message(), file=file, err=file is None)


def did_you_mean(word: str, candidates: Iterable[str], n: int = 3) -> str:
    """`` (did you mean 'x'?)`` for the closest candidates to ``word``, or ``""`` when none is close."""
    matches = difflib.get_close_matches(word, list(candidates), n=n, cutoff=0.6)
    if not matches:
        return ""
    return " (did you mean " + " or ".join(f"'{m}'" for m in matches) + "?)"
