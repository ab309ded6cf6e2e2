"""Dataclasses that cost less to define: the master's records of a scenario and of a run.

:func:`record` makes a class a dataclass (``frozen`` or not) with the ``__repr__``, ``__eq__`` and
``__hash__`` that ``@dataclass`` gives it, the same values, from three functions shared by every
record instead of functions generated for each class. ``dataclasses`` compiles every method it
generates from source text when the class is defined (six for a frozen class), and a run defines
a few dozen records before its first step; here it compiles only ``__init__`` and, for a frozen
class, ``__setattr__`` and ``__delattr__``. :func:`dataclasses.fields`,
:func:`dataclasses.replace` and :func:`dataclasses.asdict` work as for any dataclass.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Callable, Optional, Tuple, TypeVar, overload

__all__ = ["record"]

T = TypeVar("T", bound=type)

#: the attribute of a record class naming its fields that repr, eq and hash use, in order
_FIELDS = "__record_fields__"


@overload
def record(cls: T) -> T: ...


@overload
def record(cls: None = None, *, frozen: bool = True) -> Callable[[T], T]: ...


def record(cls: Optional[T] = None, *, frozen: bool = True) -> Any:
    """``@dataclass(frozen=frozen)`` for ``cls``, its ``__repr__``, ``__eq__`` and ``__hash__``
    shared (as ``@dataclass`` makes them: a frozen record hashes its fields, another one is
    unhashable). Used as ``@record`` or ``@record(frozen=False)``."""
    def wrap(cls: T) -> T:
        cls = dataclass(frozen=frozen, repr=False, eq=False)(cls)
        setattr(cls, _FIELDS, tuple(f.name for f in fields(cls)))
        cls.__repr__ = _repr
        cls.__eq__ = _eq
        cls.__hash__ = _hash if frozen else None
        return cls

    return wrap if cls is None else wrap(cls)


def _values(obj: Any) -> Tuple[Any, ...]:
    return tuple([getattr(obj, name) for name in getattr(obj, _FIELDS)])


def _repr(self: Any) -> str:
    values = ", ".join(f"{name}={getattr(self, name)!r}" for name in getattr(self, _FIELDS))
    return f"{type(self).__qualname__}({values})"


def _eq(self: Any, other: Any) -> Any:
    if other.__class__ is self.__class__:
        return _values(self) == _values(other)
    return NotImplemented


def _hash(self: Any) -> int:
    return hash(_values(self))
