"""Variable declarations of a component: ``Parameter``, ``Input``, ``Output``, ``State``.

A declaration is a class attribute of a :class:`~deltafmi.runtime.Component`. It is also a data
descriptor: on an instance it reads and writes the component's FMI value buffers, so a model works
with ``self.q`` while the native FMI layer reads the very same memory without calling Python.
Array declarations become Modelica-style scalar FMI variables ``q[1]``, ``q[2]``, ...
(in FMI 3.0 builds one array variable ``q``). A declaration with ``type=`` an :class:`enum.IntEnum`
subclass is an FMI Enumeration, stored as an integer; the model reads a scalar as the member.
"""
from __future__ import annotations

import enum
import struct
from dataclasses import dataclass
from operator import methodcaller
from typing import Any, Optional, Sequence

import numpy as np

from .native_values import ValueDescriptor

__all__ = ["Experiment", "Input", "Output", "Parameter", "State", "Variable", "flatten", "is_enumeration"]

_TYPES = {float: "Real", int: "Integer", bool: "Boolean", str: "String"}
# what a declaration's descriptor does (Variable._kind; the first four as in _values.c)
_REAL_SCALAR, _REAL_ARRAY, _INT_SCALAR, _BOOL_SCALAR, _INT_ARRAY, _STR_SCALAR, _STR_ARRAY, _ENUM_SCALAR = range(8)


def is_enumeration(kind: Any) -> bool:
    """Whether ``kind`` (a declaration's ``type``) is an :class:`enum.IntEnum` subclass."""
    return isinstance(kind, enum.EnumMeta) and issubclass(kind, enum.IntEnum)


@dataclass(frozen=True)
class Experiment:
    """The FMU's default experiment (``<DefaultExperiment>``)."""

    start: float = 0.0
    stop: float = 1.0
    step: float = 1e-3
    tolerance: float = 1e-6


class Variable(ValueDescriptor):
    """Base declaration: one scalar or a 1-D array of scalars of one FMI type.

    ``name`` sets the FMI name when the attribute name cannot be used (``lambda`` is a Python
    keyword: ``lam = Output(shape=6, name="lambda")``).
    """

    causality = "local"

    def __init__(
        self,
        start: Any = None,
        *,
        shape: Optional[int] = None,
        type: Optional[type] = None,
        unit: str = "",
        description: str = "",
        min: Optional[float] = None,
        max: Optional[float] = None,
        nominal: Optional[float] = None,
        variability: Optional[str] = None,
        initial: Optional[str] = None,
        name: Optional[str] = None,
    ) -> None:
        super().__init__()  # the accessors are installed when the offset is set (below)
        if start is not None and not isinstance(start, (str, bool, int, float)):
            start_list = list(np.asarray(start).ravel().tolist())
            if shape is not None and shape != len(start_list):
                raise ValueError(f"start has {len(start_list)} values but shape is {shape}")
            shape = len(start_list)
        elif start is not None and shape is not None:
            start_list = [start] * shape
        else:
            start_list = None if start is None else [start]
        if type is None:
            sample = start_list[0] if start_list else 0.0
            type = (bool if isinstance(sample, bool) else str if isinstance(sample, str)
                    else sample.__class__ if isinstance(sample, enum.IntEnum) else float)
        if type not in _TYPES and not is_enumeration(type):
            raise TypeError(f"unsupported variable type {type!r}; use float, int, bool, str or an enum.IntEnum")
        if is_enumeration(type) and not len(type):
            raise TypeError(f"enumeration {type.__qualname__} has no members")
        self.type = type
        self.shape = shape
        size = 1 if shape is None else shape
        default = next(iter(type)) if is_enumeration(type) else {float: 0.0, int: 0, bool: False, str: ""}[type]
        self.start = [type(v) for v in start_list] if start_list else [default] * size
        self.unit = unit
        self.description = description
        self.min = min
        self.max = max
        self.nominal = nominal
        self.variability = variability or self._default_variability()
        self.initial = initial
        self.name = ""  # the Python attribute name, set by __set_name__
        self.fmi_name = name  # the FMI name when it differs (e.g. the keyword "lambda")
        self.offset = 0  # index of the first scalar in the component's buffer of this type

    # The descriptor runs on every access a model makes (several per evaluation). Compiled
    # (native_values.COMPILED, in every FMU built with Python headers) a declaration reads and
    # writes scalars and real arrays in C, from the addresses its component holds (see the top
    # of _values.c for what it takes). Everything else, and
    # everything without the compiled module, goes through the accessors installed below: a
    # getter that is a C-level call, operator.methodcaller, of a bound __getitem__ of the
    # component's buffers (Component._attach sets them), and the setter _set, for which the
    # offset setter derives what it needs once: which access it is (_kind), the end of the slice
    # and, for real arrays, a struct that packs a list or tuple straight into the buffer (about
    # twice as fast as numpy's slice assignment from a sequence).
    @property
    def offset(self) -> int:
        """Index of the first scalar in the component's buffer of this type (set by the layout)."""
        return self._offset

    @offset.setter
    def offset(self, value: int) -> None:
        self._offset = value
        self._end = value + self.size
        self._byte_offset = 8 * value
        if self.type is str:
            self._kind = _STR_SCALAR if self.shape is None else _STR_ARRAY
        elif self.type is float:
            self._kind = _REAL_SCALAR if self.shape is None else _REAL_ARRAY
        elif self.type is bool:
            self._kind = _BOOL_SCALAR if self.shape is None else _INT_ARRAY
        elif self.shape is None and is_enumeration(self.type):
            self._kind = _ENUM_SCALAR
        else:
            self._kind = _INT_SCALAR if self.shape is None else _INT_ARRAY
        self._pack = struct.Struct(f"={self.size}d") if self._kind == _REAL_ARRAY else None
        span = slice(value, self._end)
        getter = {_REAL_SCALAR: methodcaller("_real_item", value), _REAL_ARRAY: methodcaller("_real_items", span),
                  _INT_SCALAR: methodcaller("_int_item", value), _INT_ARRAY: methodcaller("_int_items", span),
                  _STR_SCALAR: methodcaller("_str_items", value), _STR_ARRAY: methodcaller("_str_items", span),
                  _BOOL_SCALAR: self._get_bool, _ENUM_SCALAR: self._get_enum}[self._kind]
        self._install(self._kind, value, span, getter, self._set)

    def __copy__(self) -> "Variable":
        """The same declaration for another class (a subclass inherits its base's declarations as
        copies, laid out anew). ``copy.copy``'s default cannot copy a property; the accessors are
        installed again when the layout sets the copy's offset."""
        clone = type(self).__new__(type(self))
        ValueDescriptor.__init__(clone)
        clone.__dict__.update(self.__dict__)
        return clone

    # --- naming -----------------------------------------------------------------------------
    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        self.fmi_name = self.fmi_name or name

    @property
    def size(self) -> int:
        """Number of scalar FMI variables this declaration stands for."""
        return 1 if self.shape is None else self.shape

    def scalar_names(self) -> list[str]:
        """FMI names of the scalars: ``x`` or ``x[1]``, ``x[2]``, ..."""
        if self.shape is None:
            return [self.fmi_name]
        return [f"{self.fmi_name}[{i + 1}]" for i in range(self.shape)]

    @property
    def fmi_type(self) -> str:
        """``Real``, ``Integer``, ``Boolean``, ``String`` or ``Enumeration``."""
        return "Enumeration" if is_enumeration(self.type) else _TYPES[self.type]

    @property
    def buffer(self) -> str:
        """Which value buffer holds the scalars: ``real``, ``int`` or ``str``."""
        return "int" if is_enumeration(self.type) else {float: "real", int: "int", bool: "int", str: "str"}[self.type]

    def _default_variability(self) -> str:
        return "continuous" if self.type is float else "discrete"

    # --- descriptor -------------------------------------------------------------------------
    def _get_bool(self, obj: Any) -> bool:
        return bool(obj._int_item(self._offset))

    def _get_enum(self, obj: Any) -> enum.IntEnum:
        return self.type(obj._int_item(self._offset))

    def _set(self, obj: Any, value: Any) -> None:
        kind = self._kind
        if kind == _REAL_SCALAR:
            if type(value) is float:
                obj._real_view[self._offset] = value
            else:
                obj._real[self._offset] = value  # numpy's conversions (ints, numpy scalars, ...)
        elif kind == _REAL_ARRAY:
            cls = type(value)
            if cls is list or cls is tuple:
                try:
                    self._pack.pack_into(obj._real, self._byte_offset, *value)
                    return
                except Exception:
                    pass  # not a flat sequence of numbers of the right length: numpy decides
            obj._real[self._offset:self._end] = value
        elif kind == _STR_SCALAR:
            obj._str[self._offset] = str(value)
        elif kind == _STR_ARRAY:
            obj._str[self._offset:self._end] = [str(v) for v in value]
        elif kind == _INT_ARRAY:
            obj._int[self._offset:self._end] = value
        else:
            obj._int[self._offset] = value


class Parameter(Variable):
    """A parameter: fixed during a run unless ``tunable=True`` (then changeable at events)."""

    causality = "parameter"

    def __init__(self, start: Any = None, *, tunable: bool = False, **kwargs: Any) -> None:
        kwargs.setdefault("variability", "tunable" if tunable else "fixed")
        super().__init__(start, **kwargs)


class Input(Variable):
    """An input, set by the importer; continuous for reals, discrete otherwise."""

    causality = "input"


class Output(Variable):
    """An output, computed by the component in ``outputs()``, ``derivatives()`` or ``update()``."""

    causality = "output"


class State(Variable):
    """A continuous state. The FMU also gets a derivative variable ``der(name)`` per scalar.

    ``initial="exact"`` (default) makes the start value settable before initialization;
    ``initial="calculated"`` means ``initialize()`` computes it (e.g. from a parameter).
    ``derivative_unit`` defaults to ``unit + "/s"``.
    """

    causality = "local"

    def __init__(self, start: Any = None, *, derivative_unit: Optional[str] = None, **kwargs: Any) -> None:
        kwargs.setdefault("initial", "exact")
        super().__init__(start, **kwargs)
        if self.type is not float:
            raise TypeError("continuous states must be real")
        self.derivative_unit = derivative_unit


def flatten(values: Sequence[Any]) -> np.ndarray:
    """Concatenate scalars and arrays into one float vector (used for derivative returns)."""
    if isinstance(values, np.ndarray):
        return values.ravel()
    return np.concatenate([np.atleast_1d(np.asarray(v, dtype=float)).ravel() for v in values]) if len(values) else np.zeros(0)
