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
"""
from __future__ import annotations

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


def _read_ahead(source: Unit, kind: str, links: Sequence[Link]) -> Dict[Tuple[str, int], Any]:
    """The values of type ``kind`` that ``links`` (the first reads ``source``) read from ``source``
    before the next link into it, read in one call (as :meth:`Unit.get_value` returns them: bool, str)."""
    vrs: List[int] = [links[0].source.vr]
    for link in links:
        if link.target.component == source.name:
            break
        if link.source.component == source.name and link.source.type == kind and link.source.vr not in vrs:
            vrs.append(link.source.vr)
    values = list(source.call(getattr(source.fmu, _GETTERS[kind]), vrs))
    if kind == "String":
        values = decoded(values)
    elif kind == "Boolean":
        values = [bool(v) for v in values]
    return {(kind, vr): value for vr, value in zip(vrs, values)}
