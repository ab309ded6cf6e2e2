"""Serialized FMU states: loading them without running what the bytes name.

``fmi2DeSerializeFMUstate`` (and FMI 3.0's) takes bytes from the importer, which may have read
them from a file anyone could have written. A plain :func:`pickle.loads` calls whatever callable
the bytes name (``os.system`` included) and imports whatever module they name. The loader here
resolves only what an FMU state holds, from modules already loaded (the bytes import nothing):
classes and functions of the model's own code (its module, those under the FMU's resources
folder, deltafmi's physics and models), classes of deltafmi's runtime, numpy's arrays, dtypes
and scalars with their constructors, and a few value types of the standard library; anything
else (``os.system``, ``eval``, numpy's memmap) is refused with the name it asked for. A name
resolves only to what is defined under that name (``numpy`` found as an attribute of the model's
module is not the model's code), and the bytes call only what is made to be rebuilt by a call
(value types, numpy's constructors, a class with its own ``__reduce__``): the model's and the
runtime's other classes are made without their ``__init__`` (which may load a library), as
:mod:`pickle` makes them for a state it wrote.
"""
from __future__ import annotations

import builtins
import io
import os
import pickle
import sys
import types
from typing import Any, Optional

import numpy as np

__all__ = ["dump_state", "load_state"]

#: the token a state's bytes hold in place of the component's compiled functions
_FUNCTIONS = "native_functions"

_BUILTINS = frozenset({"bool", "bytearray", "bytes", "complex", "dict", "float", "frozenset", "int", "list",
                       "object", "range", "set", "slice", "str", "tuple"})
_STANDARD_MODULES = frozenset({"collections", "datetime", "decimal", "enum", "fractions"})
_NUMPY_CONSTRUCTORS = frozenset({("numpy._core.numeric", "_frombuffer"), ("numpy.core.numeric", "_frombuffer"),
                                 ("numpy._core.multiarray", "_reconstruct"), ("numpy.core.multiarray", "_reconstruct"),
                                 ("numpy._core.multiarray", "scalar"), ("numpy.core.multiarray", "scalar")})


# the pure-Python unpickler: the C one calls whatever REDUCE finds, with no hook between
class _StateUnpickler(pickle._Unpickler):  # noqa: SLF001
    dispatch = dict(pickle._Unpickler.dispatch)  # noqa: SLF001

    def __init__(self, data: bytes, own_module: str, resources_dir: str, functions: Any) -> None:
        super().__init__(io.BytesIO(data))
        self._functions = functions
        self._own_module = own_module
        self._resources = os.path.realpath(resources_dir) + os.sep if resources_dir else None
        self._constructors: list = []  # numpy's, as found

    def find_class(self, module: str, name: str) -> Any:
        if module == "builtins":
            if name in _BUILTINS:
                return getattr(builtins, name)
        elif module in sys.modules:
            found: Any = sys.modules[module]
            for part in name.split("."):  # a class nested in another: its qualified name
                found = getattr(found, part, None)
            if (module, name) in _NUMPY_CONSTRUCTORS and found is not None:
                self._constructors.append(found)
                return found
            if getattr(found, "__module__", None) != module or getattr(found, "__qualname__", None) != name:
                found = None  # reached through another module's attributes (the model's ``os``)
            if isinstance(found, type) and self._holds(module, found):
                return found
            if isinstance(found, types.FunctionType) and self._model_code(module):
                return found  # a component may keep one of its model's functions (a kernel)
        raise pickle.UnpicklingError(f"the FMU state names {module}.{name}, which no FMU state holds")

    def persistent_load(self, pid: Any) -> Any:
        if pid == _FUNCTIONS and self._functions is not None:
            return self._functions
        raise pickle.UnpicklingError(f"the FMU state refers to {pid!r}, which no FMU state refers to")

    def load_reduce(self) -> None:
        """REDUCE: the call a state's bytes make, only of what is made to be rebuilt by one."""
        args = self.stack.pop()
        self._may_call(self.stack[-1])
        self.stack[-1] = self.stack[-1](*args)

    dispatch[pickle.REDUCE[0]] = load_reduce

    def _instantiate(self, klass: Any, args: tuple) -> None:
        # INST and OBJ (protocols 0 and 1) call the class with the bytes' arguments
        self._may_call(klass)
        super()._instantiate(klass, args)  # type: ignore[misc]

    def _may_call(self, func: Any) -> None:
        if not (_rebuilt_by_call(func) or any(func is c for c in self._constructors)):
            name = f"{getattr(func, '__module__', '?')}.{getattr(func, '__qualname__', func)}"
            raise pickle.UnpicklingError(f"the FMU state calls {name}, which no FMU state calls")

    def _holds(self, module: str, cls: type) -> bool:
        """Whether an FMU state may hold an instance of ``cls`` (of the loaded ``module``)."""
        if module.partition(".")[0] == "numpy":  # not its memmap, which opens files
            return cls is np.ndarray or issubclass(cls, (np.generic, np.dtype))
        return module in _STANDARD_MODULES or module.startswith("deltafmi.runtime.") or self._model_code(module)

    def _model_code(self, module: str) -> bool:
        """The model's own code: its module, the modules under the FMU's resources folder, and
        deltafmi's physics and models."""
        if module == self._own_module or module.startswith(("deltafmi.physics.", "deltafmi.models.")):
            return True
        path = getattr(sys.modules[module], "__file__", None)
        return bool(self._resources and path and os.path.realpath(path).startswith(self._resources))


def _rebuilt_by_call(func: Any) -> bool:
    """Whether pickle's bytes for a state call the class ``func`` (REDUCE): value types and classes
    with their own ``__reduce__``; not a class that pickle makes without a call (its ``__init__``
    may do anything, load a library included), nor a function."""
    if not isinstance(func, type):
        return False
    if func.__module__ in ("builtins", *_STANDARD_MODULES) or issubclass(func, (np.generic, np.dtype)):
        return True
    return func.__reduce_ex__ is not object.__reduce_ex__ or func.__reduce__ is not object.__reduce__


class _StatePickler(pickle.Pickler):
    def __init__(self, file: Any, functions_type: type) -> None:
        super().__init__(file, protocol=pickle.HIGHEST_PROTOCOL)
        self._functions_type = functions_type

    def persistent_id(self, obj: Any) -> Optional[str]:
        return _FUNCTIONS if type(obj) is self._functions_type else None


def dump_state(state: Any, functions_type: Optional[type]) -> bytes:
    """``state``'s bytes (:mod:`pickle`), the component's compiled functions (an instance of
    ``functions_type``: calls into the FMU's kernel library, no value) kept as a reference that
    :func:`load_state` resolves to the loading instance's (None: the component has none; pickle
    alone, without a call per object)."""
    if functions_type is None:
        return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)
    out = io.BytesIO()
    _StatePickler(out, functions_type).dump(state)
    return out.getvalue()


def load_state(data: bytes, own_module: str, resources_dir: str, functions: Any = None) -> Any:
    """The object ``data`` (from :func:`dump_state`) holds, if it names only what an FMU state
    may hold, the component's functions being ``functions``; :class:`pickle.UnpicklingError`
    otherwise."""
    return _StateUnpickler(data, own_module, resources_dir, functions).load()
