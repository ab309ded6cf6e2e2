"""Cost of a compiled function called from Python (``NativeKernels(functions=...)``).

The ContactEstimator's three functions (deltafmi/physics/estimation/delta_process_kernels.py and
the projection onto the loops), compiled in-process by ``use_compiled_functions``, at a state of
the robot in motion. Per function, microseconds per call (median over blocks of calls, the
thread's CPU time): the Python function, the compiled function as a component calls it
(``self.native_functions.<name>``: argument conversion, the ctypes call, the result array), and
the bare ctypes call of its entry with the arguments already converted (the C alone, plus
ctypes' own cost). The difference of the last two is the binding's overhead per call. The ratio
of the first two is what the compiled function buys; the load of the machine enters all three
alike.

Usage: python benchmarks/native_functions.py [--calls N]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np


def per_call(call, calls: int, blocks: int = 7) -> float:
    """Median over ``blocks`` of the thread's CPU microseconds per ``call()``."""
    means = []
    for _ in range(blocks):
        start = time.thread_time()
        for _ in range(calls):
            call()
        means.append((time.thread_time() - start) / calls * 1e6)
    return float(np.median(means))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calls", type=int, default=2000, help="calls per block (the Python ones: a tenth)")
    args = parser.parse_args()
    from deltafmi.builder.codegen import use_compiled_functions
    from deltafmi.models.contact_estimator import ContactEstimator
    from deltafmi.physics import delta as d
    from deltafmi.physics.estimation.delta_process import tangent_basis
    from deltafmi.runtime.native_functions import flatten

    if not use_compiled_functions(ContactEstimator):
        raise SystemExit("the functions could not be compiled (no C compiler?)")
    functions = ContactEstimator().native_functions
    python = {name: f.func for name, f in ContactEstimator.native.functions.items()}
    p = d.RL5
    q = d.inverse_kinematics(p, [0.05, -0.02, -0.95])
    v = tangent_basis(p, q) @ np.array([0.1, -0.2, 0.3])
    arguments = {"predict": (p, q, v, [0.5, -1.0, 2.0], [0.0, 0.0, 15.0], 1e-3, 5.0, 1),
                 "project": (p, q + 1e-7, v), "kinematics": (p, q, v)}
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; microseconds per call, "
          f"the thread's CPU time")
    print(f"{'function':12}{'Python':>10}{'compiled':>10}{'bare C':>10}{'overhead':>10}{'speed-up':>10}")
    for name, values in arguments.items():
        call = getattr(functions, name)
        scope = call.__globals__  # the generated caller's names: its entry and converters
        converted = [scope[f"c{k}"](value) if f"c{k}" in scope else (int(value) if isinstance(value, int) else value)
                     for k, value in enumerate(values)]
        entry, address = scope["entry"], scope["address"]
        assert np.array_equal(call(*values), flatten(python[name](*values)))  # the same numbers
        slow = per_call(lambda: python[name](*values), max(args.calls // 10, 10))
        fast = per_call(lambda: call(*values), args.calls)
        bare = per_call(lambda: entry(*converted, address), args.calls)
        print(f"{name:12}{slow:10.1f}{fast:10.1f}{bare:10.1f}{fast - bare:10.1f}{slow / fast:9.1f}x")


if __name__ == "__main__":
    main()
