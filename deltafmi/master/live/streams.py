"""Live outputs: recorded signals sent as UDP datagrams while the run goes, or shown in a plot
window (the scope, :mod:`.scope`, a process of its own fed by such a stream, so drawing never
holds up the run)."""
from __future__ import annotations

import math
import select
import subprocess
import sys
from typing import Any, Callable, List, Optional, Sequence

import numpy as np

from deltafmi.errors import BadInput

__all__ = ["Stream", "open_stream"]

#: plot datagrams per simulated second unless the stream gives its rate
_PLOT_RATE = 50.0
#: wall seconds the scope may take to start and say its port
_SCOPE_START = 20.0
#: the plot windows started by this process
_SCOPES: List[subprocess.Popen] = []


class Stream:
    """Sends the recorded columns ``columns`` of a row at most ``rate`` times per simulated
    second (None: at every communication point): at the first point, then at the first point
    at or after each ``t0 + n / rate``, and at the last point."""

    def __init__(self, sink: Any, columns: Sequence[int], rate: Optional[float], what: str) -> None:
        self.sink = sink
        self.columns = np.asarray(columns, np.intp)
        self.interval = 0.0 if rate is None else 1.0 / rate
        self.t0 = 0.0
        self.sent_slot = 0
        self.what = what

    def start(self, t0: float, row: np.ndarray) -> None:
        """Send the first row (the point ``t0``)."""
        self.t0, self.sent_slot = t0, 0
        self.sink.send(t0, row[self.columns].tolist())

    def send(self, t: float, row: np.ndarray, last: bool = False) -> None:
        """Send the stream's values of ``row`` (the point ``t``) when its rate allows, or
        ``last``: the run's last point."""
        if self.interval:
            # counted in slots from t0, not by adding up intervals (which drifts)
            slot = math.floor((t - self.t0) / self.interval + 1e-9)
            if slot <= self.sent_slot and not last:
                return
            self.sent_slot = slot
        self.sink.send(t, row[self.columns].tolist())

    def summary(self) -> str:
        counts = ", ".join(f"{n} {k}" for k, n in self.sink.counters().items())
        return f"{self.what}: {counts}"

    def close(self) -> None:
        """Close the socket; a plot window stays open for the person looking at it."""
        self.sink.close()


def open_stream(spec: Any, names: List[str], columns: List[int], warn: Callable[[str], None]) -> Optional[Stream]:
    """The :class:`Stream` of ``streams:`` entry ``spec`` (a
    :class:`~deltafmi.master.scenario.spec.StreamSpec`) over the recorded ``columns``."""
    from .udp import UdpSink, parse_host_port

    if spec.kind == "udp":
        host, port = parse_host_port(spec.target, "streams: udp")
        sink = UdpSink(names, host, port, format=spec.format, byte_order=spec.byte_order)
        sink.open(warn)
        return Stream(sink, columns, spec.rate, f"stream to {spec.target}")
    from .display import display_problem

    problem = display_problem()
    if problem is not None:
        warn(f"streams: plot: {problem}: the plot window is not shown; stream to UDP and run "
             "`deltafmi scope` where there is a display")
        return None
    port = _start_scope(list(spec.signals), spec.window)
    sink = UdpSink(names, "127.0.0.1", port)
    sink.open(warn)
    return Stream(sink, columns, spec.rate or _PLOT_RATE, f"plot on 127.0.0.1:{port}")


def _start_scope(panels: Sequence[str], window: float):
    """Start the plot window's process (one panel per pattern of ``panels``); returns the port it
    listens on. The window outlives the run (closed by the person looking at it)."""
    process = subprocess.Popen([sys.executable, "-m", "deltafmi.apps", "scope", "--port", "0",
                                "--window", repr(window), *panels], stdout=subprocess.PIPE, text=True)
    ready, _, _ = select.select([process.stdout], [], [], _SCOPE_START)
    line = process.stdout.readline() if ready else ""
    if not line.startswith("listening "):
        process.kill()
        process.wait()
        raise BadInput(f"streams: plot: the plot window did not start ({line.strip() or 'no answer'})")
    _SCOPES.append(process)  # kept, not waited for: it ends when its window is closed
    return int(line.rsplit(":", 1)[1])
