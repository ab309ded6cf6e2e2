"""The types of the kernel code generator (deltafmi.builder.codegen): what a value is in C.

Scalars (``D`` double, ``I`` int, ``B`` bool as int, ``S`` string, ``NONE``), fixed-length
sequences and NamedTuples/records (:class:`Tup`, a C struct), Optional values (:class:`Opt`, a
struct with a flag), dataclass parameter objects (:class:`Obj`, a const pointer), and the entry
description :class:`Entry`. Types are values: a function is specialized once per tuple of
argument types.
"""
from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, field
from typing import Any, Callable, Optional

from deltafmi.errors import DeltaFmiError

__all__ = ["B", "CodegenError", "D", "Entry", "Fn", "I", "NONE", "Obj", "Opt", "Poison", "S", "Scalar", "Tup", "Vec",
           "describe", "named", "record"]



class CodegenError(DeltaFmiError):
    """A construct the generator cannot translate; the message names file:line."""


@dataclass(frozen=True)
class Scalar:
    c: str  #: "double", "int", "bool", "str", "none"


D, I, B = Scalar("double"), Scalar("int"), Scalar("bool")
S, NONE = Scalar("str"), Scalar("none")


@dataclass(frozen=True)
class Tup:
    items: tuple  #: element types
    names: Optional[tuple] = None  #: field names (a NamedTuple or a record)
    cname: Optional[str] = None  #: the class name, for the C struct's name
    #: the NamedTuple class, to build its values back from C (not part of the type's identity)
    cls: Optional[type] = field(default=None, compare=False)

    @property
    def uniform(self) -> bool:
        """All elements of one type (and no field names): a C array."""
        return self.names is None and len(self.items) > 0 and all(t == self.items[0] for t in self.items)

    @property
    def homogeneous(self) -> bool:
        """A flat float sequence."""
        return self.uniform and self.items[0] == D


@dataclass(frozen=True)
class Opt:
    inner: Any  #: the value's type when it is not None


@dataclass(frozen=True)
class Obj:
    cls: type  #: a dataclass whose fields are all floats, passed as ``const Struct *``


@dataclass(frozen=True)
class Fn:
    name: str  #: a math function bound to a local name (``sin = math.sin``)


@dataclass(frozen=True)
class Poison:
    types: tuple  #: a name whose type differs between the branches that join


def Vec(n: int) -> Tup:
    """A fixed-length float sequence (tuple or list) of ``n`` elements."""
    return Tup((D,) * n)


def named(cls: type) -> Tup:
    """The type of a NamedTuple class from its annotations (float, int, bool, str, fixed-length
    tuples, other NamedTuples, Optional[...] of these)."""
    hints = typing.get_type_hints(cls)
    return Tup(tuple(_type_of_hint(hints[f], f"{cls.__name__}.{f}") for f in cls._fields), tuple(cls._fields),
               cls.__name__, cls)


def record(obj: Any) -> Tup:
    """The type of an object's attributes that a kernel can read (floats, ints, bools, strings
    and fixed-length sequences of them; others, e.g. numpy arrays, are left out)."""
    names, items = [], []
    for name, value in vars(obj).items():
        try:
            items.append(_type_of_value(value, ""))
        except CodegenError:
            continue
        names.append(name)
    return Tup(tuple(items), tuple(names), type(obj).__name__)


def _type_of_hint(hint: Any, where: str) -> Any:
    if hint is float:
        return D
    if hint is bool:
        return B
    if hint is int:
        return I
    if hint is str:
        return S
    if isinstance(hint, type) and issubclass(hint, tuple) and hasattr(hint, "_fields"):
        return named(hint)
    if typing.get_origin(hint) is tuple and Ellipsis not in typing.get_args(hint):
        return Tup(tuple(_type_of_hint(h, where) for h in typing.get_args(hint)))
    args = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType) and len(args) == 2 and type(None) in args:
        return Opt(_type_of_hint(args[0] if args[1] is type(None) else args[1], where))  # Optional[X]
    raise CodegenError(f"{where}: type {hint!r} has no fixed C layout")


@dataclass
class Entry:
    """An exported C function: ``c_name`` runs ``func`` specialized on ``args``."""

    c_name: str
    func: Callable
    args: list


def _type_of_value(value: Any, where: str) -> Any:
    if isinstance(value, bool):
        return B
    if isinstance(value, int):
        return I
    if isinstance(value, float):
        return D
    if isinstance(value, str):
        return S
    if isinstance(value, tuple) and hasattr(value, "_fields"):
        return Tup(tuple(_type_of_value(v, where) for v in value), tuple(value._fields), type(value).__name__)
    if isinstance(value, (tuple, list)) and value:
        return Tup(tuple(_type_of_value(v, where) for v in value))
    raise CodegenError(f"{where}: a constant must be a number, a string or a non-empty tuple of them, "
                       f"not {type(value).__name__}")


def _unify(a: Any, b: Any) -> Optional[Any]:
    """The type both a and b convert to at a join (None: they do not)."""
    if a == b:
        return a
    if {a, b} == {I, D}:
        return D
    for x, y in ((a, b), (b, a)):
        if x == NONE:
            return y if isinstance(y, Opt) else Opt(y)
        if isinstance(x, Opt) and x.inner == y:
            return x
    return None


def describe(t: Any) -> Any:
    """The layout description of a kernel type (see deltafmi/runtime/native_kernels.py): what the
    FMU runtime builds its C structs from."""
    if t in (D, I, B, S):
        return {D: "double", I: "int", B: "bool", S: "str"}[t]
    if isinstance(t, Obj):
        return {"object": [f.name for f in dataclasses.fields(t.cls)]}
    if isinstance(t, Opt):
        return {"optional": describe(t.inner)}
    if isinstance(t, Tup) and t.uniform:
        return {"array": describe(t.items[0]), "n": len(t.items)}
    if isinstance(t, Tup) and t.names:
        return {"record": [[name, describe(item)] for name, item in zip(t.names, t.items)]}
    if isinstance(t, Tup):
        return {"tuple": [describe(item) for item in t.items]}
    raise CodegenError(f"no run-time layout for {t!r}")
