"""The loader of serialized FMU states: what a state's bytes may name and call."""
from __future__ import annotations

import collections
import datetime
import decimal
import fractions
import pickle

import numpy as np
import pytest

from deltafmi.runtime import native_kernels
from deltafmi.runtime.equations.expr import Var
from deltafmi.runtime.state_bytes import load_state


def _call(module: str, name: str, args: tuple, protocol: int = 2) -> bytes:
    """Bytes calling ``module.name(*args)``: REDUCE (protocol 2) or INST (protocol 0, string and
    empty-dict arguments)."""
    if protocol == 0:
        items = "".join(f"V{a}\n" if isinstance(a, str) else "(d" for a in args)
        return f"({items}i{module}\n{name}\n.".encode()
    return b"\x80\x02c" + f"{module}\n{name}\n".encode() + pickle.dumps(args, protocol=2)[2:-1] + b"R."


def test_what_a_state_holds_loads_as_it_was():
    state = {"real": np.arange(5.0), "scalar": np.float64(2.5), "int": np.int32(3), "dtype": np.dtype("f8"),
             "record": np.zeros((2, 3), dtype=[("x", "f8"), ("n", "i4")]), "objects": np.array([1, "a"], dtype=object),
             "when": datetime.datetime(2026, 1, 2, 3, 4, 5), "money": decimal.Decimal("1.5"),
             "third": fractions.Fraction(1, 3), "ordered": collections.OrderedDict(a=1),
             "queue": collections.deque([1, 2]), "lists": collections.defaultdict(list, a=[1]),
             "expr": Var("arm.q[1]", "unknown"), "values": ({1, 2}, frozenset([3]), complex(1, 2), bytearray(b"ab"),
                                                        range(3), slice(1, 2), b"xy", None, True)}
    for protocol in (4, 5):
        assert repr(load_state(pickle.dumps(state, protocol=protocol), "no_model", "")) == repr(state)


@pytest.mark.parametrize("module, name", [
    ("deltafmi.runtime.native_kernels", "ctypes.CDLL"),    # ctypes as an attribute of a runtime module
    ("deltafmi.runtime.state_bytes", "os.popen"),          # a function of os, through the same door
    ("deltafmi.runtime.native_kernels", "np.memmap"),      # numpy's memmap (opens files) through it
])
def test_a_name_resolves_only_to_what_is_defined_under_it(module, name):
    with pytest.raises(pickle.UnpicklingError, match=f"names {module}.{name}, which no FMU state holds"):
        load_state(_call(module, name, ("/nonexistent/library.so",)), module, "")


@pytest.mark.parametrize("protocol", [2, 0])
def test_a_runtime_class_is_not_called_with_the_bytes_arguments(protocol, tmp_path):
    """NativeKernelsRuntime's __init__ loads the library it is given (ctypes.CDLL: the library's
    constructors run). pickle makes such an object without calling the class; bytes that call it
    (REDUCE, or protocol 0's INST) are refused before the call: no OSError from the loader."""
    not_a_library = tmp_path / "evil.so"
    not_a_library.write_bytes(b"not an ELF file")
    assert native_kernels.NativeKernelsRuntime.__reduce__ is object.__reduce__
    with pytest.raises(pickle.UnpicklingError, match="calls deltafmi.runtime.native_kernels.NativeKernelsRuntime"):
        load_state(_call("deltafmi.runtime.native_kernels", "NativeKernelsRuntime", (str(not_a_library), {}),
                         protocol), "no_model", "")


def test_a_class_made_to_be_called_by_its_own_reduce_still_is():
    assert load_state(_call("deltafmi.runtime.equations.expr", "Var", ("x", "unknown")), "no_model", "").name == "x"
