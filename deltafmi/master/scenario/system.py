"""A scenario resolved against its FMUs: what the master runs.

:class:`System` is what :func:`~deltafmi.master.scenario.resolve.resolve_system` returns: the
components with their FMUs read (:class:`ResolvedComponent`), the connections as scalar
:class:`Link` s between :class:`Port` s, the recorded variables, the stepping order and the
algebraic loops.
"""
from __future__ import annotations

from dataclasses import field
from pathlib import Path
from typing import Any, List, Optional, Tuple

from deltafmi.errors import Diagnostic

from .records import record
from .modelinfo import ModelInfo
from .spec import ComponentSpec, Scenario

__all__ = ["AlgebraicLoop", "Link", "Port", "ResolvedComponent", "System", "SystemInterface", "bus_type"]

_TYPE_NAMES = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean",
               "String": "String",
               # FMI 3.0: each type on the bus that holds all its values (see Port.type)
               "Float64": "Real", "Float32": "Real", "Int8": "Integer", "UInt8": "Integer", "Int16": "Integer",
               "UInt16": "Integer", "Int32": "Integer", "UInt32": "Int64", "Int64": "Int64", "UInt64": "UInt64"}
_FMI2_EQUIVALENT = {"Float64": "Real", "Int32": "Integer"}

def bus_type(fmi_type: str) -> str:
    """The bus an FMI 2.0 or 3.0 variable type travels on: Real, Integer, Int64, UInt64, Boolean,
    String; other types (Binary, Clock) by their own name."""
    return _TYPE_NAMES.get(fmi_type, fmi_type)



@record
class Port:
    """One scalar variable of one component."""

    component: str
    name: str
    vr: int
    #: the bus its values travel on: Real (also Float32), Integer (also Enumeration and the FMI 3.0
    #: integers up to Int32), Int64 (UInt32, Int64), UInt64, Boolean, String
    type: str
    unit: str = ""
    enumeration: str = ""  # the declared type's name for an Enumeration variable
    #: the FMI 3.0 type (Float64, Int8, ...); "" for an FMI 2.0 variable
    fmi_type: str = ""
    #: the element's place (row-major) in its FMI 3.0 array variable; 0 for a scalar
    index: int = 0

    @property
    def ref(self) -> str:
        """``component.variable``."""
        return f"{self.component}.{self.name}"

    @property
    def type_name(self) -> str:
        """The FMI type as a user reads it: ``Real``, ``Float32``, ..., ``Enumeration 'Color'``."""
        return f"Enumeration '{self.enumeration}'" if self.enumeration else (self.fmi_type or self.type)

    @property
    def same_type_as(self) -> str:
        """What two connected variables must share: FMI 2.0's Real and Integer are FMI 3.0's
        Float64 and Int32."""
        return _FMI2_EQUIVALENT.get(self.type_name, self.type_name)


@record
class Link:
    """A scalar connection ``target = factor * source + offset``."""

    source: Port
    target: Port
    factor: float = 1.0
    offset: float = 0.0
    line: Optional[int] = None


@record
class AlgebraicLoop:
    """Connections that close a cycle of direct feedthrough: the master solves them together.

    ``members`` step (or, at initialization, are evaluated) in this order, each taking the
    fresh outputs of those before it; ``tears`` are the outputs read by a member at or before
    their own component in that order: their values are guessed and iterated on (see
    :mod:`deltafmi.master.stepping.algebraic_loops`).
    """

    members: Tuple[str, ...]
    links: Tuple[Link, ...]
    tears: Tuple[Port, ...]
    line: Optional[int] = None
    initial: bool = False  # a loop of the initialization (from <InitialUnknowns>)

    def __str__(self) -> str:
        connections = ", ".join(f"{l.source.ref} -> {l.target.ref}" for l in self.links)
        where = f"; line {self.line}" if self.line is not None else ""
        return f"algebraic loop {connections} ({', '.join(self.members)}{where})"


@record(frozen=False)
class ResolvedComponent:
    """A scenario component with its FMU located, read and its start values checked."""

    spec: ComponentSpec
    fmu: Path
    info: ModelInfo
    interface: str
    start_values: List[Tuple[Port, Any]] = field(default_factory=list)

    @property
    def name(self) -> str:
        """Instance name in the scenario."""
        return self.spec.name


@record
class SystemInterface:
    """The variables a scenario exported as one FMU offers (``exports:`` or the defaults):
    each a variable of one of its components, under the same name (``plant.z[1]``)."""

    outputs: Tuple[Port, ...] = ()
    inputs: Tuple[Port, ...] = ()
    parameters: Tuple[Port, ...] = ()


@record(frozen=False)
class System:
    """Everything the master needs: components, scalar links, recorded variables, orders."""

    scenario: Scenario
    components: List[ResolvedComponent]
    links: List[Link]
    recorded: List[Port]
    order: List[str]
    init_links: List[Link]
    warnings: List[Diagnostic]
    #: algebraic loops solved at every step, and those solved during initialization
    loops: List[AlgebraicLoop] = field(default_factory=list)
    init_loops: List[AlgebraicLoop] = field(default_factory=list)
    #: live input sources (and the pacing measurements of a paced run): components with no FMU
    live: List[ResolvedComponent] = field(default_factory=list)
    #: each ``streams:`` entry's signals, resolved (in the order of :attr:`Scenario.streams`)
    streamed: List[List[Port]] = field(default_factory=list)
    #: what the scenario exported as one FMU offers
    interface: SystemInterface = SystemInterface()
