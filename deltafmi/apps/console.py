"""What the commands show on the terminal besides their results: the library's progress messages.

The library logs them (``deltafmi.build``: "building X FMU ..."); a command shows them on stderr,
one line each, and ``-q`` keeps them back. Python users see them through their own logging
set-up (``logging.basicConfig(level=logging.INFO)``).
"""
from __future__ import annotations

import contextlib
import logging
import re
import warnings
from pathlib import Path
from typing import Dict, Iterator, Optional

import click

__all__ = ["folder_output", "output_folders", "progress_shown", "show_progress"]

#: the loggers whose INFO messages a command shows
PROGRESS_LOGGERS = ("deltafmi.build",)
#: a number, and the unit of time after it (one kind of message says "10.1 ms" or "9069.7 us")
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?: ?(?:[mun\u00b5]?s)\b)?")


class _Stderr(logging.Handler):
    """Each record as one line on the current stderr (click's, so that tests capturing it see it)."""

    def emit(self, record: logging.LogRecord) -> None:
        click.echo(self.format(record), err=True)


def show_progress() -> None:
    """Show the library's progress messages on stderr (once per process), and its warnings as
    one ``Warning: ...`` line each (not Python's file, line and source of the warn() call)."""
    warnings.formatwarning = _one_line_warning
    for name in PROGRESS_LOGGERS:
        logger = logging.getLogger(name)
        if not any(isinstance(h, _Stderr) for h in logger.handlers):
            logger.addHandler(_Stderr())
            logger.setLevel(logging.INFO)
            logger.propagate = False


@contextlib.contextmanager
def progress_shown(show: bool) -> Iterator[None]:
    """Within the block, the progress messages show (``show``) or not (``-q``)."""
    loggers = [logging.getLogger(name) for name in PROGRESS_LOGGERS]
    before = [logger.disabled for logger in loggers]
    for logger in loggers:
        logger.disabled = not show
    try:
        yield
    finally:
        for logger, disabled in zip(loggers, before):
            logger.disabled = disabled


def _one_line_warning(message: Warning | str, category: type, filename: str, lineno: int,
                      line: Optional[str] = None) -> str:
    return f"Warning: {message}\n"


class RepeatedWarnings:
    """A ``warn(message)`` for a run that shows the first :attr:`keep` warnings of each kind as
    ``warning: ...`` lines on stderr and counts the rest; :meth:`close` says how many were held
    back. Two warnings are of one kind when they differ only in their numbers (``fell behind real
    time at t = 1.2 s`` and ``... at t = 3.4 s``)."""

    def __init__(self, keep: int = 3) -> None:
        self.keep = keep
        self._seen: Dict[str, int] = {}
        self._first: Dict[str, str] = {}

    @staticmethod
    def kind(message: str) -> str:
        """The message with every number (and a unit of time after it) replaced by ``#``."""
        return _NUMBER.sub("#", message)

    def __call__(self, message: str) -> None:
        kind = self.kind(message)
        count = self._seen[kind] = self._seen.get(kind, 0) + 1
        self._first.setdefault(kind, message)
        if count <= self.keep:
            click.echo(f"warning: {message}", err=True)
        elif count == self.keep + 1:
            click.echo("warning: more warnings like this one are counted, not shown", err=True)

    def close(self) -> None:
        """One line for each kind of warning with more than :attr:`keep`: how many were not shown."""
        for kind, count in self._seen.items():
            if count > self.keep:
                first = self._first[kind]
                short = first if len(first) <= 80 else first[:77] + "..."
                click.echo(f"warning: {count - self.keep} more warning{'s' * (count - self.keep > 1)} like "
                           f"'{short}' not shown ({count} in all)", err=True)
        self._seen.clear()


def _note_made(ctx: click.Context, path: Path, folder: bool) -> None:
    """Register, on the running command's context, a note for when it ends: the folder of
    ``path`` (``path`` itself when ``folder``) did not exist and the command made it."""
    holder = path if folder else path.parent
    missing = next((p for p in reversed([holder, *holder.parents]) if not p.exists()), None)
    if missing is None:
        return

    def note() -> None:
        if holder.is_dir():
            made = f"the folder {holder}" if folder else f"the folder {holder} for {path}"
            click.echo(f"made {made} (it did not exist)", err=True)
    ctx.call_on_close(note)


def output_folders(ctx: click.Context, param: click.Parameter, value: Optional[str]) -> Optional[str]:
    """click callback of an output file option: every command makes the missing folders of its
    output's path (as ``mkdir -p``) and says so in one line on stderr when it has."""
    if value:
        text = str(value)
        _note_made(ctx, Path(text), folder=text.endswith(("/", "\\")))
    return value


def folder_output(ctx: click.Context, param: click.Parameter, value: Optional[str | Path]) -> Optional[str | Path]:
    """click callback of an output folder argument or option: like :func:`output_folders`, the
    folder itself included."""
    if value:
        _note_made(ctx, Path(value), folder=True)
    return value
