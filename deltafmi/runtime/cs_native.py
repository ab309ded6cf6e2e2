"""The Co-Simulation step's bookkeeping, shared by :class:`.instance.FmuInstance` and the FMU's C
layer (``native/cs_step.c``), which takes a component's steps from C when it has states and
compiled kernels.

One C struct holds what a step reads and writes between steps (the time, the communication grid,
the next time event, the inputs the last step saw, the derivatives and event indicators at its
end, whether the solver must restart) and the solver's addresses once it exists (CVODE's memory, its state vector, the
SUNDIALS functions a step calls). Python reads and writes the same fields (the instance's
attributes are views of them), so the Python step (``DELTAFMI_NATIVE_CS=0``, components without
compiled kernels) and the C step are one state machine, and either may take any step.
"""
from __future__ import annotations

import ctypes
import os
from ctypes import c_double, c_int, c_int64, c_void_p
from typing import Any

import numpy as np

__all__ = ["CsShared", "native_cs_wanted"]


class CsShared(ctypes.Structure):
    """``DfmiCs`` of ``native/bridge.h``, field for field."""

    _fields_ = [("mem", c_void_p), ("y", c_void_p), ("x", c_void_p),
                ("cvode", c_void_p), ("set_stop_time", c_void_p), ("reinit", c_void_p),
                ("quiet", c_void_p), ("atol", c_void_p),
                ("rtol", c_double), ("jump_tolerance", c_double), ("solver_t", c_double),
                ("time", c_double), ("start_time", c_double), ("grid_step", c_double),
                ("next_time_event", c_double), ("event_time", c_double),
                ("restart_solver", c_int), ("jump_kept", c_int), ("after_valid", c_int), ("inputs_valid", c_int),
                ("after", c_void_p), ("inputs", c_void_p), ("real_inputs", c_void_p), ("int_inputs", c_void_p),
                ("n_real_inputs", c_int64), ("n_int_inputs", c_int64), ("enabled", c_int),
                ("pre_indicators", c_void_p), ("pre_indicators_valid", c_int), ("handled_reported", c_int)]

    def setup(self, nx: int, nz: int, real_inputs: np.ndarray, int_inputs: np.ndarray) -> None:
        """Arrays the struct points into, kept alive by it (one per instance, for its whole life)."""
        self._arrays = {"after": np.zeros(max(nx, 1)), "atol": np.zeros(max(nx, 1)),
                        "pre_indicators": np.zeros(max(nz, 1)),
                        "inputs": np.zeros(max(len(real_inputs) + len(int_inputs), 1)),
                        "real_inputs": np.ascontiguousarray(real_inputs, dtype=np.int64),
                        "int_inputs": np.ascontiguousarray(int_inputs, dtype=np.int64)}
        for name, array in self._arrays.items():
            setattr(self, name, array.ctypes.data)
        self.n_real_inputs, self.n_int_inputs = len(real_inputs), len(int_inputs)
        self.after_view = self._arrays["after"][:nx]
        self.atol_view = self._arrays["atol"][:nx]
        self.inputs_view = self._arrays["inputs"][:len(real_inputs) + len(int_inputs)]
        self.pre_indicators_view = self._arrays["pre_indicators"][:nz]
        self.next_time_event = self.event_time = float("nan")

    def attach_solver(self, solver: Any) -> None:
        """The solver's addresses and tolerances for the C step (``solver``: a :class:`.cvode.Cvode`)."""
        self.mem, self.y, self.x = solver._mem, solver._y, solver.x.ctypes.data
        self.cvode, self.set_stop_time, self.reinit = solver.c_functions()
        self.quiet = solver.quiet.ctypes.data
        self.rtol = solver.rtol
        self.atol_view[:] = solver.atol
        self.solver_t = solver.t

    def detach_solver(self) -> None:
        """No solver: the next step makes one."""
        self.mem = self.y = self.x = None
        self.event_time = float("nan")


def native_cs_wanted() -> bool:
    """Whether the C step may take a component's steps (``DELTAFMI_NATIVE_CS=0`` keeps them in Python)."""
    return os.environ.get("DELTAFMI_NATIVE_CS", "1") != "0"
