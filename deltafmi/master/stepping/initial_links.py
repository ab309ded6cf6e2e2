"""The initialization's connections carried over in as few FMI calls as the order allows.

In initialization mode the master copies every connected output to its input, source before
target (``System.init_links``, in dependency order). One ``fmi2Get``/``fmi2Set`` call per scalar
costs a call into the FMU each (a flagship system has 18 such scalars); here the values a source
gives are read in one call per FMI type for all the links that read it before anything is set
into it again, and the values set into a target are set in one call per type just before it is
read or at the end. What each FMU sees is what the one-by-one copy gives it: a source is read
only after every value meant for it is set, and each input gets the same value (same
``factor * value + offset`` arithmetic) in the same order per type.

Units whose ``get_value``/``set_value`` are their own (FMI 3.0 arrays, live inputs) are read and
set one scalar at a time, as before.

Which calls these are depends on the links and on which units are read and set in batches only,
not on the values: they are worked out once per list of links (a study's cases share their
system's) and kept (:class:`_CopyPlan`); each run then makes those calls with its values.
"""
from __future__ import annotations

import threading
from typing import Any, Dict, List, Mapping, Sequence, Tuple

from ..scenario.system import Link, Port
from .unit_base import Unit, decoded

__all__ = ["copy_initial_links"]

_GETTERS = {"Real": "getReal", "Integer": "getInteger", "Boolean": "getBoolean", "String": "getString"}
_SETTERS = {"Real": "setReal", "Integer": "setInteger", "Boolean": "setBoolean", "String": "setString"}


def _batched(unit: Unit) -> bool:
    """Whether ``unit`` reads and sets through the FMI 2.0 calls of :class:`Unit` itself."""
    return type(unit).get_value is Unit.get_value and type(unit).set_value is Unit.set_value and not unit.fmi3


class _Pending:
    """Values waiting to be set into one unit: per FMI type, value references and values in order."""

    def __init__(self) -> None:
        self.by_type: Dict[str, Tuple[List[int], List[Any]]] = {}

    def add(self, port: Port, value: Any) -> bool:
        """Queue ``value`` for ``port``; False (nothing queued) when the port is queued already."""
        vrs, values = self.by_type.setdefault(port.type, ([], []))
        if port.vr in vrs:
            return False
        vrs.append(port.vr)
        values.append(value)
        return True

    def flush(self, unit: Unit) -> None:
        """Set everything queued (one call per type) and forget it."""
        for kind, (vrs, values) in self.by_type.items():
            unit.call(getattr(unit.fmu, _SETTERS[kind]), vrs, values)
        self.by_type.clear()


def copy_initial_links(links: Sequence[Link], by_name: Mapping[str, Unit], loops: Any = None) -> None:
    """Set every link's target from its source, in order. ``loops``: the initialization's loops
    (:class:`~.algebraic_loops.InitialLoops`); a link of a loop is solved with the rest of its
    loop when the copy reaches it, and with loops the copy goes one scalar at a time (a solve
    reads and sets the units in between)."""
    if loops is not None and loops.loops:
        for link in links:
            if loops.solve_with(link):
                continue
            value = by_name[link.source.component].get_value(link.source)
            if link.source.type == "Real":
                value = link.factor * value + link.offset
            by_name[link.target.component].set_value(link.target, value)
        return
    _CopyPlan.of(links, by_name).run(by_name)


def _copy_one_by_one(links: Sequence[Link], by_name: Mapping[str, Unit]) -> None:
    """What :class:`_CopyPlan` plans, made as it goes (the reference for its calls)."""
    pending: Dict[str, _Pending] = {}
    read: Dict[str, Dict[Tuple[str, int], Any]] = {}  # values read from a unit since its last set
    chosen = list(links)
    for position, link in enumerate(chosen):
        source, target = by_name[link.source.component], by_name[link.target.component]
        waiting = pending.get(source.name)
        if waiting is not None and waiting.by_type:
            waiting.flush(source)
            read.pop(source.name, None)
        if _batched(source):
            known = read.setdefault(source.name, {})
            key = (link.source.type, link.source.vr)
            if key not in known:
                known.update(_read_ahead(source, link.source.type, chosen[position:]))
            value = known[key]
        else:
            value = source.get_value(link.source)
        if link.source.type == "Real":
            value = link.factor * value + link.offset
        if not _batched(target):
            target.set_value(link.target, value)
            continue
        queue = pending.setdefault(target.name, _Pending())
        if not queue.add(link.target, value):  # set twice: the first value goes in first
            queue.flush(target)
            queue.add(link.target, value)
        read.pop(target.name, None)
    for name, queue in pending.items():
        queue.flush(by_name[name])


def _ahead(name: str, kind: str, links: Sequence[Link]) -> List[int]:
    """The value references of type ``kind`` that ``links`` (the first reads unit ``name``) read
    from that unit before the next link into it, in order."""
    vrs: List[int] = [links[0].source.vr]
    for link in links:
        if link.target.component == name:
            break
        if link.source.component == name and link.source.type == kind and link.source.vr not in vrs:
            vrs.append(link.source.vr)
    return vrs


def _read(source: Unit, kind: str, vrs: List[int]) -> List[Any]:
    """The values of ``vrs`` read in one call (as :meth:`Unit.get_value` returns them: bool, str)."""
    values = list(source.call(getattr(source.fmu, _GETTERS[kind]), vrs))
    if kind == "String":
        return decoded(values)
    if kind == "Boolean":
        return [bool(v) for v in values]
    return values


def _read_ahead(source: Unit, kind: str, links: Sequence[Link]) -> Dict[Tuple[str, int], Any]:
    """:func:`_ahead`'s values of ``source`` read in one call, by (type, value reference)."""
    vrs = _ahead(source.name, kind, links)
    return {(kind, vr): value for vr, value in zip(vrs, _read(source, kind, vrs))}


_READ, _GET, _SCALE, _SET, _FLUSH = range(5)


class _CopyPlan:
    """The calls of :func:`copy_initial_links` for one list of links, whose units read and set in
    batches or not as ``batched`` says, in order: each a step on slots of a list of values (the
    values read, and each Real link's ``factor * value + offset``), the same calls with the same
    arguments :func:`_copy_one_by_one` makes."""

    #: plans kept, by the links' identity (the links kept with them), the oldest dropped beyond
    KEEP = 16
    _kept: Dict[int, Tuple[Sequence[Link], Tuple[Tuple[str, bool], ...], "_CopyPlan"]] = {}
    _lock = threading.Lock()

    def __init__(self, links: Sequence[Link], batched: Mapping[str, bool]) -> None:
        self.steps: List[Tuple[Any, ...]] = []
        self.size = 0
        pending: Dict[str, Dict[str, Tuple[List[int], List[int]]]] = {}  # unit -> type -> (vrs, slots)
        read: Dict[str, Dict[Tuple[str, int], int]] = {}  # unit -> (type, vr) -> slot, since its last set
        chosen = list(links)
        for position, link in enumerate(chosen):
            source, target = link.source.component, link.target.component
            if pending.get(source):
                self._flush(pending, source)
                read.pop(source, None)
            if batched[source]:
                known = read.setdefault(source, {})
                key = (link.source.type, link.source.vr)
                if key not in known:
                    vrs = _ahead(source, link.source.type, chosen[position:])
                    slots = self._slots(len(vrs))
                    self.steps.append((_READ, source, link.source.type, vrs, slots))
                    known.update({(link.source.type, vr): slot for vr, slot in zip(vrs, slots)})
                value = known[key]
            else:
                value = self._slots(1)[0]
                self.steps.append((_GET, source, link.source, value))
            if link.source.type == "Real":
                scaled = self._slots(1)[0]
                self.steps.append((_SCALE, value, link.factor, link.offset, scaled))
                value = scaled
            if not batched[target]:
                self.steps.append((_SET, target, link.target, value))
                continue
            queue = pending.setdefault(target, {})
            if link.target.vr in queue.get(link.target.type, ((), ()))[0]:  # set twice: the first value goes in first
                queue = self._flush(pending, target)
            vrs, slots = queue.setdefault(link.target.type, ([], []))
            vrs.append(link.target.vr)
            slots.append(value)
            read.pop(target, None)
        for name in list(pending):
            if pending[name]:
                self._flush(pending, name)

    def _slots(self, n: int) -> List[int]:
        first, self.size = self.size, self.size + n
        return list(range(first, self.size))

    def _flush(self, pending: Dict[str, Dict[str, Tuple[List[int], List[int]]]], name: str) -> Dict[str, Any]:
        """Everything queued for unit ``name`` set (one call per type); its new, empty queue."""
        self.steps.append((_FLUSH, name, [(kind, vrs, slots) for kind, (vrs, slots) in pending[name].items()]))
        queue = pending[name] = {}
        return queue

    @classmethod
    def of(cls, links: Sequence[Link], by_name: Mapping[str, Unit]) -> "_CopyPlan":
        """The plan of ``links`` for these units, made once (kept by the links' identity)."""
        names = {name for link in links for name in (link.source.component, link.target.component)}
        batched = tuple(sorted((name, _batched(by_name[name])) for name in names))
        kept = cls._kept.get(id(links))
        if kept is not None and kept[0] is links and kept[1] == batched:
            return kept[2]
        plan = cls(links, dict(batched))
        with cls._lock:
            cls._kept.pop(id(links), None)
            cls._kept[id(links)] = (links, batched, plan)
            while len(cls._kept) > cls.KEEP:
                cls._kept.pop(next(iter(cls._kept)))
        return plan

    def run(self, by_name: Mapping[str, Unit]) -> None:
        """Make the planned calls on the units ``by_name``."""
        values: List[Any] = [None] * self.size
        for step in self.steps:
            what = step[0]
            if what == _SCALE:
                _, value, factor, offset, scaled = step
                values[scaled] = factor * values[value] + offset
            elif what == _READ:
                _, name, kind, vrs, slots = step
                for slot, value in zip(slots, _read(by_name[name], kind, vrs)):
                    values[slot] = value
            elif what == _FLUSH:
                unit = by_name[step[1]]
                for kind, vrs, slots in step[2]:
                    unit.call(getattr(unit.fmu, _SETTERS[kind]), list(vrs), [values[i] for i in slots])
            elif what == _GET:
                values[step[3]] = by_name[step[1]].get_value(step[2])
            else:
                by_name[step[1]].set_value(step[2], values[step[3]])
