"""The functions a component calls itself, compiled (``NativeKernels(functions=...)``, see :mod:`.native`).

A component declares plain-float functions with their argument types; ``deltafmi build`` generates
their C from the Python source into the component's kernel library, with one exported entry
each: ``int dfmi_function_<name>(<arguments>, double *values)``, an argument's C type from its
declared type (a double or an int by value; n floats as ``const double *``; a dataclass of floats,
a NamedTuple or another tuple as a pointer to its struct), the result's numbers flattened into
``values``, 0 returned (else the line of a ``raise`` the kernel took). ``native_kernels.json``
describes each (:func:`FunctionSet.load`): ``{"args": [...], "result": ...}``, an argument
``"double"``, ``"int"``, ``"bool"``, ``{"floats": n}`` or ``{"struct": layout}`` (a layout
description of :mod:`.native_kernels`), the result ``"double"``, ``"int"``, ``"bool"`` or
``{"floats": n}``.

:class:`FunctionSet` is what the component sees (``self.native_functions``): one callable per
function, the compiled one (:class:`NativeFunction`: argument types set once, its float buffers
and structs allocated once, an argument's struct written again only when the value is not the
immutable one written last) or the Python function (:class:`PythonFunction`), both returning the
same: a number, or the flattened result as a new float64 array. A compiled call whose kernel
raised calls the Python function, which raises with its message (or computes what C could not).

Where a component's functions come from: in an FMU, its kernel library (the instance hands the
set to the component); in-process (tests, benchmarks, a master running components directly), the
library :func:`register_library` was given for the class (the builder's
``use_compiled_functions``); else, or with ``DELTAFMI_NATIVE=0`` in the environment, Python.
"""
from __future__ import annotations

import ctypes
import os
from pathlib import Path
from typing import Any, Callable, Mapping, Optional

import numpy as np

from .native_kernels import FieldWriter, _immutable, c_type

__all__ = ["FunctionSet", "NativeFunction", "PythonFunction", "flatten", "register_library"]

#: a class's compiled library for in-process use: class -> (library path, its description)
_REGISTERED: dict[type, tuple[str, dict]] = {}
_LIBRARIES: dict[str, ctypes.CDLL] = {}


def flatten(value: Any) -> Any:
    """A function's result as its callers get it: a number as it is, anything else (fixed-length
    tuples and lists of numbers, nested) as a new float64 array of its numbers in order."""
    if isinstance(value, (float, int)):
        return value
    if isinstance(value, np.ndarray):
        return np.array(value, dtype=float).reshape(-1)
    out: list = []
    _leaves(value, out)
    return np.array(out, dtype=float)


def _leaves(value: Any, out: list) -> None:
    for item in value:
        if isinstance(item, (float, int)):
            out.append(item)
        else:
            _leaves(item, out)


class PythonFunction:
    """A declared function run as Python (results as :func:`flatten` gives them)."""

    __slots__ = ("func", "__name__")
    compiled = False

    def __init__(self, func: Callable) -> None:
        self.func = func
        self.__name__ = getattr(func, "__name__", "function")

    def __call__(self, *args: Any) -> Any:
        return flatten(self.func(*args))


class _Struct:
    """One struct argument: its ctypes struct and writer, and the immutable value it holds."""

    __slots__ = ("struct", "writer", "address", "held")

    def __init__(self, layout: Any) -> None:
        self.struct = c_type(layout)()
        self.writer = FieldWriter(layout, 0)
        self.address = ctypes.addressof(self.struct)
        self.held: Any = self  # nothing written yet

    def __call__(self, value: Any) -> int:
        if value is not self.held:
            self.writer.write(self.struct, value)
            self.held = value if _immutable(value) else self
        return self.address


class _Floats:
    """One argument of n floats: copied into a buffer of its own."""

    __slots__ = ("buffer", "address")

    def __init__(self, n: int) -> None:
        self.buffer = np.zeros(n)
        self.address = self.buffer.ctypes.data

    def __call__(self, value: Any) -> int:
        self.buffer[:] = value
        return self.address


class NativeFunction:
    """A declared function's compiled entry, called with Python values (see the module docstring):
    :attr:`call` is a Python function made for its signature (one line of conversions and the
    ctypes call), what :class:`FunctionSet` hands out."""

    compiled = True

    def __init__(self, library: ctypes.CDLL, name: str, description: Mapping[str, Any], python: Callable) -> None:
        self.python = python
        entry = getattr(library, f"dfmi_function_{name}")
        argtypes, converted = [], []
        namespace: dict[str, Any] = {"entry": entry, "python": python, "flatten": flatten}
        for k, desc in enumerate(description["args"]):
            if desc == "double":
                argtypes.append(ctypes.c_double)
                converted.append(f"a{k}")  # ctypes takes floats, ints and numpy floats
            elif desc in ("int", "bool"):
                argtypes.append(ctypes.c_int)
                converted.append(f"int(a{k})")
            else:
                argtypes.append(ctypes.c_void_p)
                namespace[f"c{k}"] = _Floats(desc["floats"]) if "floats" in desc else _Struct(desc["struct"])
                converted.append(f"c{k}(a{k})")
        entry.argtypes = [*argtypes, ctypes.c_void_p]
        entry.restype = ctypes.c_int
        result = description["result"]
        scalar = {"double": "float", "int": "int", "bool": "bool"}.get(result) if isinstance(result, str) else None
        self.values = np.zeros(1 if scalar is not None else result["floats"])
        namespace.update(address=self.values.ctypes.data, item=memoryview(self.values).__getitem__,
                         values=self.values)
        params = ", ".join(f"a{k}" for k in range(len(converted)))
        source = (f"def {name}({params}):\n"
                  f"    if entry({', '.join([*converted, 'address'])}):\n"
                  f"        return flatten(python({params}))  # the kernel raised: Python raises with its message\n"
                  f"    return {f'{scalar}(item(0))' if scalar else 'values.copy()'}\n")
        exec(compile(source, f"<compiled function {name}>", "exec"), namespace)  # noqa: S102 (our own source)
        self.call = namespace[name]
        self.call.compiled = True
        self.call.__doc__ = getattr(python, "__doc__", None)

    def __call__(self, *args: Any) -> Any:
        return self.call(*args)


class FunctionSet:
    """A component's declared functions by name (attributes), compiled or Python; ``compiled``
    says whether all are the compiled ones."""

    def __init__(self, functions: Mapping[str, Any]) -> None:
        self.__dict__.update(functions)
        self._names = tuple(functions)
        self.compiled = all(getattr(f, "compiled", False) for f in functions.values())

    def __repr__(self) -> str:
        kind = "compiled" if self.compiled else "Python"
        return f"<FunctionSet {kind}: {', '.join(self._names) or 'none'}>"

    @classmethod
    def python(cls, declared: Mapping[str, Any]) -> FunctionSet:
        """The declared functions (``NativeKernels.functions``) as Python."""
        return cls({name: PythonFunction(f.func) for name, f in declared.items()})

    @classmethod
    def load(cls, library: ctypes.CDLL, descriptions: Mapping[str, Any], declared: Mapping[str, Any]) -> FunctionSet:
        """The declared functions from ``library`` where ``descriptions`` has them, Python otherwise."""
        return cls({name: NativeFunction(library, name, descriptions[name], f.func).call if name in descriptions
                    else PythonFunction(f.func) for name, f in declared.items()})

    @classmethod
    def for_class(cls, component_class: type) -> FunctionSet:
        """The functions of ``component_class`` in-process: from the library registered for it
        (:func:`register_library`), else Python (also with ``DELTAFMI_NATIVE=0``)."""
        native = getattr(component_class, "native", None)
        declared = native.functions if native is not None else {}
        registered = _REGISTERED.get(component_class)
        if registered is None or os.environ.get("DELTAFMI_NATIVE", "1") == "0":
            return cls.python(declared)
        path, description = registered
        return cls.load(library(path), description.get("functions", {}), declared)


def library(path: str | Path) -> ctypes.CDLL:
    """The shared library at ``path``, loaded once per process."""
    key = str(path)
    if key not in _LIBRARIES:
        _LIBRARIES[key] = ctypes.CDLL(key)
    return _LIBRARIES[key]


def register_library(component_class: type, path: Optional[str | Path], description: Optional[dict] = None) -> None:
    """The compiled kernel library (and its description) of ``component_class`` for in-process
    instances made from now on; ``path`` None forgets it (Python again)."""
    if path is None:
        _REGISTERED.pop(component_class, None)
    else:
        _REGISTERED[component_class] = (str(path), dict(description or {}))
