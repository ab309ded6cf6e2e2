"""Pacing a run to the wall clock, and the report of how well it kept up.

Communication point ``t`` is due at wall time ``wall0 + (t - t0) / speed``. :meth:`Pacer.wait`
sleeps until shortly before (``spin`` seconds) and polls the clock for the rest: ``time.sleep``
alone wakes 50-100 us late on Linux (the thread's timer slack, the scheduler), which at 1 kHz is
a tenth of the step. Where the C library allows it the thread's timer slack is set to 1 ns, the
least there is (``prctl(PR_SET_TIMERSLACK)``), so the sleep itself lands closer and the polling
stays short. Where locking memory cannot make a later allocation fail (the process may lock
without limit: ``CAP_IPC_LOCK``, or ``RLIMIT_MEMLOCK`` unlimited) and nothing is locked already,
the process's pages stay in memory for the run (``mlockall``, as they are faulted in; unlocked at
:meth:`Pacer.close`): no page of the run is swapped or evicted and read back at a deadline. The
lateness record is written through once when it is made, so that the run itself faults in none
of its pages.

With a ``lead`` (wall seconds) a point may go out before its time: one due within the
lead is released at once, one due later is waited for until half the lead is left. The points then
go out in bursts between the lead and half of it ahead of their deadlines, so that a stall of the
thread shorter than half the lead makes no point late, and each wait is long enough to sleep
through rather than poll; the price is a point released up to ``lead`` early, and a live input
taken by a step up to ``lead * speed`` of simulated time later than its arrival's (its lateness
is then negative: how early). By default (:func:`default_lead`) a run whose paced step is shorter
than :data:`FINE_STEP` has a lead of :data:`DEFAULT_LEAD`: below that a step is shorter than what
one wake-up from a sleep, one scheduler tick or another process's turn costs, so a deadline per
step cannot be kept however the run waits; longer paced steps are released at their time.

A point released after its time is late by the difference; the schedule is absolute, so a late
run catches up when it can (no point is skipped, no time is stretched). A point later than
``tolerance`` is an overrun; one later than a whole paced step means the run fell behind: a
warning at the start of each such episode (or an error with ``behind="error"``) and an entry of
:attr:`RealtimeReport.behind`.
"""
from __future__ import annotations

import math
import time
from dataclasses import field
from typing import Callable, List, Optional, Tuple

import numpy as np

from deltafmi.errors import SimulationError

from ..scenario.records import record
from .thread_timing import lock_memory, real_time_priority, restore_scheduling, timer_slack, unlock_memory

__all__ = ["DEFAULT_LEAD", "DEFAULT_SPIN", "FINE_STEP", "Pacer", "RealtimeReport", "FellBehind", "default_lead"]

#: longest single sleep: a stop signal is looked at between sleeps
_SLEEP_CHUNK = 0.05
#: a paced step [s of wall time] shorter than this gets :data:`DEFAULT_LEAD` unless the scenario says
FINE_STEP = 1e-4
#: the lead [s of wall time] of a run paced finer than :data:`FINE_STEP`
DEFAULT_LEAD = 5e-4
#: wall seconds polled before a deadline without a lead (with one the waits sleep only)
DEFAULT_SPIN = 5e-5


def default_lead(period: float) -> float:
    """The lead [s] of a run paced at ``period`` wall seconds per step when the scenario gives none."""
    return DEFAULT_LEAD if period < FINE_STEP else 0.0


class FellBehind(SimulationError):
    """The run fell a whole communication step behind the wall clock and ``behind`` is "error"."""


@record(frozen=False)
class RealtimeReport:
    """How a paced run kept up: lateness of every communication point after the first [s]."""

    speed: float
    step: float
    tolerance: float
    lateness: np.ndarray
    #: (simulation time it began, end or None, largest lateness) of each time the run fell behind
    behind: List[Tuple[float, Optional[float], float]] = field(default_factory=list)
    #: CPU time [s] of the thread that stepped and waited, over :attr:`wall` seconds of the paced stepping
    cpu: float = 0.0
    wall: float = 0.0
    #: wall time [s] spent polling the clock before deadlines (CPU spent waiting)
    polled: float = 0.0
    #: whether the process's memory was locked for the run (mlockall)
    locked: bool = False
    #: wall seconds a point could be released before its time (negative lateness: how early)
    lead: float = 0.0
    #: the wall-clock time [s, ``time.perf_counter``] at which simulation time :attr:`t0` was due:
    #: point ``t`` was due at ``wall0 + (t - t0) / speed`` and released ``lateness`` after that
    wall0: float = 0.0
    t0: float = 0.0

    @property
    def overruns(self) -> int:
        """Communication points released later than :attr:`tolerance`."""
        return int(np.count_nonzero(self.lateness > self.tolerance))

    def percentile(self, q: float) -> float:
        """The ``q``-th percentile of the lateness [s] (0 for a run of one point)."""
        return float(np.percentile(self.lateness, q)) if len(self.lateness) else 0.0

    def __str__(self) -> str:
        lat = self.lateness
        if not len(lat):
            return f"real time at {self.speed:g}x: no step taken"
        text = (f"real time at {self.speed:g}x: lateness median {_us(self.percentile(50))}, "
                f"99th percentile {_us(self.percentile(99))}, max {_us(float(lat.max()))}; "
                f"{self.overruns} overrun{'s' * (self.overruns != 1)} (> {_us(self.tolerance)})"
                + (f", released up to {_us(max(0.0, -float(lat.min())))} early (lead {_us(self.lead)})"
                   if self.lead else ""))
        if not self.behind:
            return text + "; kept up"
        first = self.behind[0]
        return (text + f"; fell behind {len(self.behind)} time{'s' * (len(self.behind) != 1)}, first at "
                f"t = {first[0]:.6g} s (by up to {_us(first[2])})")


def _us(seconds: float) -> str:
    return f"{seconds * 1e6:.1f} us" if abs(seconds) < 1e-2 else f"{seconds * 1e3:.1f} ms"


class Pacer:
    """Releases communication points at their wall-clock times and measures how late they were."""

    def __init__(self, speed: float, step: float, n_points: int, *, tolerance: Optional[float] = None,
                 spin: Optional[float] = None, behind: str = "warn", warn: Callable[[str], None] = lambda text: None,
                 stopped: Callable[[], bool] = lambda: False, clock: Callable[[], float] = time.perf_counter,
                 priority: Optional[int] = None, lead: Optional[float] = None) -> None:
        """``step``: the communication step [s of simulated time]; ``n_points``: how many points
        :meth:`wait` will be asked for (sizes the lateness record); ``stopped()``: True when a stop
        signal came (the wait then returns early); ``priority``: a real-time priority (SCHED_FIFO)
        for the calling thread from :meth:`start` to :meth:`close`, and the threads it starts
        meanwhile (they inherit it); ``lead``: wall seconds a point may be released before its time
        (None: :func:`default_lead`); ``spin``: wall seconds polled before a deadline (None:
        :data:`DEFAULT_SPIN` without a lead, 0 with one; see the module's docstring)."""
        if not (speed > 0 and math.isfinite(speed)):
            raise ValueError(f"real-time speed {speed!r} must be a positive number")
        self.speed = float(speed)
        self.period = step / self.speed  # wall seconds per communication step
        self.lead = default_lead(self.period) if lead is None else float(lead)
        if not (self.lead >= 0 and math.isfinite(self.lead)):
            raise ValueError(f"real-time lead {lead!r} must be a number >= 0")
        self.tolerance = self.period / 4 if tolerance is None else float(tolerance)
        self.spin = (DEFAULT_SPIN if not self.lead else 0.0) if spin is None else float(spin)
        self.behind_is_error = behind == "error"
        self.warn = warn
        self.stopped = stopped
        self.clock = clock
        self.step = step
        self._lateness = np.full(max(n_points, 1), 0.0)  # written through: its pages faulted in now
        self._count = 0
        self._behind: List[Tuple[float, Optional[float], float]] = []
        self._t0 = 0.0
        self._wall0 = 0.0
        self._slack: Optional[int] = None
        self.released = 0.0  # wall time the last point was released
        self.late = 0.0  # how late it was
        #: behind = "error" and the run fell behind: what the caller raises once the point is recorded
        self.failure: Optional[FellBehind] = None
        #: wall seconds from the release of the last point to the call of the next wait
        self.busy = 0.0
        #: the stepping thread's CPU time and the wall time of the paced stepping so far [s]
        self.cpu = self.wall = 0.0
        #: wall time spent polling the clock before deadlines [s]
        self.polled = 0.0
        self._cpu0 = 0.0
        #: whether :meth:`start` locked the process's memory (until :meth:`close`)
        self.locked = False
        self._unlock = False
        self.priority = priority
        #: the calling thread's scheduling (policy, priority) before :meth:`start` raised it
        self._scheduling: Optional[Tuple[int, int]] = None

    def start(self, t0: float) -> None:
        """Simulation time ``t0`` is now (call :meth:`close` when the run ends)."""
        self._slack = timer_slack(1)
        self.locked = self._unlock = lock_memory()
        if self.priority is not None:
            self._scheduling = real_time_priority(self.priority, self.warn)
        self._t0 = t0
        self._cpu0 = time.thread_time()
        self._wall0 = self.released = self.clock()

    def restart(self) -> None:
        """The clock starts again now, at the same simulation time, before any point was waited
        for (preparing the stepping does not count as the first point's lateness)."""
        if self._count == 0:
            self._cpu0 = time.thread_time()
            self._wall0 = self.released = self.clock()

    def wait(self, t: float) -> float:
        """Return at the wall-clock time of simulation time ``t``; returns how late [s]."""
        clock = self.clock
        now = clock()
        self.busy = now - self.released
        deadline = self._wall0 + (t - self._t0) / self.speed
        lead = self.lead
        wake = deadline if not lead else deadline - lead / 2 if now < deadline - lead else now
        while wake - now > self.spin + 1e-6:
            if self.stopped():  # the run ends at this point: no use waiting for its time
                self.released = now
                return 0.0
            time.sleep(min(wake - now - self.spin, _SLEEP_CHUNK))
            now = clock()
        polling = now
        while now < wake:
            now = clock()
        self.polled += now - polling
        late = self.late = now - deadline
        self.released = now
        self.cpu, self.wall = time.thread_time() - self._cpu0, now - self._wall0
        self._note(t, late)
        return late

    def _note(self, t: float, late: float) -> None:
        if self._count < len(self._lateness):
            self._lateness[self._count] = late
            self._count += 1
        self._episode(t, late)

    def note_released(self, times: np.ndarray, lateness: np.ndarray) -> None:
        """Points released elsewhere (the master's C loop, which waited as :meth:`wait` does and
        wrote their lateness into the record): at ``times``, ``lateness`` late."""
        over = lateness > self.period
        if not len(over) or (not (self._behind and self._behind[-1][1] is None) and not over.any()):
            return
        # a point changes the episodes only where the run falls behind or catches up: one call
        # for the first point of each stretch of points late by more than a step or not (a whole
        # C run's points one by one took a millisecond of Python between two paced points)
        firsts = np.flatnonzero(np.diff(over, prepend=not over[0])).tolist()
        late, at = lateness.tolist(), times.tolist()
        for first, end in zip(firsts, firsts[1:] + [len(late)]):
            self._episode(at[first], late[first])
            if late[first] > self.period and end - first > 1:
                self._episode(at[first], max(late[first:end]))

    def _episode(self, t: float, late: float) -> None:
        """A run falling behind (a point later than a whole step) and catching up again."""
        episodes = self._behind
        if late > self.period:
            if episodes and episodes[-1][1] is None:
                begun, _, worst = episodes[-1]
                episodes[-1] = (begun, None, max(worst, late))
                return
            episodes.append((t, None, late))
            message = (f"fell behind real time at t = {t:.6g} s: released {_us(late)} late, more than a "
                       f"whole step ({_us(self.period)} of wall time)")
            if self.behind_is_error:
                self.failure = FellBehind(message)
            else:
                self.warn(message + "; going on")
        elif episodes and episodes[-1][1] is None:
            begun, _, worst = episodes[-1]
            episodes[-1] = (begun, t, worst)

    def close(self) -> None:
        """Give the thread its timer slack back (a notebook's thread outlives the run)."""
        if self._slack is not None:
            timer_slack(self._slack)
            self._slack = None
        if self._unlock:
            unlock_memory()
            self._unlock = False
        if self._scheduling is not None:
            restore_scheduling(self._scheduling)
            self._scheduling = None

    def report(self) -> RealtimeReport:
        """The lateness of every point so far."""
        return RealtimeReport(self.speed, self.step, self.tolerance, self._lateness[:self._count].copy(),
                              list(self._behind), cpu=self.cpu, wall=self.wall, polled=self.polled,
                              locked=self.locked, lead=self.lead, wall0=self._wall0, t0=self._t0)
