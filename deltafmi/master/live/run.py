"""What a live run adds to the master: its sources' units, the pacer, the output streams.

The master calls :meth:`LiveRun.begin` once the first row is recorded, and
:meth:`LiveRun.at_point` at every later communication point, after the steps that reach it and
before its row is recorded: wait for the point's wall-clock time (a paced run), note how late it
came, take what every source received, then send the streams.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, List, Optional

import numpy as np

from ..scenario.system import System
from ..scenario.spec import grid_steps
from ..scenario.live_components import REALTIME
from .pacing import Pacer, RealtimeReport
from .streams import Stream, open_stream
from deltafmi.master.live.input_units import LiveInputUnit

__all__ = ["C_LONGEST_WAIT", "LiveRun", "LiveReport"]

#: a paced step longer than this [s of wall time] is paced in Python (which looks at stop signals while it waits)
C_LONGEST_WAIT = 0.05


class LiveReport:
    """The live part of a run's summary: pacing and each source's counters."""

    def __init__(self, realtime: Optional[RealtimeReport], sources: List[str], streams: List[str]) -> None:
        self.realtime = realtime
        self.sources = sources
        self.streams = streams

    def __str__(self) -> str:
        parts = ([str(self.realtime)] if self.realtime is not None else []) + self.sources + self.streams
        return "; ".join(parts)


class LiveRun:
    """The live sources, pacing and streams of one run of ``system``."""

    def __init__(self, system: System, start: float, stop: float, step: float, *, replay: Optional[Path] = None,
                 warn: Callable[[str], None] = lambda text: None, stopped: Callable[[], bool] = lambda: False) -> None:
        """A run of ``system`` from ``start`` to ``stop`` in communication steps ``step``;
        ``replay``: a results file whose live columns stand in for the sources; ``warn(text)``:
        messages for the user; ``stopped()``: True once a stop signal came."""
        scenario = system.scenario
        self.warn = warn
        realtime = scenario.master.realtime
        self.pacer: Optional[Pacer] = None
        self._clock_unit: Optional[LiveInputUnit] = None
        result = grid = None
        if replay is not None:
            from ..results.result import read_result
            from .replay import Grid
            result, grid = read_result(replay), Grid(start, stop, step)
            grid.check(result, Path(replay))
        specs = {spec.name: spec for spec in scenario.live}
        self.units: List[LiveInputUnit] = []
        for component in system.live:
            if component.name == REALTIME:
                self.pacer = Pacer(realtime.speed, step, grid_steps(start, stop, step), tolerance=realtime.tolerance,
                                   spin=realtime.spin, behind=realtime.behind, warn=warn, stopped=stopped,
                                   priority=realtime.priority, lead=realtime.lead)
                self._clock_unit = LiveInputUnit(component, _Measurements(self.pacer), [0.0] * 3)
                continue
            spec = specs[component.name]
            source = (_replayed(spec, result, Path(replay), grid) if result is not None
                      else make_source(spec, scenario.directory))
            self.units.append(LiveInputUnit(component, source, [s.start for s in spec.signals],
                                            None if result is not None else spec.timeout, warn))
        self.sources = list(self.units)
        if self._clock_unit is not None:
            self.units.append(self._clock_unit)
        self.streams: List[Stream] = []
        self._stream_specs = list(zip(scenario.streams, system.streamed))
        if replay is not None and self.pacer is None and self._stream_specs:
            # a replay at the desk must not drive the device or controller of the live run again
            warn("--replay: the streams are not sent in a replay that is not paced (--realtime or --speed "
                 "sends them)")
            self._stream_specs = []
        self._recorded = [port.ref for port in system.recorded]
        self._sample: Optional[Callable[[], np.ndarray]] = None
        self.stop = stop
        self._replayed = replay is not None
        #: the first row is recorded: there is something to report
        self.started = False
        #: the sources' readers in the master's C loop (:meth:`read_in_c`), or None
        self.native_readers: Optional[Any] = None

    def open_streams(self) -> None:
        """Connect the streams (and start a plot window): before the result file is opened, so
        that a stream that cannot start leaves an earlier result file as it was."""
        position = {ref: i for i, ref in enumerate(self._recorded)}
        for spec, ports in self._stream_specs:
            stream = open_stream(spec, [p.ref for p in ports], [position[p.ref] for p in ports], self.warn)
            if stream is not None:
                self.streams.append(stream)

    def begin(self, t0: float, sample: Callable[[], np.ndarray]) -> None:
        """The first row (at ``t0``) is recorded: send it and start the clock; ``sample()``
        returns the row the master records (the streams' values)."""
        self._sample = sample
        self.started = True
        row = sample()
        for stream in self.streams:
            stream.start(t0, row)
        if self.pacer is not None:
            self.pacer.start(t0)

    def at_point(self, t: float, record: Optional[Callable[[float], None]]) -> None:
        """Communication point ``t`` is reached: wait for its time, take the sources' news,
        ``record(t)`` its row (None: not recorded), stream; then fail if the run fell behind
        and must not go on (the row is on disk first)."""
        if self.pacer is not None:
            self.pacer.wait(t)
            self._clock_unit.sample(t)
        for unit in self.sources:
            unit.sample(t)
        if self.native_readers is not None:
            self.native_readers.before_c()
        if record is not None:
            record(t)
        if self.streams:
            row = self._sample()
            last = t >= self.stop
            for stream in self.streams:
                stream.send(t, row, last)
        if self.pacer is not None and self.pacer.failure is not None:
            raise self.pacer.failure

    # --- a paced run stepped by the master's C loop ------------------------------------------------
    def paced_in_c(self) -> bool:
        """Whether the master's C loop may pace this run: a pacer, no streams (they send every
        point's row from Python), and a paced step short enough that a stop signal waits at
        most :data:`C_LONGEST_WAIT` for the C loop to hand back."""
        return self.pacer is not None and not self._stream_specs and self.pacer.period <= C_LONGEST_WAIT

    def read_in_c(self) -> Optional[Any]:
        """The C readers of the live sources when the C loop paces the run and can read every
        source itself (:mod:`.native_udp`: UDP on IPv4), else None (Python samples them at every
        point)."""
        if self.pacer is not None and self.sources and not self._replayed and self.native_readers is None:
            from .native_udp import native_readers
            self.native_readers = native_readers(self.sources)
        return self.native_readers

    def points_between_samples(self) -> int:
        """Communication points the C loop steps between two samples of the sources (and looks
        at stop signals): a replay or a live source samples at every point (what arrived before
        a point is what the step from it takes, as the recording says and a replay repeats);
        with no source but the clock, as many as :data:`C_LONGEST_WAIT` of wall time holds (more
        than one: the master runs the whole run in one call on a thread of its own and looks at
        stop signals while it goes, ``NativeLoop.run_streamed``)."""
        if self._replayed or self.pacer is None or (self.sources and self.native_readers is None):
            return 1
        return max(1, int(C_LONGEST_WAIT / self.pacer.period))

    def clock_slots(self) -> List[Optional[int]]:
        """The Real bus addresses of the pacing measurements (lateness, busy, behind; None where
        a measurement is not on the bus)."""
        unit = self._clock_unit
        slots: List[Optional[int]] = [None, None, None]
        if unit is not None and unit._bus is not None:
            for vr, slot in zip(unit._vrs.tolist(), unit._slots.tolist()):
                slots[vr] = unit._bus.ctypes.data + slot * unit._bus.itemsize
        return slots

    def after_c_points(self, t: float, handed_back: bool = False) -> None:
        """The C loop released the points up to ``t`` (the pacer's record is up to date): the
        pacing measurements of the last one and the sources' news, put on the bus, as
        :meth:`at_point` would have before ``t``'s row (sources the C loop reads: only where it
        ``handed_back`` for them, having read them up to there)."""
        unit = self._clock_unit
        if unit is not None:
            pacer = self.pacer
            unit.values[:] = (pacer.late, pacer.busy, float(pacer.late > pacer.period))
        if self.native_readers is not None and not handed_back:
            return
        for unit in self.sources:
            unit.sample(t)
        if self.native_readers is not None:
            self.native_readers.before_c()

    def close(self) -> None:
        """Stop the streams and the clock (the sources close with their units)."""
        for stream in self.streams:
            stream.close()
        if self.native_readers is not None:
            self.native_readers.close()
        if self.pacer is not None:
            self.pacer.close()

    def report(self) -> LiveReport:
        """Pacing figures and every source's and stream's counters."""
        return LiveReport(self.pacer.report() if self.pacer is not None else None,
                          [unit.summary() for unit in self.sources], [s.summary() for s in self.streams])


class _Measurements:
    """The pacing measurements as a source: lateness of the point just released, how long the
    step before it computed, and whether the run is a whole step behind."""

    name = REALTIME
    signals = ("lateness", "busy", "behind")

    def __init__(self, pacer: Pacer) -> None:
        self.pacer = pacer
        self.started = False

    def open(self, warn: Callable[[str], None]) -> None:
        pass

    def poll(self, t: float) -> Optional[dict]:
        pacer = self.pacer
        if not self.started:  # the first point: nothing measured yet
            self.started = True
            return None
        return {"lateness": pacer.late, "busy": pacer.busy, "behind": float(pacer.late > pacer.period)}

    def counters(self) -> dict:
        return {}

    def close(self) -> None:
        pass


def make_source(spec: Any, directory: Path) -> Any:
    """The source of ``live:`` entry ``spec`` (a :class:`~deltafmi.master.scenario.spec.LiveSpec`);
    relative files are relative to the scenario's ``directory``."""
    settings = spec.settings
    names = [s.name for s in spec.signals]
    if spec.kind == "udp":
        from .udp import UdpSource
        return UdpSource(spec.name, names, host=settings.get("host", "127.0.0.1"), port=int(settings["port"]),
                         format=settings.get("format", "dfmi"), byte_order=settings.get("byte_order", "little"),
                         dtype=settings.get("dtype", "float64"), sender=settings.get("sender"))
    from .joystick import AxisMap, JoystickSource
    session = settings.get("session")
    axes = {s.name: AxisMap(**s.options) for s in spec.signals}
    return JoystickSource(spec.name, axes, device=settings.get("device"),
                          session=None if session is None else directory / session,
                          record_to=None if settings.get("record") is None else Path(settings["record"]))


def _replayed(spec: Any, result: Any, path: Path, grid: Any) -> Any:
    from .replay import ReplaySource
    return ReplaySource(spec.name, [s.name for s in spec.signals], result, path, grid)

