"""Live sources as scenario components: what the resolver checks connections and records against.

A live source (``live:`` entry) and the pacing measurements (``realtime.lateness``,
``realtime.busy``, ``realtime.behind``) have no FMU; each gets a model description made here, of Real outputs with no
inputs, so connections, units and ``outputs:`` patterns are checked as for any component.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence, Tuple

from fmpy.model_description import ModelDescription, ModelVariable, Unknown

from .modelinfo import ModelInfo
from .system import ResolvedComponent
from .spec import ComponentSpec, LiveSpec

__all__ = ["LIVE", "REALTIME", "REALTIME_SIGNALS", "live_component", "realtime_component", "refuse_live"]

#: the interface of a component that is no FMU
LIVE = "LIVE"
#: the component holding the pacing measurements
REALTIME = "realtime"
#: its signals: (name, unit, description)
REALTIME_SIGNALS = (("lateness", "s", "How late this communication point was released"),
                    ("busy", "s", "Wall time the step before this point took (computing, not waiting)"),
                    ("behind", "", "1 when this point came more than a whole paced step late (the run fell behind)"))


def live_component(spec: LiveSpec) -> ResolvedComponent:
    """The component of live source ``spec``: one Real output per signal, value reference = its
    place in ``spec.signals``."""
    signals = [(s.name, s.unit, s.description or f"live input ({spec.kind})") for s in spec.signals]
    return _component(spec.name, spec.line, f"<live {spec.kind} source>", signals)


def realtime_component() -> ResolvedComponent:
    """The component whose outputs are the pacing measurements."""
    return _component(REALTIME, None, "<real-time pacing>", REALTIME_SIGNALS)


def _component(name: str, line, what: str, signals: Sequence[Tuple[str, str, str]]) -> ResolvedComponent:
    variables = [ModelVariable(name=signal, valueReference=vr, type="Real", causality="output",
                               variability="discrete", unit=unit or None, description=description)
                 for vr, (signal, unit, description) in enumerate(signals)]
    md = ModelDescription(fmiVersion="2.0", modelName=what, modelVariables=variables,
                          outputs=[Unknown(index=i + 1, variable=v, dependencies=[]) for i, v in enumerate(variables)])
    return ResolvedComponent(ComponentSpec(name, line), Path(what), ModelInfo(what, md), LIVE)


def refuse_live(system, what: str) -> None:
    """:class:`~deltafmi.errors.BadInput` when ``system`` has live sources or is paced: ``what``
    (an SSP export, a study, a linearization) has no place for them."""
    from deltafmi.errors import BadInput

    if system.live:
        names = ", ".join(c.name for c in system.live if c.name != REALTIME) or "none"
        raise BadInput(f"{what} cannot take a live run: {system.scenario.path} has live sources ({names}) or is "
                       "paced (master.realtime); use a copy of the scenario without them")
