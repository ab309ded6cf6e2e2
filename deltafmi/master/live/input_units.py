"""Live sources in the master: a unit per source, whose outputs are the values last received.

A :class:`LiveInputUnit` has the part of a unit's interface the master uses (wiring, fetch,
initialization, close) and no stepping of its own: :class:`~deltafmi.master.live.run.LiveRun`
samples it at each communication point (:meth:`LiveInputUnit.sample`), after the steps that
reach the point and before its row is recorded, so the row at ``t`` shows the value received by
``t``, which the next step then uses: a zero-order hold, as an FMU's output at ``t`` is held
over the step from ``t``.
"""
from __future__ import annotations

import time
from typing import Any, Callable, Dict, List, Optional, Protocol, Sequence, Tuple

import numpy as np

from ..scenario.system import ResolvedComponent, Port

__all__ = ["LiveSource", "LiveInputUnit"]


class LiveSource(Protocol):
    """What a live input source offers the master (UDP, joystick, a replayed results file)."""

    name: str
    signals: Tuple[str, ...]

    def open(self, warn: Callable[[str], None]) -> None:
        """Bind, open a device or a file; ``warn(text)`` takes messages for the user."""

    def poll(self, t: float) -> Optional[Dict[str, float]]:
        """New values since the last poll (any subset of :attr:`signals`), None when nothing new;
        ``t``: the simulation time. Never blocks, never raises on bad data from outside."""

    def counters(self) -> Dict[str, int]:
        """What happened so far (received, malformed, ...), for the summary."""

    def close(self) -> None:
        """Release what :meth:`open` took (twice is fine)."""


class LiveInputUnit:
    """The master's unit of one live source: its signals' current values on the Real bus."""

    interface = "LIVE"
    fmi3 = False
    step_multiple = 1
    can_save_state = False
    initialized = True

    def __init__(self, component: ResolvedComponent, source: LiveSource, starts: Sequence[float],
                 timeout: Optional[float] = None, warn: Callable[[str], None] = lambda text: None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """``starts``: each signal's value before anything arrives; ``timeout``: wall seconds
        without new values before the source is reported silent (None: never)."""
        self.component = component
        self.name = component.name
        self.source = source
        self.values = np.array(starts, dtype=float)
        self._index = {name: i for i, name in enumerate(source.signals)}
        self.timeout = timeout
        self.warn = warn
        self.clock = clock
        self.on_message = None
        self.logging_on = False
        self._bus: Optional[np.ndarray] = None
        self._slots = np.zeros(0, np.intp)
        self._vrs = np.zeros(0, np.intp)
        self._last_news = 0.0
        self._silent_since: Optional[float] = None
        #: simulation times at which the source was found silent
        self.silences: List[float] = []
        self.opened = False
        self.start = 0.0

    # --- the master's unit interface ------------------------------------------------------------
    def instantiate(self, start: float, stop: float) -> None:
        self.start = start
        self.source.open(self.warn)
        self.opened = True
        self._last_news = self.clock()

    def apply_start_values(self) -> None:
        pass

    def output_slots(self, kind: str, vrs: Sequence[int]) -> List[Tuple[int, int]]:
        return [(vr, 0) for vr in vrs]

    def wire_outputs(self, kind: str, vrs: Sequence[int], bus: np.ndarray, start: int) -> None:
        self._bus = bus
        self._vrs = np.asarray(vrs, np.intp)
        self._slots = np.arange(start, start + len(vrs), dtype=np.intp)

    def bus_addresses(self) -> List[Optional[int]]:
        """The address of each value's slot on the Real bus, by value reference (None: not on the
        bus), for C code that writes them there."""
        addresses: List[Optional[int]] = [None] * len(self.values)
        if self._bus is not None:
            for vr, slot in zip(self._vrs.tolist(), self._slots.tolist()):
                addresses[vr] = self._bus.ctypes.data + slot * self._bus.itemsize
        return addresses

    def wire_inputs(self, *args: Any) -> None:
        raise AssertionError(f"live source {self.name} has no inputs")

    def enter_initialization(self) -> None:
        self.sample(None)

    def exit_initialization(self, time: float) -> None:
        pass

    def pull(self) -> None:
        pass

    def do_step(self, time: float, step: float) -> None:
        pass

    def fetch(self) -> None:
        if self._bus is not None:
            self._bus[self._slots] = self.values[self._vrs]

    def get_value(self, port: Port) -> float:
        return float(self.values[port.vr])

    def close(self) -> None:
        if self.opened:
            self.opened = False
            self.source.close()

    def termination_reason(self) -> str:
        return ""

    # --- live ---------------------------------------------------------------------------------
    def sample(self, t: Optional[float]) -> None:
        """Take what the source received by now (simulation time ``t``; None: the start) and put
        it on the bus; report a silence longer than the timeout once, and its end."""
        t = self.start if t is None else t
        news = self.source.poll(t)
        now = self.clock()
        if news:
            index = self._index
            for name, value in news.items():
                self.values[index[name]] = value
            self._last_news = now
            if self._silent_since is not None:
                self.warn(f"live input '{self.name}': data again at t = {t:.6g} s after "
                          f"{now - self._silent_since:.3g} s of silence")
                self._silent_since = None
        elif (self.timeout is not None and self._silent_since is None
              and now - self._last_news > self.timeout):
            self._silent_since = self._last_news
            self.silences.append(t)
            self.warn(f"live input '{self.name}': nothing received for {now - self._last_news:.3g} s "
                      f"(t = {t:.6g} s); holding "
                      + ", ".join(f"{s} = {v:.6g}" for s, v in zip(self.source.signals, self.values)))
        self.fetch()


    def summary(self) -> str:
        """One line of what the source did: its counters and silences."""
        counts = ", ".join(f"{n} {k}" for k, n in self.source.counters().items())
        silent = f", silent {len(self.silences)} time{'s' * (len(self.silences) != 1)}" if self.silences else ""
        return f"{self.name}: {counts or 'nothing counted'}{silent}"
