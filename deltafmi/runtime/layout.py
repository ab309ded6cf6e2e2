"""Where every scalar of a component lives: buffers, value references, FMI attributes.

The real buffer is ordered ``[states | derivatives | other reals]`` so that the native layer can
copy continuous states and derivatives as contiguous blocks. Value references are global:
reals ``0 .. n_real-1``, then integers/booleans, then strings.

FMI 3.0 builds name each declaration (scalar or 1-D array) ONE variable whose value reference is
that of its first scalar, so the buffers and the scalar value references are the same for both
versions (:attr:`Layout.sizes3` gives the element counts the native layer needs).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np

from .clocks import Clock, check_clock
from .variables import Parameter, Input, State, Variable, is_enumeration

__all__ = ["Layout", "ScalarVariable", "build_layout"]

# Bits of the per-scalar flag byte read by the native layer (keep in sync with native/core.h).
SET_INSTANTIATED = 1
SET_INITIALIZATION = 2
SET_EVENT = 4  # event mode (ME) and step complete (CS)
SET_CONTINUOUS = 8
IS_BOOLEAN = 16
IS_ENUMERATION = 32  # an Enumeration in the int buffer (FMI 3.0 reads it with fmi3GetInt64)


@dataclass
class ScalarVariable:
    """One ``<ScalarVariable>`` of the model description."""

    name: str
    value_reference: int
    fmi_type: str
    causality: str
    variability: str
    initial: Optional[str]
    start: Any
    unit: str = ""
    description: str = ""
    min: Optional[float] = None
    max: Optional[float] = None
    nominal: Optional[float] = None
    derivative_of: Optional[int] = None  # 1-based index of the state in the variable list
    declaration: Optional[Variable] = None
    flags: int = 0


@dataclass
class Layout:
    """The complete variable layout of a component class."""

    declarations: list[Variable]
    scalars: list[ScalarVariable] = field(default_factory=list)
    n_real: int = 0
    n_int: int = 0
    n_str: int = 0
    nx: int = 0
    real_start: np.ndarray = field(default_factory=lambda: np.zeros(0))
    int_start: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int32))
    str_start: list[str] = field(default_factory=list)
    flags: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.uint8))
    nominals: np.ndarray = field(default_factory=lambda: np.ones(0))
    #: FMI 3.0: ``sizes3[v]`` is the element count of the variable whose value reference is ``v``
    #: (the first scalar of a declaration, or of a derivative array), 0 for every other scalar
    sizes3: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.uint32))
    #: FMI 3.0 Clocks: value references ``time_vr + 1 .. time_vr + n_clocks``
    n_clocks: int = 0
    clocks: list[Clock] = field(default_factory=list)
    #: per Clock: the real-buffer index of its period Parameter, -1 for a constant interval ...
    clock_period_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: ... and the constant interval (NaN where a Parameter gives it)
    clock_interval: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def n_total(self) -> int:
        """Number of scalars (value references ``0 .. n_total-1``)."""
        return self.n_real + self.n_int + self.n_str

    @property
    def time_vr(self) -> int:
        """FMI 3.0: value reference of the independent variable ``time`` (after all scalars)."""
        return self.n_total

    @property
    def first_indicator_vr(self) -> int:
        """FMI 3.0: value reference of the first event-indicator variable (after the Clocks);
        event indicator ``i`` (0-based) is ``first_indicator_vr + i``."""
        return self.n_total + 1 + self.n_clocks

    @property
    def x_offset(self) -> int:
        """Index of the first continuous state in the real buffer."""
        return 0

    @property
    def dx_offset(self) -> int:
        """Index of the first derivative in the real buffer."""
        return self.nx

    def by_name(self) -> dict[str, ScalarVariable]:
        """Scalars keyed by FMI name."""
        return {s.name: s for s in self.scalars}

    def variables3(self) -> list[list[ScalarVariable]]:
        """The FMI 3.0 variables in value-reference order, each as the scalars it stands for: a
        declaration's scalars, or the derivatives of one array state (``der(q)``)."""
        groups: list[list[ScalarVariable]] = []
        previous = None
        for s in self.scalars:
            key = _group_key(self, s)
            if key == previous:
                groups[-1].append(s)
            else:
                groups.append([s])
            previous = key
        return groups


def _group_key(layout: Layout, s: ScalarVariable) -> tuple[int, bool]:
    owner = layout.scalars[s.derivative_of - 1].declaration if s.derivative_of else s.declaration
    return id(owner), s.derivative_of is not None


def collect_declarations(cls: type) -> list[Variable]:
    """All variable declarations of ``cls`` in declaration order, base classes first.

    Inherited declarations are copied onto ``cls`` because a descriptor stores its buffer offset,
    and a subclass with more variables has a different layout than its base.
    """
    declarations = []
    for name, value in _declared(cls, Variable).items():
        if name not in vars(cls):
            value = copy.copy(value)
            setattr(cls, name, value)
        declarations.append(value)
    return declarations


def _declared(cls: type, kind: type) -> dict[str, Any]:
    """The class attributes of ``cls`` that are ``kind`` instances, by name, in declaration order
    (base classes first; a redefinition takes the place of the last definition)."""
    seen: dict[str, Any] = {}
    for klass in reversed(cls.__mro__):
        for name, value in vars(klass).items():
            if isinstance(value, kind):
                seen.pop(name, None)
                seen[name] = value
    return seen


def _setter_flags(decl: Variable) -> int:
    if isinstance(decl, Parameter):
        base = SET_INSTANTIATED | SET_INITIALIZATION
        return base | SET_EVENT if decl.variability == "tunable" else base
    if isinstance(decl, Input):
        base = SET_INSTANTIATED | SET_INITIALIZATION | SET_EVENT
        return base | SET_CONTINUOUS if decl.variability == "continuous" else base
    if isinstance(decl, State) and decl.initial in ("exact", "approx"):
        return SET_INSTANTIATED | SET_INITIALIZATION
    return 0


def _initial(decl: Variable) -> Optional[str]:
    if isinstance(decl, State):
        return decl.initial
    if decl.causality == "output":
        return "calculated" if decl.initial is None else decl.initial
    return None  # parameters/inputs: the default (exact) applies


def build_layout(cls: type) -> Layout:
    """Compute the layout of a component class (states, derivatives, other reals, ints, strings)."""
    decls = collect_declarations(cls)
    states = [d for d in decls if isinstance(d, State)]
    reals = [d for d in decls if d.buffer == "real" and not isinstance(d, State)]
    ints = [d for d in decls if d.buffer == "int"]
    strs = [d for d in decls if d.buffer == "str"]
    layout = Layout(declarations=decls)
    layout.nx = sum(d.size for d in states)

    real_rows: list[ScalarVariable] = []
    offset = 0
    for d in states:
        d.offset = offset
        for i, name in enumerate(d.scalar_names()):
            real_rows.append(_scalar(d, name, offset + i, d.start[i]))
        offset += d.size
    for d in states:  # derivatives follow the states, scalar by scalar
        unit = d.derivative_unit if d.derivative_unit is not None else (f"{d.unit}/s" if d.unit else "")
        for i, name in enumerate(d.scalar_names()):
            real_rows.append(ScalarVariable(
                name=f"der({name})", value_reference=offset, fmi_type="Real", causality="local",
                variability="continuous", initial="calculated", start=None, unit=unit,
                description=f"Time derivative of {name}", derivative_of=d.offset + i + 1))
            offset += 1
    for d in reals:
        d.offset = offset
        for i, name in enumerate(d.scalar_names()):
            real_rows.append(_scalar(d, name, offset + i, d.start[i]))
        offset += d.size
    layout.n_real = offset

    int_rows, str_rows = [], []
    offset = 0
    for d in ints:
        d.offset = offset
        for i, name in enumerate(d.scalar_names()):
            int_rows.append(_scalar(d, name, layout.n_real + offset + i, d.start[i]))
        offset += d.size
    layout.n_int = offset
    offset = 0
    for d in strs:
        d.offset = offset
        for i, name in enumerate(d.scalar_names()):
            str_rows.append(_scalar(d, name, layout.n_real + layout.n_int + offset + i, d.start[i]))
        offset += d.size
    layout.n_str = offset

    layout.scalars = real_rows + int_rows + str_rows
    layout.real_start = np.array([r.start if r.start is not None else 0.0 for r in real_rows], dtype=float)
    layout.int_start = np.array([int(r.start) for r in int_rows], dtype=np.int32)
    layout.str_start = [r.start for r in str_rows]
    layout.flags = np.array([r.flags for r in real_rows + int_rows], dtype=np.uint8)
    layout.nominals = np.array([r.nominal or 1.0 for r in real_rows[:layout.nx]], dtype=float)
    layout.sizes3 = np.zeros(layout.n_total, dtype=np.uint32)
    for group in layout.variables3():
        layout.sizes3[group[0].value_reference] = len(group)
    _lay_out_clocks(cls, layout)
    return layout


#: the native layer keeps the Clocks' activation in one 64-bit mask
MAX_CLOCKS = 64


def _lay_out_clocks(cls: type, layout: Layout) -> None:
    layout.clocks = list(_declared(cls, Clock).values())
    layout.n_clocks = len(layout.clocks)
    if layout.n_clocks > MAX_CLOCKS:
        raise ValueError(f"{cls.__qualname__}: {layout.n_clocks} Clocks; at most {MAX_CLOCKS} are supported")
    by_name = {d.name: d for d in layout.declarations}
    for clock in layout.clocks:
        check_clock(cls, clock, by_name)
    layout.clock_period_index = np.array([-1 if c.constant else by_name[c.period].offset for c in layout.clocks],
                                         dtype=np.int64)
    layout.clock_interval = np.array([c.period if c.constant else np.nan for c in layout.clocks], dtype=float)


def _scalar(decl: Variable, name: str, vr: int, start: Any) -> ScalarVariable:
    flags = (_setter_flags(decl) | (IS_BOOLEAN if decl.type is bool else 0)
             | (IS_ENUMERATION if is_enumeration(decl.type) else 0))
    initial = _initial(decl)
    return ScalarVariable(
        name=name, value_reference=vr, fmi_type=decl.fmi_type, causality=decl.causality,
        variability=decl.variability, initial=initial,
        start=start, unit=decl.unit,
        description=decl.description, min=decl.min, max=decl.max, nominal=decl.nominal,
        declaration=decl, flags=flags)
