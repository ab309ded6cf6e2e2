"""Ctrl-C (SIGINT), SIGTERM and SIGHUP (a closed terminal, a dropped SSH session) during a run:
stop between two steps, keep the results.

Python turns SIGINT into a KeyboardInterrupt in whatever Python code runs next, and during a
co-simulation that is mostly code inside an FMU (a deltafmi FMU runs its model in this
interpreter), where the FMU turns it into an fmi2Error: the run would fail with "fmi2DoStep
failed ... KeyboardInterrupt", possibly after a solver restart has swallowed it. While a
:class:`StopSignals` is active the signal only sets :attr:`StopSignals.received`; the master
checks it between steps and ends the run with :class:`~deltafmi.errors.Interrupted`. A
second signal raises KeyboardInterrupt at once (a step that never ends can still be broken).
SIGINT is caught also where the shell ignored it (a command started with ``&`` in a script):
``kill -INT`` stops such a run as it stops one in a terminal. SIGHUP is left alone where it is
ignored (``nohup``).
"""
from __future__ import annotations

import signal
import threading
from types import FrameType, TracebackType
from typing import Any, Dict, Optional, Type

__all__ = ["StopSignals"]

#: the signals a run catches
SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class StopSignals:
    """Context manager: SIGINT/SIGTERM/SIGHUP set :attr:`received` (the signal number) instead of
    raising. Signal handlers belong to the main thread: elsewhere it does nothing."""

    def __init__(self) -> None:
        self.received: Optional[int] = None
        self._previous: Dict[int, Any] = {}

    def __enter__(self) -> "StopSignals":
        if threading.current_thread() is threading.main_thread():
            for signum in SIGNALS:
                if signum == signal.SIGHUP and signal.getsignal(signum) == signal.SIG_IGN:
                    continue  # started under nohup: a closed terminal must not stop the run
                self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, kind: Optional[Type[BaseException]], value: Optional[BaseException],
                 traceback: Optional[TracebackType]) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()

    def _handle(self, signum: int, frame: Optional[FrameType]) -> None:
        if self.received is not None:
            raise KeyboardInterrupt
        self.received = signum


class InterruptOnSignals:
    """Context manager for a loop that waits rather than steps (a study's sweep): SIGINT, SIGTERM
    and SIGHUP raise KeyboardInterrupt where the loop waits, so its ``except KeyboardInterrupt``
    keeps what finished; :attr:`received` says which signal. SIGINT is caught where the shell
    ignored it (a command started with ``&``), SIGHUP is left alone under ``nohup``; a second
    signal while the first is handled is ignored (the results are being written), unless
    ``again``: then it interrupts that too."""

    def __init__(self, again: bool = False) -> None:
        self.received: Optional[int] = None
        self.again = again
        self._previous: Dict[int, Any] = {}

    @property
    def exit_code(self) -> int:
        """128 + the signal received (130 when none was: a KeyboardInterrupt from elsewhere)."""
        return 128 + (self.received or signal.SIGINT)

    def __enter__(self) -> "InterruptOnSignals":
        if threading.current_thread() is threading.main_thread():
            for signum in SIGNALS:
                if signum == signal.SIGHUP and signal.getsignal(signum) == signal.SIG_IGN:
                    continue
                self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, kind: Optional[Type[BaseException]], value: Optional[BaseException],
                 traceback: Optional[TracebackType]) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()

    def _handle(self, signum: int, frame: Optional[FrameType]) -> None:
        if self.received is not None and not self.again:
            return
        self.received = signum
        raise KeyboardInterrupt
