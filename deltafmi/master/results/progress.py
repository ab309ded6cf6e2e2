"""A one-line progress bar for terminals, and the end-of-run summary."""
from __future__ import annotations

import sys
import time as _time
from dataclasses import field
from pathlib import Path
from typing import Any, Optional, TextIO

from ..scenario.records import record

__all__ = ["Progress", "Summary", "Termination"]


#: seconds between progress lines when the output is not a terminal (a log file, CI)
LINE_EVERY = 30.0


class Progress:
    """Redraws ``[#####.....]  42% t = 0.84 s`` at most five times a second; silent when disabled.
    With ``lines`` (no terminal to redraw on), ``progress: 42% t = 0.84 s`` as a line of its own on
    stderr every :data:`LINE_EVERY` seconds instead: a log shows a long run is alive."""

    def __init__(self, start: float, stop: float, enabled: bool, stream: TextIO = sys.stdout,
                 lines: bool = False) -> None:
        self.start, self.span = start, max(stop - start, 1e-300)
        self.lines = lines and not enabled
        self.enabled = enabled or self.lines
        self.stream = sys.stderr if self.lines and stream is sys.stdout else stream
        self._next_draw = _time.monotonic() + LINE_EVERY if self.lines else 0.0

    def update(self, t: float) -> None:
        """Show simulated time ``t`` (cheap when called often: redraws are rate limited)."""
        if not self.enabled:
            return
        now = _time.monotonic()
        if now < self._next_draw:
            return
        self._next_draw = now + (LINE_EVERY if self.lines else 0.2)
        fraction = min(max((t - self.start) / self.span, 0.0), 1.0)
        if self.lines:
            self.stream.write(f"progress: {100 * fraction:5.1f}% t = {t:.6g} s\n")
            self.stream.flush()
            return
        filled = int(30 * fraction)
        self.stream.write(f"\r[{'#' * filled}{'.' * (30 - filled)}] {100 * fraction:5.1f}% t = {t:.6g} s")
        self.stream.flush()

    def close(self, t: float) -> None:
        """Draw the bar at ``t`` (where the run ended) and finish its line; later calls do nothing."""
        if self.enabled and not self.lines:
            self._next_draw = 0.0
            self.update(t)
            self.stream.write("\n")
            self.stream.flush()
        self.enabled = False


@record
class Termination:
    """A component ended the run before its stop time (FMI 2.0: terminateSimulation in Model
    Exchange, fmi2Discard with fmi2Terminated in Co-Simulation)."""

    component: str
    time: float
    #: what the component said (its fmi2Discard message), "" when nothing
    reason: str = field(default="", compare=False)

    def __str__(self) -> str:
        text = f"ended early: {self.component} terminated the simulation at t = {self.time:.9g} s"
        return text + (f" ({self.reason})" if self.reason else "")


@record(frozen=False)
class Summary:
    """Figures of a finished run."""

    steps: int
    rejected: int
    events: int
    wall_time: float
    simulated: float
    rows: int
    result: Path
    #: who ended the run early, and when (None: it ran to its stop time)
    terminated: Optional[Termination] = None
    #: wall seconds spent before the first step (extracting, loading, initializing)
    setup_time: float = 0.0
    #: algebraic loops solved (a :class:`~deltafmi.master.stepping.algebraic_loops.LoopStatistics`; None: no loop)
    loops: Any = None
    #: wall seconds spent after the last step (last results written, units freed, files removed)
    close_time: float = 0.0
    #: a live run's pacing figures and sources' counters (a
    #: :class:`~deltafmi.master.live.run.LiveReport`; None: no live source, not paced)
    live: Any = None

    @property
    def stepping_time(self) -> float:
        """Wall seconds of the stepping alone (neither set-up nor close)."""
        return self.wall_time - self.setup_time - self.close_time

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall-clock second (> 1: faster than real time), set-up and close
        included."""
        return self.simulated / self.wall_time if self.wall_time > 0 else float("inf")

    @property
    def stepping_factor(self) -> float:
        """Simulated seconds per wall-clock second of the stepping alone: the figure the README and
        the benchmarks quote (a short run spends most of its time loading and initializing)."""
        return self.simulated / self.stepping_time if self.stepping_time > 0 else float("inf")

    def __str__(self) -> str:
        overhead = self.wall_time - self.stepping_time
        text = (f"{self.steps} steps ({self.rejected} rejected), {self.events} events, "
                f"{self.simulated:.6g} s simulated in {self.wall_time:.3f} s wall "
                f"(real-time factor {_factor(self.stepping_factor)}x stepping, {_factor(self.real_time_factor)}x "
                f"with the {overhead:.2f} s of loading and writing); {self.rows} rows -> {self.result}")
        if self.terminated:
            text += f"; {self.terminated}"
        if self.loops is not None and self.loops.solves:
            text += f"; algebraic loops: {self.loops}"
        if self.live is not None:
            text += f"\n{self.live}"
        return text


def _factor(value: float) -> str:
    """A real-time factor: one decimal from 1 up, two significant digits below (0.042, not 0.0)."""
    return f"{value:.1f}" if value >= 1 or value == 0 else f"{value:.2g}"
