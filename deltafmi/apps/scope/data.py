"""What the live plot window holds: a rolling window of each received signal (:class:`Trace`)
and the routing of received datagrams to the subplots whose patterns take them (:class:`ScopeData`).

A SIGNAL argument of the scope is one subplot; spaces separate its patterns. A pattern is a
received name, a glob (``plant.z[*]``, ``plant.z[1:3]``, ``osc.*``) or an array's name (``plant.z``:
its elements). A signal several subplots take is kept once.

Time is the sender's (simulation time). A datagram older than the newest is dropped as stale,
unless the sender has started again (its sequence number went back, or its time went back by more
than the window): then every trace starts again. Malformed datagrams are counted and dropped, with
a warning for the first few.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from deltafmi.errors import BadInput, did_you_mean

from deltafmi.master.live.datagram import MalformedDatagram, decode, sequence_went_back

__all__ = ["Group", "MALFORMED_WARNINGS", "ScopeData", "Trace", "warn_on_stderr"]

#: points a trace holds before it first grows
_INITIAL_CAPACITY = 1024
#: the most points a trace holds: a sender whose time stands still cannot exhaust the memory
MAX_POINTS = 1 << 20
#: malformed datagrams warned about; further ones are counted only
MALFORMED_WARNINGS = 5


def warn_on_stderr(text: str) -> None:
    """The default ``warn`` of the scope: ``scope: warning: ...`` on stderr (if it is still open)."""
    try:
        print(f"scope: warning: {text}", file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


class Trace:
    """One signal's rolling window: times and values in numpy arrays, oldest first.

    Not a wrap-around ring: points go to the end, and when the arrays are full the points older
    than the window are dropped by moving the rest to the front (amortized O(1) per point; the
    arrays grow when the window holds more than half of them). What is drawn is therefore always
    a contiguous view, never a copy. :meth:`add` only queues a point; :meth:`flush` stores the queue.
    """

    def __init__(self, name: str, window: float, capacity: int = _INITIAL_CAPACITY) -> None:
        self.name = name
        self.window = window
        self._t = np.empty(capacity)
        self._v = np.empty(capacity)
        self._n = 0
        self._first = 0  # the number of the first stored point among all the trace has stored
        self._queued_t: List[float] = []
        self._queued_v: List[float] = []

    def __len__(self) -> int:
        """The points stored (queued ones are not, until :meth:`flush`)."""
        return self._n

    def add(self, t: float, value: float) -> None:
        """Queue one point (times never decrease: :class:`ScopeData` sees to it)."""
        self._queued_t.append(t)
        self._queued_v.append(value)

    def flush(self) -> None:
        """Store the queued points."""
        if self._queued_t:
            self.extend(self._queued_t, self._queued_v)
            self._queued_t, self._queued_v = [], []

    def extend(self, times: Sequence[float], values: Sequence[float]) -> None:
        """Store points whose times do not decrease and come at or after the last one stored."""
        k = len(times)
        if k > MAX_POINTS:
            times, values, k = times[-MAX_POINTS:], values[-MAX_POINTS:], MAX_POINTS
        if not k:
            return
        if self._n + k > len(self._t):
            self._make_room(k, times[-1])
        n = self._n
        self._t[n:n + k] = times
        self._v[n:n + k] = values
        self._n = n + k

    def _make_room(self, k: int, newest: float) -> None:
        start = int(np.searchsorted(self._t[:self._n], newest - self.window, "left"))
        # one point before the window stays (the curve reaches the edge of the axes)
        start = max(start - 1, self._n + k - MAX_POINTS, 0)
        kept = self._n - start
        capacity = len(self._t)
        if kept + k > capacity // 2:
            capacity = min(MAX_POINTS, max(2 * capacity, 2 * (kept + k)))
        if capacity == len(self._t):
            self._t[:kept] = self._t[start:self._n]  # overlapping: numpy copies through a buffer
            self._v[:kept] = self._v[start:self._n]
        else:
            t, v = np.empty(capacity), np.empty(capacity)
            t[:kept], v[:kept] = self._t[start:self._n], self._v[start:self._n]
            self._t, self._v = t, v
        self._n = kept
        self._first += start

    def since(self, t0: float) -> Tuple[np.ndarray, np.ndarray]:
        """Views of the stored points from ``t0`` on, with the last one before ``t0`` (so that a
        curve reaches the left edge of the axes)."""
        return self._since(t0)[:2]

    def _since(self, t0: float) -> Tuple[np.ndarray, np.ndarray, int]:
        n = self._n
        i = max(int(np.searchsorted(self._t[:n], t0, "left")) - 1, 0)
        return self._t[i:n], self._v[i:n], self._first + i

    def visible(self, t0: float, columns: int) -> Tuple[np.ndarray, np.ndarray]:
        """The points from ``t0`` on as :meth:`since`, thinned to about two per column of pixels
        when there are more: the least and the greatest value of each run of points (runs of a
        power of two, numbered from the trace's first point, so that they stay put while the window
        moves and the picture does not shimmer)."""
        t, v, number = self._since(t0)
        n = len(t)
        if n <= 2 * columns:
            return t, v
        run = 1 << math.ceil(math.log2(n / columns))
        head = -number % run  # points before the first whole run
        runs = (n - head) // run
        body = v[head:head + runs * run].reshape(runs, run)
        low, high = body.argmin(axis=1), body.argmax(axis=1)
        starts = head + run * np.arange(runs)
        index = np.empty(2 * runs, dtype=np.intp)
        index[0::2] = starts + np.minimum(low, high)
        index[1::2] = starts + np.maximum(low, high)
        index = np.concatenate((np.arange(head), index, np.arange(head + runs * run, n)))
        return t[index], v[index]

    def clear(self) -> None:
        """Forget every point (a new run)."""
        self._n = 0
        self._first = 0
        self._queued_t, self._queued_v = [], []


@dataclass
class Group:
    """One subplot: its patterns and the traces they matched, in pattern order, then arrival order."""

    patterns: Tuple[str, ...]
    traces: List[Trace] = field(default_factory=list)

    @property
    def title(self) -> str:
        """The argument it came from."""
        return " ".join(self.patterns)


def _matcher(pattern: str) -> Callable[[str], bool]:
    from deltafmi.master.scenario.modelinfo import split_element
    from deltafmi.master.scenario.resolve import pattern_regex

    regex = pattern_regex(pattern)

    def matches(name: str) -> bool:
        element = split_element(name)
        return bool(regex.match(name)) or (element is not None and element[0] == pattern)
    return matches


_UNSEEN = object()


class ScopeData:
    """What the scope has received: the traces of the selected signals grouped per subplot, the
    newest time, and ``counters`` (received, malformed, stale, restarts).

    ``arguments`` are the SIGNAL arguments (each one subplot; spaces separate its patterns),
    ``window`` the seconds of the sender's time shown, ``warn`` takes one-line warnings. Feed it
    raw datagrams with :meth:`receive`, or decoded ones with :meth:`add`.
    """

    def __init__(self, arguments: Sequence[str], window: float,
                 warn: Callable[[str], None] = warn_on_stderr) -> None:
        if not window > 0 or not math.isfinite(window):
            raise BadInput(f"the window must be a positive number of seconds, not {window}")
        self.groups = [Group(tuple(argument.split())) for argument in arguments]
        if not self.groups or not all(g.patterns for g in self.groups):
            raise BadInput("name the signals to draw (a name, a pattern like 'plant.z[*]', or an array's name)")
        self.window = float(window)
        self.warn = warn
        self._matchers = [[_matcher(p) for p in g.patterns] for g in self.groups]
        self._routes: Dict[str, Any] = {}  # name -> its Trace, or None when no pattern takes it
        self._order: Dict[Tuple[int, str], Tuple[int, int]] = {}  # (group, name) -> (pattern, arrival)
        self.traces: Dict[str, Trace] = {}
        self.unselected: List[str] = []  # received names no pattern takes (the first 1000)
        self.newest = self.started = -math.inf  # the newest time, the first since the (re)start
        self._seq: Optional[int] = None
        self.counters = {"received": 0, "malformed": 0, "stale": 0, "restarts": 0}

    def receive(self, data: bytes) -> None:
        """One raw datagram: decoded and added, or counted as malformed and dropped."""
        self.counters["received"] += 1
        try:
            datagram = decode(data)
        except MalformedDatagram as error:
            self._malformed(error.reason)
            return
        self.add(datagram.t, datagram.seq, datagram.values)

    def _malformed(self, reason: str) -> None:
        self.counters["malformed"] += 1
        count = self.counters["malformed"]
        if count <= MALFORMED_WARNINGS:
            self.warn(f"malformed datagram dropped: {reason}")
        if count == MALFORMED_WARNINGS:
            self.warn("further malformed datagrams are counted only")

    def add(self, t: float, seq: int, values: Dict[str, float]) -> None:
        """One decoded datagram: the sender's time ``t``, its sequence number and its values."""
        if t < self.newest:
            if not (sequence_went_back(self._seq, seq) or t < self.newest - self.window):
                self.counters["stale"] += 1
                return
            self.restart(t)
        if self.newest == -math.inf:
            self.started = t
        self.newest = t
        self._seq = seq
        routes = self._routes
        for name, value in values.items():
            trace = routes.get(name, _UNSEEN)
            if trace is _UNSEEN:
                trace = self._route(name)
            if trace is not None:
                trace.add(t, value)

    def restart(self, t: float) -> None:
        """The sender started again at ``t``: forget every point."""
        self.counters["restarts"] += 1
        self.warn(f"the sender's time went back from {self.newest:g} s to {t:g} s: a new run, the picture starts again")
        for trace in self.traces.values():
            trace.clear()
        self.newest = self.started = -math.inf

    def _route(self, name: str) -> Optional[Trace]:
        """The trace of a name received for the first time (shared by every group that takes it)."""
        trace = None
        for index, (group, matchers) in enumerate(zip(self.groups, self._matchers)):
            hits = [i for i, matches in enumerate(matchers) if matches(name)]
            if not hits:
                continue
            if trace is None:
                trace = Trace(name, self.window)
            self._order[index, name] = (hits[0], len(self._routes))
            group.traces.append(trace)
            group.traces.sort(key=lambda tr: self._order[index, tr.name])
        if trace is None:
            if len(self.unselected) < 1000:
                self.unselected.append(name)
        else:
            self.traces[name] = trace
        self._routes[name] = trace
        return trace

    def flush(self) -> None:
        """Store every queued point (before drawing or reading the traces)."""
        for trace in self.traces.values():
            trace.flush()

    def unmatched(self) -> List[str]:
        """One line per pattern that matched none of the received names, with a suggestion."""
        lines = []
        for group, matchers in zip(self.groups, self._matchers):
            for pattern, matches in zip(group.patterns, matchers):
                if not any(matches(name) for name in self.traces):
                    hint = did_you_mean(pattern, self.unselected)
                    heard = f" (received: {', '.join(self.unselected[:8])}{', ...' * (len(self.unselected) > 8)})"
                    lines.append(f"'{pattern}' matched none of the received signals"
                                 + (hint or (heard if self.unselected else "")))
        return lines

    def summary(self) -> str:
        """One line: what was received and drawn."""
        c = self.counters
        return (f"{c['received']} datagrams received ({c['malformed']} malformed, {c['stale']} stale, "
                f"{c['restarts']} restarts); {len(self.traces)} signals drawn")
