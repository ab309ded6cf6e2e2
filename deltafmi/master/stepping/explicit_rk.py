"""Fixed-step explicit Runge-Kutta for Model Exchange units, as in fixed-step tools (Simulink's
ode4): the cheap choice for a smooth, non-stiff model driven by zero-order-hold inputs.

A one-step method loses nothing when a held input jumps at a communication point, where CVODE's
multistep history does (it re-learns its order and step size after every jump: about 29
right-hand sides per 1 ms step for the delta robot under a 1 kHz controller, against 4 here).
It has no error control: the user picks the method and ``max_step``; CVODE stays the default.

The stages run in C (``native/erk.c``) against the FMU's own fmi2 functions, so a step costs one
foreign call instead of three FMI calls per stage from Python. State events: after each step the
event indicators are compared with the step's start; on a sign change the step is bisected (each
trial one Runge-Kutta step from the start) down to round-off, and the solver stops just past the
crossing, as CVODE's root finding does.
"""
from __future__ import annotations

import ctypes
import math
from ctypes import POINTER, c_double, c_int, c_size_t, c_void_p
from pathlib import Path
from typing import Any, Callable, Dict, Optional, Tuple

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model

from deltafmi.errors import DeltaFmiError
from deltafmi.toolchain import plain_c_library

from .unit_base import function_address

__all__ = ["ExplicitRungeKutta", "FmuEvaluations", "RungeKuttaError", "TABLEAUS", "step_failure"]

#: name -> Butcher tableau (a rows, b, c)
TABLEAUS = {
    "euler": ([[]], [1.0], [0.0]),
    "midpoint": ([[], [0.5]], [0.0, 1.0], [0.0, 0.5]),
    "rk3": ([[], [0.5], [-1.0, 2.0]], [1 / 6, 2 / 3, 1 / 6], [0.0, 0.5, 1.0]),  # Kutta's third order
    "rk4": ([[], [0.5], [0.0, 0.5], [0.0, 0.0, 1.0]], [1 / 6, 1 / 3, 1 / 3, 1 / 6], [0.0, 0.5, 0.5, 1.0]),
}

Indicators = Callable[[float, np.ndarray], np.ndarray]


class RungeKuttaError(DeltaFmiError, RuntimeError):
    """An FMI call inside a Runge-Kutta step failed."""


class _Plan(ctypes.Structure):
    _fields_ = [("set_time", c_void_p), ("set_states", c_void_p), ("get_derivatives", c_void_p),
                ("component", c_void_p), ("stages", c_int), ("a", c_void_p), ("b", c_void_p),
                ("c", c_void_p), ("nx", c_size_t), ("work", c_void_p), ("current", c_int)]


_kernel: Optional[ctypes._CFuncPtr] = None
_evaluate: Optional[ctypes._CFuncPtr] = None


def _steps_function() -> ctypes._CFuncPtr:
    global _kernel, _evaluate
    if _kernel is None:
        library = ctypes.PyDLL(str(plain_c_library(Path(__file__).parent / "native" / "erk.c")))
        _kernel = library.deltafmi_erk_steps
        _kernel.argtypes = [POINTER(_Plan), c_double, c_double, c_int, c_void_p]
        _kernel.restype = c_int
        _evaluate = library.deltafmi_fmu_evaluate
        _evaluate.argtypes = [c_void_p, c_void_p, c_double, c_void_p, c_void_p, c_size_t]
        _evaluate.restype = c_int
    return _kernel


class FmuEvaluations:
    """An instantiated ME FMU's derivatives or event indicators at (t, x) in one foreign call
    (fmi2SetTime + fmi2SetContinuousStates + fmi2GetDerivatives or fmi2GetEventIndicators), for
    a solver's callbacks: one call into C where three from Python cost about 3 us more.
    Raises fmpy's ``FMICallException`` naming the call that returned a status above fmi2Warning."""

    _CALLS = ("fmi2SetTime", "fmi2SetContinuousStates")

    def __init__(self, fmu: FMU2Model, nx: int) -> None:
        _steps_function()
        self._plan = _Plan(function_address(fmu, "fmi2SetTime"), function_address(fmu, "fmi2SetContinuousStates"),
                           function_address(fmu, "fmi2GetDerivatives"), fmu.component, 0, None, None, None, nx, None, 0)
        self._address = ctypes.addressof(self._plan)
        self._get_indicators = function_address(fmu, "fmi2GetEventIndicators")
        self._evaluate = _evaluate

    def derivatives(self, t: float, x: Any, dx: Any, nx: int) -> None:
        """``dx`` (a pointer to nx doubles) = der(x) at (t, ``x``)."""
        status = self._evaluate(self._address, None, t, x, dx, nx)
        if status > 1:
            self._raise(status, "fmi2GetDerivatives")

    def indicators(self, t: float, x: Any, z: Any, nz: int) -> None:
        """``z`` (a pointer to nz doubles) = the event indicators at (t, ``x``)."""
        status = self._evaluate(self._address, self._get_indicators, t, x, z, nz)
        if status > 1:
            self._raise(status, "fmi2GetEventIndicators")

    def _raise(self, code: int, get: str) -> None:
        call = code >> 8
        raise FMICallException(function=self._CALLS[call] if call < 2 else get, status=code & 0xFF)


_tableaus: Dict[str, Tuple[np.ndarray, np.ndarray, np.ndarray]] = {}


def _tableau(method: str) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Butcher tableau of ``method`` as the C steps read it (a: stages x stages, b, c), made
    once and shared by every solver (read-only)."""
    made = _tableaus.get(method)
    if made is None:
        a_rows, b, c = TABLEAUS[method]
        a = np.zeros((len(b), len(b)))
        for i, row in enumerate(a_rows):
            a[i, :len(row)] = row
        made = (a, np.array(b, float), np.array(c, float))
        for array in made:
            array.flags.writeable = False
        _tableaus[method] = made
    return made


class ExplicitRungeKutta:
    """Integrates an ME FMU in continuous-time mode with a fixed-step explicit Runge-Kutta method.

    Same protocol as :class:`deltafmi.runtime.cvode.Cvode` for the master: ``t``, ``x``,
    :meth:`advance` (returns True at a state event) and :meth:`reinit`.

    Args:
        fmu: the instantiated model (its fmi2 functions are called directly).
        x0, t0: start point.
        method: a key of :data:`TABLEAUS`.
        max_step: largest step (s); each call of :meth:`advance` takes equal steps no larger
            than this, one step when 0.
        indicators: ``indicators(t, x)`` -> event indicators at that point, or None (no state events).
    """

    def __init__(self, fmu: FMU2Model, x0: np.ndarray, t0: float, method: str = "rk4",
                 max_step: float = 0.0, indicators: Optional[Indicators] = None) -> None:
        self._a, self._b, self._c = _tableau(method)
        stages, nx = len(self._b), len(x0)
        self._work = np.zeros((stages + 1) * nx)
        self._plan = _Plan(function_address(fmu, "fmi2SetTime"), function_address(fmu, "fmi2SetContinuousStates"),
                           function_address(fmu, "fmi2GetDerivatives"), fmu.component, stages,
                           self._a.ctypes.data, self._b.ctypes.data, self._c.ctypes.data, nx,
                           self._work.ctypes.data)
        self._steps = _steps_function()
        self.max_step = max_step
        self._indicators = indicators
        self.x = np.array(x0, dtype=float)
        self.t = t0
        self._z: Optional[np.ndarray] = None

    def reinit(self, t: float, x: np.ndarray) -> None:
        """Restart from (t, x) (after an event or a rollback)."""
        self.t = t
        self.x[:] = x
        self._z = None

    def advance(self, t_stop: float) -> bool:
        """Integrate to ``t_stop``; True if it stopped early, just past a state event."""
        span = t_stop - self.t
        n = max(1, math.ceil(span / self.max_step - 1e-9)) if self.max_step > 0 else 1
        h = span / n
        if self._indicators is None:
            self._run(self.t, h, n, self.x)
            self.t = t_stop
            return False
        if self._z is None:
            self._z = self._indicators(self.t, self.x)
        for k in range(n):
            t0, x0 = self.t, self.x.copy()
            self._run(t0, h, 1, self.x)
            self.t = t_stop if k == n - 1 else t0 + h
            z = self._indicators(self.t, self.x)
            if np.any((z > 0) != (self._z > 0)):
                self._locate(t0, x0, h)
                return True
            self._z = z
        return False

    @property
    def last_indicators(self) -> Optional[np.ndarray]:
        """The event indicators at the end of the last step (None: to be read before the next)."""
        return self._z

    @last_indicators.setter
    def last_indicators(self, z: Optional[np.ndarray]) -> None:
        self._z = z

    def locate(self, t0: float, x0: np.ndarray, h: float) -> None:
        """The step from (t0, x0) of size h crossed an event: bisect it, as :meth:`advance` does
        (for :mod:`.native_loop`, whose C steps found the crossing)."""
        self._locate(t0, x0, h)

    def _locate(self, t0: float, x0: np.ndarray, h: float) -> None:
        """Bisect the step (t0, x0) -> t0 + h down to round-off; stop just past the crossing."""
        low, high, x = 0.0, 1.0, self.x.copy()
        resolution = 1e-14 * max(1.0, abs(t0))
        while (high - low) * h > resolution:
            middle = 0.5 * (low + high)
            trial = x0.copy()
            self._run(t0, middle * h, 1, trial)
            if np.any((self._indicators(t0 + middle * h, trial) > 0) != (self._z > 0)):
                high, x = middle, trial
            else:
                low = middle
        self.t, self.x[:] = t0 + high * h, x
        self._z = None  # the event changes the model: indicators are read afresh after it

    @property
    def kernel(self) -> Tuple[int, int, int]:
        """(address of the C function taking steps, address of this solver's plan for it, address
        of the plan's int ``current``): what :mod:`.native_loop` calls ``steps(plan, t, h, n, x)``
        with, as :meth:`advance` does; ``current`` set to 1 before a call says the FMU holds the
        start time and states already (its first stage then sets neither)."""
        plan = ctypes.addressof(self._plan)
        return ctypes.cast(self._steps, c_void_p).value, plan, plan + _Plan.current.offset

    def _run(self, t: float, h: float, n: int, x: np.ndarray) -> None:
        status = self._steps(ctypes.byref(self._plan), t, h, n, x.ctypes.data)
        if status > 1:
            raise step_failure(t, status)


def step_failure(t: float, status: int) -> RungeKuttaError:
    """The error of Runge-Kutta steps from ``t`` that stopped on an FMI ``status`` above fmi2Warning."""
    return RungeKuttaError(f"an FMI call in a Runge-Kutta step from t = {t:.9g} s returned "
                           f"status {status} (see the FMU's log)")
