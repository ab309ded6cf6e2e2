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
from typing import Any, Iterable

from .codegen import generate
from .kernel_types import NONE, B, D, I, S, Entry, Obj, Opt, Tup

#: no fused multiply-add; pow(x, 2.0) stays libm's pow, as in Python
CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-fno-builtin-pow"]

_CTYPES: dict = {}


def ctypes_type(t: Any) -> Any:
    """The ctypes type laid out as the generated C type of ``t``."""
    if t == D:
        return ctypes.c_double
    if t in (I, B):
        return ctypes.c_int
    if t == S:
        return ctypes.c_char_p
    if t in _CTYPES:
        return _CTYPES[t]
    if isinstance(t, Obj):
        import dataclasses

        fields = [(f.name, ctypes.c_double) for f in dataclasses.fields(t.cls)]
    elif isinstance(t, Opt):
        fields = [("some", ctypes.c_int), ("v", ctypes_type(t.inner))]
    elif t.uniform:
        fields = [("v", ctypes_type(t.items[0]) * len(t.items))]
    else:
        names = t.names or tuple(f"f{k}" for k in range(len(t.items)))
        fields = [(n, ctypes_type(item)) for n, item in zip(names, t.items)]
    cls = type(getattr(t, "cname", None) or "T", (ctypes.Structure,), {"_fields_": fields})
    _CTYPES[t] = cls
    return cls


def to_c(t: Any, value: Any) -> Any:
    """``value`` (a Python float, tuple, NamedTuple, object, ...) as a ctypes value of type ``t``."""
    if t == D:
        return float(value)
    if t in (I, B):
        return int(value)
    if t == S:
        return value.encode()
    out = ctypes_type(t)()
    if isinstance(t, Obj):
        for name, _ in out._fields_:
            setattr(out, name, float(getattr(value, name)))
    elif isinstance(t, Opt):
        out.some = value is not None
        if value is not None:
            out.v = to_c(t.inner, value)
    elif t.uniform:
        items = list(value.tolist() if hasattr(value, "tolist") else value)
        for k, item in enumerate(items):
            out.v[k] = to_c(t.items[0], item)
    else:
        names = t.names or tuple(f"f{k}" for k in range(len(t.items)))
        for k, (name, item) in enumerate(zip(names, t.items)):
            raw = getattr(value, name) if t.names else value[k]
            setattr(out, name, to_c(item, raw))
    return out


def from_c(t: Any, value: Any) -> Any:
    """A ctypes value of type ``t`` as Python values (tuples for structs, None for an empty Optional)."""
    if t == D:
        return float(value)
    if t in (I, B):
        return int(value) if t == I else bool(value)
    if isinstance(t, Opt):
        return from_c(t.inner, value.v) if value.some else None
    if t.uniform:
        return tuple(from_c(t.items[0], v) for v in value.v)
    names = t.names or tuple(f"f{k}" for k in range(len(t.items)))
    return tuple(from_c(item, getattr(value, n)) for n, item in zip(names, t.items))


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
        return from_c(ret, out.value if ret == D else out)


def compile_unit(entries: list[Entry], directory: Path, extra_c: str = "", identities: Iterable[str] = (),
                 name: str = "kernels") -> Library:
    """Generate, compile (``$CC`` honoured) and load ``entries``; ``extra_c`` is appended to the unit."""
    from deltafmi.export.compiler import require_compiler

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
