"""The Clocks of an FMI 3.0 unit, as the master drives them (FMI 3.0, 2.2.9 "Clocks").

A time-based periodic input Clock ticks at ``t_i = start + shift + i * interval`` (computed from
``i``, so round-off does not pile up); the importer activates it at each tick with
``fmi3SetClock`` in Event Mode before ``fmi3UpdateDiscreteStates``, whose first round deactivates it.
Where the interval and shift come from depends on ``intervalVariability``:

* ``constant``, and ``fixed``/``tunable`` with ``intervalDecimal`` in the XML (the importer may set
  such an interval; the master does not, so the XML's holds): ``intervalDecimal`` (or
  ``intervalCounter / resolution``) and ``shiftDecimal`` (or ``shiftCounter / resolution``; 0);
* ``fixed``/``tunable`` without ``intervalDecimal``: ``fmi3GetIntervalDecimal`` and
  ``fmi3GetShiftDecimal`` in Initialization Mode; a ``tunable`` Clock is asked again after each
  Event Mode, and a new interval (``fmi3IntervalChanged``) counts from that event.

Output Clocks are read with ``fmi3GetClock`` in every Event Mode of the unit, after the input
Clocks are set and before ``fmi3UpdateDiscreteStates`` (their ticks are counted: Clocks are not
connected). The master cannot drive aperiodic input Clocks (``changing``, ``countdown``,
``triggered``: their ticks come from the FMU's answers in every Event Mode or from other FMUs)
nor Clocks in Co-Simulation without Event Mode: :func:`unit_clocks` refuses them by name, as the
scenario check does. fmpy parses
neither ``intervalDecimal`` nor ``shiftDecimal``, so the Clock elements are read from the
modelDescription.xml here.
"""
from __future__ import annotations

import ctypes
import math
import xml.etree.ElementTree as ElementTree
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple

import numpy as np
from fmpy.fmi3 import fmi3IntervalChanged, fmi3IntervalNotYetKnown, fmi3ValueReference

from ..scenario.fmu_checks import clocks_refused
from .unit_base import FmuFailure, instant_margin

__all__ = ["UnitClocks", "unit_clocks"]


def _xml_timing(element: Any) -> Tuple[Optional[float], float]:
    """(interval or None, shift) of a <Clock> element as its XML gives them."""
    resolution = element.get("resolution")
    interval: Optional[float] = None
    if element.get("intervalDecimal") is not None:
        interval = float(element.get("intervalDecimal"))
    elif element.get("intervalCounter") is not None and resolution is not None:
        interval = int(element.get("intervalCounter")) / int(resolution)
    shift = 0.0
    if element.get("shiftDecimal") is not None:
        shift = float(element.get("shiftDecimal"))
    elif element.get("shiftCounter") is not None and resolution is not None:
        shift = int(element.get("shiftCounter")) / int(resolution)
    return interval, shift


class UnitClocks:
    """A unit's periodic input Clocks (their ticks, activated by :meth:`activate` in Event Mode)
    and output Clocks (read by :meth:`read_outputs`). The schedule (``interval``, ``first``,
    ``count``) and the activation counts are numpy arrays that the master's C loop advances too
    (:mod:`.native_loop`)."""

    def __init__(self, unit: str, names: List[str], vrs: List[int], kinds: List[str],
                 xml: List[Tuple[Optional[float], float]], outputs: Dict[str, int]) -> None:
        self.unit = unit
        self.names, self.vrs, self.kinds = names, vrs, kinds
        self._xml = xml
        n = len(vrs)
        self.interval = np.zeros(n)
        self.first = np.zeros(n)  # the tick counted from (start + shift, or a tunable change)
        self.count = np.zeros(n, dtype=np.int64)  # ticks activated since `first`
        self.activated = np.zeros(n, dtype=np.int64)  # fmi3SetClock activations so far
        #: ticks of each output Clock so far (fmi3GetClock said active)
        self.output_ticks: Dict[str, int] = dict.fromkeys(outputs, 0)
        self._outputs = list(outputs.values())
        self._qualifiers: List[int] = []

    @property
    def activations(self) -> Dict[str, int]:
        """fmi3SetClock activations so far (ticks taken), per input Clock name."""
        return dict(zip(self.names, self.activated.tolist()))

    @property
    def steps_in_c(self) -> bool:
        """Whether the C loop can take the ticks: it keeps no output Clocks and asks the FMU for
        no new interval (a tunable Clock without one in the XML)."""
        return not self._outputs and not any(kind == "tunable" and xml[0] is None
                                             for kind, xml in zip(self.kinds, self._xml))

    # --- timing -------------------------------------------------------------------------------
    def schedule(self, unit: Any, start: float) -> None:
        """In Initialization Mode: every Clock's interval and shift (from the XML or the FMU)."""
        asked = [i for i, (interval, _) in enumerate(self._xml) if interval is None]
        intervals, shifts = self._ask(unit, asked, shifts=True)
        for i, (given, shift) in enumerate(self._xml):
            interval = given if given is not None else intervals[asked.index(i)]
            if given is None:
                shift = shifts[asked.index(i)]
            if not interval > 0.0 or shift < 0.0:
                raise FmuFailure(f"{self.unit}: Clock '{self.names[i]}' has interval {interval:g} s and shift "
                                 f"{shift:g} s; a periodic Clock needs interval > 0 and shift >= 0")
            self.interval[i], self.first[i], self.count[i] = interval, start + shift, 0

    def _ask(self, unit: Any, which: List[int], shifts: bool = False) -> Tuple[List[float], List[float]]:
        """fmi3GetIntervalDecimal (and fmi3GetShiftDecimal) of the Clocks ``which``; a
        fmi3IntervalNotYetKnown is refused (periodic Clocks always know their interval)."""
        if not which:
            return [], []
        n = len(which)
        refs = (fmi3ValueReference * n)(*[self.vrs[i] for i in which])
        intervals, qualifiers, offsets = (ctypes.c_double * n)(), (ctypes.c_int * n)(), (ctypes.c_double * n)()
        unit.call(unit.fmu.getIntervalDecimal, refs, intervals, qualifiers)
        for k, i in enumerate(which):
            if qualifiers[k] == fmi3IntervalNotYetKnown:
                raise FmuFailure(f"{self.unit}: fmi3GetIntervalDecimal says the interval of the periodic Clock "
                                 f"'{self.names[i]}' is not yet known")
        self._qualifiers = list(qualifiers)
        if shifts:
            unit.call(unit.fmu.getShiftDecimal, refs, offsets)
        return list(intervals), list(offsets)

    def refresh(self, unit: Any, t: float) -> None:
        """After an Event Mode at ``t``: a tunable Clock without an XML interval may have a new
        one (fmi3IntervalChanged), which counts from ``t``."""
        tunable = [i for i, kind in enumerate(self.kinds) if kind == "tunable" and self._xml[i][0] is None]
        intervals, _ = self._ask(unit, tunable)
        for k, i in enumerate(tunable):
            if self._qualifiers[k] == fmi3IntervalChanged and intervals[k] > 0.0:
                self.interval[i], self.first[i], self.count[i] = intervals[k], t + intervals[k], 0

    def tick(self, i: int) -> float:
        """The next tick of Clock ``i``."""
        return float(self.first[i] + float(self.count[i]) * self.interval[i])

    def next_tick(self) -> float:
        """The earliest tick to come (inf: no input Clocks)."""
        return min((self.tick(i) for i in range(len(self.vrs))), default=math.inf)

    def earliest(self, event_time: Optional[float]) -> Optional[float]:
        """The next time event of a unit whose FMU asked for ``event_time`` (None: none)."""
        tick = self.next_tick()
        if math.isinf(tick):
            return event_time
        return tick if event_time is None else min(tick, event_time)

    # --- activation ---------------------------------------------------------------------------
    def activate(self, unit: Any, t: float) -> bool:
        """In Event Mode at ``t``, before fmi3UpdateDiscreteStates: fmi3SetClock on every Clock
        ticking at ``t`` (together, in one call); True when one did."""
        due = [self.tick(i) <= t + instant_margin(t) for i in range(len(self.vrs))]
        if not any(due):
            return False
        for i, on in enumerate(due):
            if on:
                while self.tick(i) <= t + instant_margin(t):  # the ticks due now (more than one: missed ones)
                    self.count[i] += 1
                self.activated[i] += 1
        refs = [self.vrs[i] for i, on in enumerate(due) if on]
        unit.call(unit.fmu.setClock, refs, [True] * len(refs))
        return True

    def read_outputs(self, unit: Any) -> None:
        """In Event Mode, before fmi3UpdateDiscreteStates: fmi3GetClock on the output Clocks."""
        if self._outputs:
            for name, active in zip(self.output_ticks, unit.call(unit.fmu.getClock, self._outputs)):
                self.output_ticks[name] += bool(active)

    # --- rollback -----------------------------------------------------------------------------
    def state(self) -> tuple:
        """What :meth:`restore` needs to go back here."""
        return (self.interval.copy(), self.first.copy(), self.count.copy(), self.activated.copy(),
                dict(self.output_ticks))

    def restore(self, state: tuple) -> None:
        """Back to a :meth:`state` (in place: the C loop points into these arrays)."""
        interval, first, count, activated, output_ticks = state
        self.interval[:], self.first[:], self.count[:], self.activated[:] = interval, first, count, activated
        self.output_ticks = dict(output_ticks)


def unit_clocks(unit: str, unzip_dir: str, interface: str) -> Optional[UnitClocks]:
    """The Clocks of the FMU unzipped at ``unzip_dir`` (None when it has no input or output
    Clock); raises :class:`~.unit_base.FmuFailure` naming the unit and Clock that the master
    cannot drive as ``interface`` (see :func:`~deltafmi.master.scenario.fmu_checks.clocks_refused`)."""
    try:
        root = ElementTree.parse(Path(unzip_dir) / "modelDescription.xml").getroot()
    except (OSError, ElementTree.ParseError):
        return None
    problem = clocks_refused(root, interface)
    if problem:
        raise FmuFailure(f"{unit}: {problem}")
    names, vrs, kinds, xml, outputs = [], [], [], [], {}
    for element in root.iterfind("ModelVariables/Clock"):
        name, vr = element.get("name", ""), int(element.get("valueReference", "-1"))
        if element.get("causality") == "output":
            outputs[name] = vr
        if element.get("causality") != "input":
            continue
        kind = element.get("intervalVariability", "")
        names.append(name)
        vrs.append(vr)
        kinds.append(kind)
        xml.append(_xml_timing(element) if kind == "constant" or element.get("intervalDecimal") is not None
                   or element.get("intervalCounter") is not None else (None, 0.0))
    return UnitClocks(unit, names, vrs, kinds, xml, outputs) if names or outputs else None
