"""A thin, reusable CVODE integrator over SUNDIALS (our own binding, :mod:`.sundials`).

fmpy's own ``CVodeSolver`` is tied to FMU callbacks and integrates past the output point; this one
works on numpy callbacks, stops exactly at a stop time (``CVodeSetStopTime``) so zero-order-hold
inputs are never sampled beyond a communication point, reports roots, and keeps its step-size
history between calls until :meth:`Cvode.reinit` is called after a state jump.

SUNDIALS' errors are kept for the exception (and logged at ERROR on ``deltafmi.solver`` unless a
callback's own exception explains them); its warnings are logged at WARNING there. Nothing is
printed.
"""
from __future__ import annotations

import ctypes
import math
from ctypes import byref, c_double, c_int, c_void_p
from typing import Callable, Optional, Sequence

import numpy as np
import numpy.ctypeslib  # noqa: F401  (numpy loads it lazily on first use, which raced between threads)

from deltafmi.runtime import sundials as _sun

from .errors import DeltaFmiError

__all__ = ["Cvode", "CvodeError"]

Rhs = Callable[[float, np.ndarray, np.ndarray], None]
Roots = Callable[[float, np.ndarray, np.ndarray], None]
Project = Callable[[float, np.ndarray, np.ndarray], None]
Jacobian = Callable[[float, np.ndarray, np.ndarray], None]
#: (addresses of the Python right-hand side, root and projection functions (0: none), of
#: N_VGetArrayPointer, of the Python Jacobian function (0: none), of SUNDenseMatrix_Data) ->
#: (addresses of a C right-hand side, of C root functions, of a C projection function and of a C
#: Jacobian function (0: the Python ones) with CVODE's signatures, their user data): compiled
#: callbacks that call the Python ones themselves when they cannot compute (see
#: deltafmi/runtime/native_kernels.py)
NativeCallbacks = Callable[[int, int, int, int, int, int], tuple[int, int, int, int, int]]


class CvodeError(DeltaFmiError, RuntimeError):
    """CVODE failed (error test or convergence failures, too much work, ...)."""


class Cvode:
    """CVODE (BDF with dense Newton by default, or Adams) on ``x' = rhs(t, x)`` with root finding.

    ``rhs(t, x, xdot)`` and ``roots(t, x, g)`` fill their last argument in place; ``x`` is the
    solver's own memory viewed as a numpy array, valid during the call only. With
    ``project(t, x, correction)`` CVODE projects onto an invariant manifold after every internal
    step (its own projection method: no restart, BDF only): the callback writes the correction
    that moves ``x`` onto the manifold. With ``jacobian(t, x, J)`` the Newton iteration uses
    that dense ``d rhs / d x`` (``J`` an (n, n) view of SUNDIALS' matrix, to fill) instead of
    CVODE's difference quotients. With ``native`` (:data:`NativeCallbacks`) CVODE calls a compiled
    right-hand side (and root functions, projection), which fall back on ``rhs`` (``roots``,
    ``project``).
    """

    def __init__(self, rhs: Rhs, x0: np.ndarray, t0: float, *, roots: Optional[Roots] = None,
                 n_roots: int = 0, rtol: float = 1e-6, atol: float | np.ndarray = 1e-8,
                 max_step: float = 0.0, method: str = "bdf", max_num_steps: int = 100000,
                 project: Optional[Project] = None, project_every: int = 1,
                 jacobian: Optional[Jacobian] = None, native: Optional[NativeCallbacks] = None) -> None:
        self.n = n = len(x0)
        self.n_roots = n_roots if roots is not None else 0
        self._rhs, self._roots = rhs, roots
        # SUNDIALS' errors are kept for the exception, not printed (see :mod:`.sundials`)
        self.last_message = ""
        self.callback_error: Optional[BaseException] = None
        #: [0] nonzero while a failure would be recovered from (the caller retries): errors are kept,
        #: not logged (an array: a step taken in C sets it too, see cs_native.py)
        self.quiet = np.zeros(1, dtype=np.intc)
        self._ctx, self._err_handler = _sun.new_context(self._on_error)
        self._y = _sun.N_VNew_Serial(n, self._ctx)
        self.x = np.ctypeslib.as_array(_sun.N_VGetArrayPointer(self._y), (n,))
        self.x[:] = x0
        self._atol = _sun.N_VNew_Serial(n, self._ctx)
        np.ctypeslib.as_array(_sun.N_VGetArrayPointer(self._atol), (n,))[:] = atol
        #: the tolerances, for :meth:`error_norm`
        self.rtol, self.atol = rtol, np.broadcast_to(np.asarray(atol, dtype=float), (n,)).tolist()
        lmm = _sun.CV_ADAMS if method == "adams" else _sun.CV_BDF
        self._mem = _sun.CVodeCreate(lmm, self._ctx)
        # keep the ctypes callbacks referenced: CVODE only holds raw pointers (which are cheaper
        # than typed arguments, and hashable)
        self._f = _sun.RhsFn(self._f_callback)
        self._g = _sun.RhsFn(self._g_callback)
        self._p = _sun.ProjFn(self._p_callback) if project is not None else None
        self._j = _sun.JacFn(self._j_callback) if jacobian is not None else None
        if native is not None:
            self._fallbacks = self._f, self._g, self._p, self._j  # the compiled callbacks call these: keep them alive
            rhs, roots, projection, jac, user_data = native(
                ctypes.cast(self._f, c_void_p).value, ctypes.cast(self._g, c_void_p).value,
                ctypes.cast(self._p, c_void_p).value if self._p is not None else 0,
                ctypes.cast(_sun.N_VGetArrayPointer, c_void_p).value,
                ctypes.cast(self._j, c_void_p).value if self._j is not None else 0,
                ctypes.cast(_sun.SUNDenseMatrix_Data, c_void_p).value)
            self._f, self._g = _sun.RhsFn(rhs), _sun.RhsFn(roots) if roots else self._g
            self._p = _sun.ProjFn(projection) if projection else self._p
            self._j = _sun.JacFn(jac) if jac else self._j
        _check(_sun.CVodeInit(self._mem, self._f, t0, self._y), "CVodeInit")
        if native is not None:
            _check(_sun.CVodeSetUserData(self._mem, user_data), "CVodeSetUserData")
        _check(_sun.CVodeSVtolerances(self._mem, rtol, self._atol), "CVodeSVtolerances")
        if self.n_roots:
            _check(_sun.CVodeRootInit(self._mem, self.n_roots, self._g), "CVodeRootInit")
            _check(_sun.CVodeSetNoInactiveRootWarn(self._mem), "CVodeSetNoInactiveRootWarn")
        self._A = _sun.SUNDenseMatrix(n, n, self._ctx)
        self._LS = _sun.SUNLinSol_Dense(self._y, self._A, self._ctx)
        _check(_sun.CVodeSetLinearSolver(self._mem, self._LS, self._A), "CVodeSetLinearSolver")
        self._jacobian = jacobian
        if jacobian is not None:
            # CVODE hands the Jacobian function the matrix given to the linear solver: view it once
            self._J = np.ctypeslib.as_array(_sun.SUNDenseMatrix_Data(self._A), (n * n,)).reshape((n, n), order="F")
            _check(_sun.CVodeSetJacFn(self._mem, self._j), "CVodeSetJacFn")
        if max_step > 0:
            _check(_sun.CVodeSetMaxStep(self._mem, max_step), "CVodeSetMaxStep")
        _check(_sun.CVodeSetMaxNumSteps(self._mem, max_num_steps), "CVodeSetMaxNumSteps")
        self._project = project
        if project is not None:
            if method != "bdf":
                raise ValueError("CVODE projects only with BDF")
            _check(_sun.CVodeSetProjFn(self._mem, self._p), "CVodeSetProjFn")
            _check(_sun.CVodeSetProjErrEst(self._mem, 0), "CVodeSetProjErrEst")
            _check(_sun.CVodeSetProjFrequency(self._mem, project_every), "CVodeSetProjFrequency")
        self._root_info = np.zeros(max(self.n_roots, 1), dtype=np.int32)
        self._views: dict[int, np.ndarray] = {}
        self.t = t0

    @property
    def log_errors(self) -> bool:
        """Whether SUNDIALS' errors are logged (False while the caller would recover from a failure)."""
        return not self.quiet[0]

    @log_errors.setter
    def log_errors(self, value: bool) -> None:
        self.quiet[0] = 0 if value else 1

    def _on_error(self, _line: int, function: Optional[bytes], _file: Optional[bytes],
                  message: Optional[bytes], _code: int) -> None:
        try:
            self.last_message = (message or b"").decode(errors="replace")
            # a callback's own exception says it all; a failure the caller recovers from is no error
            if self.callback_error is None and self.log_errors:
                _sun.LOGGER.error("%s: %s", (function or b"CVODE").decode(errors="replace"), self.last_message)
        except Exception:  # noqa: BLE001  (nothing may cross into C)
            pass

    def _view(self, vector: int) -> np.ndarray:
        # CVODE passes a handful of internal vectors over and over: build each view only once
        view = self._views.get(vector)
        if view is None:
            view = self._views[vector] = np.ctypeslib.as_array(_sun.N_VGetArrayPointer(vector), (self.n,))
        return view

    def _roots_view(self, address: int) -> np.ndarray:
        view = self._views.get(address)
        if view is None:
            pointer = ctypes.cast(address, ctypes.POINTER(c_double))
            view = self._views[address] = np.ctypeslib.as_array(pointer, (self.n_roots,))
        return view

    def _guarded(self, callback: Callable, *args: object) -> int:
        # CVODE can only take an error code: keep the exception for advance() to re-raise
        try:
            callback(*args)
            return 0
        except Exception as exc:  # noqa: BLE001
            self.callback_error = exc
            return -1

    def _f_callback(self, t: float, y: int, ydot: int, _user: int) -> int:
        return self._guarded(self._rhs, t, self._view(y), self._view(ydot))

    def _g_callback(self, t: float, y: int, gout: int, _user: int) -> int:
        return self._guarded(self._roots, t, self._view(y), self._roots_view(gout))

    def _j_callback(self, t: float, y: int, _fy: int, _J: int, _user: int, _t1: int, _t2: int, _t3: int) -> int:
        return self._guarded(self._jacobian, t, self._view(y), self._J)

    def _p_callback(self, t: float, y: int, corr: int, _eps: float, _err: int, _user: int) -> int:
        return self._guarded(self._project, t, self._view(y), self._view(corr))

    def advance(self, t_stop: float) -> bool:
        """Integrate to ``t_stop`` exactly, or to the first root before it.

        Returns True when a root stopped the integration; :attr:`t` and :attr:`x` hold the
        reached time and state, :attr:`roots` which indicators crossed (+1/-1 direction).
        """
        self.callback_error = None
        _sun.CVodeSetStopTime(self._mem, t_stop)
        tret = c_double(0.0)
        flag = _sun.CVode(self._mem, t_stop, self._y, byref(tret), _sun.CV_NORMAL)
        if flag < 0:
            if self.callback_error is not None:
                raise self.callback_error
            raise CvodeError(f"CVODE failed with flag {flag} at t = {tret.value:.9g}: {self.last_message}")
        self.t = tret.value
        if flag == _sun.CV_ROOT_RETURN:
            _check(_sun.CVodeGetRootInfo(self._mem, self._root_info.ctypes.data_as(ctypes.POINTER(c_int))),
                   "CVodeGetRootInfo")
            return True
        return False

    def c_functions(self) -> tuple[int, int, int]:
        """The addresses of ``CVode``, ``CVodeSetStopTime`` and ``CVodeReInit`` of the SUNDIALS this
        solver runs on, for C code that steps it (the FMU's Co-Simulation step, cs_native.py)."""
        return tuple(ctypes.cast(f, c_void_p).value for f in (_sun.CVode, _sun.CVodeSetStopTime, _sun.CVodeReInit))

    @property
    def roots(self) -> np.ndarray:
        """Crossing directions of the last root return (0 where no root)."""
        return self._root_info[: self.n_roots]

    def reinit(self, t: float, x: np.ndarray) -> None:
        """Restart at ``(t, x)``, discarding the step history (after a discontinuity)."""
        self.x[:] = x
        _check(_sun.CVodeReInit(self._mem, t, self._y), "CVodeReInit")
        self.t = t

    def error_norm(self, v: Sequence[float]) -> float:
        """``v`` in CVODE's error norm at the current state: the root mean square of
        ``v_i / (rtol |x_i| + atol_i)``; CVODE's error test accepts a step whose local error
        estimate has a norm <= 1."""
        total = 0.0
        for vi, xi, ai in zip(v, self.x.tolist(), self.atol):
            total += (vi / (self.rtol * abs(xi) + ai)) ** 2
        return math.sqrt(total / self.n) if self.n else 0.0

    def free(self) -> None:
        """Release every SUNDIALS object of this solver (also done on garbage collection).

        The callbacks reference the solver, so without this it lives until the cycle collector
        runs; owners that drop solvers often (a reset, a restored FMU state) call it at once.
        """
        if getattr(self, "_mem", None):
            _sun.CVodeFree(byref(c_void_p(self._mem)))
            self._mem = None
        for name, destroy in (("_LS", _sun.SUNLinSolFree), ("_A", _sun.SUNMatDestroy),
                              ("_y", _sun.N_VDestroy), ("_atol", _sun.N_VDestroy)):
            if getattr(self, name, None):
                destroy(getattr(self, name))
                setattr(self, name, None)
        if getattr(self, "_ctx", None):
            _sun.SUNContext_Free(byref(self._ctx))
            self._ctx = None
        self._views = {}
        self.x = np.zeros(0)

    def __del__(self) -> None:
        self.free()


def _check(flag: int, what: str) -> None:
    if flag < 0:
        raise CvodeError(f"{what} failed with flag {flag}")
