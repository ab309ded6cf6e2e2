"""Ctrl-C (SIGINT) and SIGTERM during a run: stop between two steps, keep the results.

Python turns SIGINT into a KeyboardInterrupt in whatever Python code runs next, and during a
co-simulation that is mostly code inside an FMU (a deltafmi FMU runs its model in this
interpreter), where the FMU turns it into an fmi2Error: the run would fail with "fmi2DoStep
failed ... KeyboardInterrupt", possibly after a solver restart has swallowed it. While a
:class:`StopSignals` is active the signal only sets :attr:`StopSignals.received`; the master
checks it between steps and ends the run with :class:`~deltafmi.errors.Interrupted`. A
second signal raises KeyboardInterrupt at once (a step that never ends can still be broken).
"""
from __future__ import annotations

import signal
import threading
from types import FrameType, TracebackType
from typing import Any, Dict, Optional, Type

__all__ = ["StopSignals"]

#: the signals a run catches
SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopSignals:
    """Context manager: SIGINT/SIGTERM set :attr:`received` (the signal number) instead of
    raising. Signal handlers belong to the main thread: elsewhere it does nothing."""

    def __init__(self) -> None:
        self.received: Optional[int] = None
        self._previous: Dict[int, Any] = {}

    def __enter__(self) -> "StopSignals":
        if threading.current_thread() is threading.main_thread():
            for signum in SIGNALS:
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
