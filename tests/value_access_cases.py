"""What a model can do with its variables, as a list of outcomes (value and type, or the error).

Run by test_component_values.py twice: with the pure-Python accessors and, in a subprocess, with
the compiled ones (deltafmi/runtime/_values.c). Both must give the same list.
"""
import array
import json
import sys

import numpy as np

from deltafmi.component import Component, Input, Output, Parameter, State
from deltafmi.runtime import native_values


class Cases(Component):
    """Every kind of declaration the compiled accessors handle, and those they hand back."""

    x = State([1.0, 2.0])
    b = Input(6.0)
    a = Input([3.0, 4.0, 5.0])
    n = Input(7, type=int)
    flag = Output(True)
    label = Parameter("abc")
    names = Parameter(["p", "q"], type=str)


SETS = {
    "b": [2.5, 3, np.float32(0.25), np.float64(1.5), True, "1.5", None, [1.0], np.array(2.0), 1e308 * 10],
    "n": [5, True, 2.7, 2**40, -2**31, 2**31, "3", None, np.int64(9)],
    "flag": [False, True, 0, 2, np.bool_(False), None],
    "a": [[1, 2, 3], (1.0, 2.0, 3.0), np.arange(3), 0.5, [1.0, 2.0], "x", [1.5, 2.5, 3.5], [1.0, 2, 3.0],
          [1.0, 2.0, "3"], [1.0, 2.0, None], np.array([0.5, 1.5, 2.5]), np.arange(6.0)[::2], np.arange(6.0)[::-2],
          np.array([1.0, 2.0, 3.0], dtype=">f8"), np.ones(3, np.float32), np.ones((3, 1)), np.ones(4), np.float64(2.0),
          [[1.0], [2.0], [3.0]], array.array("d", [4.0, 5.0, 6.0])],
    "label": ["xyz", 5],
    "names": [["u", "v"], ("w", 1)],
    "states": [[0.0, 0.0]],
}


def outcome(thunk):
    """('ok', repr, type) of what the thunk returns, or ('error', exception type)."""
    try:
        value = thunk()
    except Exception as exc:  # the type is what must agree, not the message
        return ["error", type(exc).__name__]
    if isinstance(value, np.ndarray):
        return ["ok", repr(value.tolist()), f"ndarray {value.dtype}"]
    return ["ok", repr(value), type(value).__name__]


def run() -> list:
    c = Cases()
    results = [outcome(lambda name=name: getattr(c, name)) for name in [*SETS, "x"]]
    for name, values in SETS.items():
        for value in values:
            results.append([name, repr(value), outcome(lambda: setattr(c, name, value)),
                            outcome(lambda: getattr(c, name))])
    results.append(["del", outcome(lambda: delattr(c, "b")), outcome(lambda: c.b)])
    results.append(["class", type(Cases.b).__name__, Cases.b.description == "", Cases.a.shape])
    c.x[1] = 9.0  # an array read is a view of the buffer
    results.append(["view", c.x.tolist(), c.states.tolist()])
    c.a = [1.0, 2.0, 3.0]
    c.a = c.a[::-1]  # from a view of the same values: the write must not read what it wrote
    results.append(["reversed", c.a.tolist()])
    c.x = c.a[1:]  # from a view of another declaration
    results.append(["other view", c.x.tolist()])
    held = c.a
    c.a = [7.0, 8.0, 9.0]  # a view read earlier sees later writes
    results.append(["held view", held.tolist(), c.a.tolist(), np.shares_memory(c.a, c._real)])
    # a scalar read after the buffer changed underneath (as fmi2SetReal does) gives the new value,
    # bit for bit: the compiled access returns the float it made earlier only for the same bits
    b = Cases.b.offset
    reads = []
    for value in [1.25, 1.25, -0.0, 0.0, -0.0, float("nan"), float("nan"), float("inf"), 1.25]:
        c._real[b] = value
        reads += [repr(c.b), repr(c.b)]
    c.b = 0.5
    c._real[b] = -0.5
    reads.append(repr(c.b))
    c.b = -0.0
    reads.append(repr(c.b))
    results.append(["scalar reads", reads])
    c._attach("", [])  # new buffers: reads are views of those, not of the old ones
    c.a[0] = -1.0
    c._real[b] = 3.5
    results.append(["rebound", c.a.tolist(), c.b, c._real.tolist(),
                    np.shares_memory(c.a, c._real), np.shares_memory(held, c._real)])
    return results


if __name__ == "__main__":
    json.dump({"compiled": native_values.COMPILED, "results": run()}, sys.stdout)
