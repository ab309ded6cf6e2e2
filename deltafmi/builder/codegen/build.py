"""Compile generated kernels into a shared library and call them from Python through ctypes.

For tests and benchmarks: :func:`compile_unit` writes ``generate(entries)`` (plus optional
hand-written C appended to the same translation unit) to a directory, compiles it with the C
compiler deltafmi requires and the flags that keep Python's floating-point semantics, and
returns a :class:`Library` whose :meth:`Library.call` takes and returns Python values.
"""
from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path
from typing import Any, Iterable, Optional

from .translate import generate
from deltafmi.runtime.native_kernels import c_type, pack, unpack
from .kernel_types import NONE, B, D, I, Entry, Obj, Opt, Tup, describe

__all__ = ["CFLAGS", "Library", "compile_unit", "ctypes_type", "from_c", "to_c"]

#: no fused multiply-add; pow(x, 2.0) stays libm's pow, as in Python
CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-fno-builtin-pow"]

def ctypes_type(t: Any) -> Any:
    """The ctypes type laid out as the generated C type of ``t`` (the FMU runtime's own, from the
    type's layout description)."""
    return c_type(describe(t))


def to_c(t: Any, value: Any) -> Any:
    """``value`` (a Python float, tuple, NamedTuple, object, ...) as a ctypes value of type ``t``."""
    return pack(describe(t), value)


def from_c(t: Any, value: Any) -> Any:
    """A ctypes value of type ``t`` as Python values (tuples for structs, the NamedTuple for a
    :func:`~.kernel_types.named` type, None for an empty Optional)."""
    return unpack(describe(t), value, _classes(t))


def _classes(t: Any, path: str = "", found: Optional[dict] = None) -> dict:
    """What :func:`unpack` builds each record of ``t`` with, by its path (as :func:`pack` records)."""
    found = {} if found is None else found
    if isinstance(t, Opt):
        _classes(t.inner, f"{path}?", found)
    elif isinstance(t, Tup) and t.uniform:
        _classes(t.items[0], f"{path}[]", found)
    elif isinstance(t, Tup) and t.names:
        found[path] = t.cls if t.cls is not None else (lambda *values: values)
        for name, item in zip(t.names, t.items):
            _classes(item, f"{path}.{name}", found)
    elif isinstance(t, Tup):
        for k, item in enumerate(t.items):
            _classes(item, f"{path}[{k}]", found)
    return found


class Library:
    """A compiled unit: call its entries with Python values."""

    def __init__(self, path: Path, entries: Iterable[Entry], returns: dict) -> None:
        self.path = path
        self.lib = ctypes.CDLL(str(path))
        self.entries = {e.c_name: e for e in entries}
        self.returns = returns

    def call(self, name: str, *args: Any) -> Any:
        """``name``'s result for ``args`` (Python values); raises ArithmeticError with the line of a
        ``raise`` the kernel took."""
        entry = self.entries[name]
        cargs, keep = [], []
        for t, value in zip(entry.args, args):
            if t == NONE:
                continue
            if isinstance(t, Tup) and t.homogeneous:
                arr = (ctypes.c_double * len(t.items))(*[float(v) for v in value])
                keep.append(arr)
                cargs.append(arr)
            elif isinstance(t, Opt) and isinstance(t.inner, Tup) and t.inner.homogeneous:
                if value is None:
                    cargs.append(None)
                else:
                    arr = (ctypes.c_double * len(t.inner.items))(*[float(v) for v in value])
                    keep.append(arr)
                    cargs.append(arr)
            elif isinstance(t, (Tup, Opt, Obj)):
                c = to_c(t, value)
                keep.append(c)
                cargs.append(ctypes.byref(c))
            else:
                cargs.append(ctypes.c_double(value) if t == D else ctypes.c_int(int(value)))
        ret = self.returns[name]
        out = ctypes_type(ret)()
        err = getattr(self.lib, name)(*cargs, ctypes.byref(out))
        if err:
            raise ArithmeticError(f"{name}: the kernel raised at line {err}")
        return from_c(ret, out.value if ret in (D, I, B) else out)


def compile_unit(entries: list[Entry], directory: Path, extra_c: str = "", identities: Iterable[str] = (),
                 name: str = "kernels") -> Library:
    """Generate, compile (``$CC`` honoured) and load ``entries``; ``extra_c`` is appended to the unit."""
    from deltafmi.toolchain import require_compiler

    returns: dict = {}
    source_text = generate(entries, identities=identities, returns=returns)
    source = Path(directory) / f"{name}.c"
    source.write_text(source_text + extra_c)
    library = Path(directory) / f"{name}.so"
    cc = require_compiler(source)
    done = subprocess.run([*cc, *CFLAGS, "-shared", "-fPIC", str(source), "-o", str(library), "-lm"],
                          capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"compiling {source} failed:\n{done.stderr[-4000:]}")
    return Library(library, entries, returns)
