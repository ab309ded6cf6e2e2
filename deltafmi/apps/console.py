"""What the commands show on the terminal besides their results: the library's progress messages.

The library logs them (``deltafmi.build``: "building X FMU ..."); a command shows them on stderr,
one line each, and ``-q`` keeps them back. Python users see them through their own logging
set-up (``logging.basicConfig(level=logging.INFO)``).
"""
from __future__ import annotations

import contextlib
import logging
import warnings
from typing import Iterator, Optional

import click

__all__ = ["progress_shown", "show_progress"]

#: the loggers whose INFO messages a command shows
PROGRESS_LOGGERS = ("deltafmi.build",)


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
