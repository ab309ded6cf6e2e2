"""Model Exchange FMUs as master units: integrated with SUNDIALS CVODE (the library fmpy ships),
or with a fixed-step explicit Runge-Kutta method (:mod:`.explicit_rk`) on request.

Events follow FMI 2.0: state events from the event indicators (CVODE root finding), time events
from ``nextEventTime``, step events from ``fmi2CompletedIntegratorStep``; at each one the FMU goes
through event mode and its ``fmi2NewDiscreteStates`` iteration. Inputs are held constant over a
step, and CVODE stops exactly at every communication point so it never integrates past a held
input; it keeps its step history across communication points and events, and is re-initialized
only where that history is wrong: the states jumped (``valuesOfContinuousStatesChanged``), their
nominals changed, the derivatives jumped at the event, or a state event (see :meth:`_event`).
An FMU that sets ``terminateSimulation`` (in fmi2CompletedIntegratorStep or in the event
iteration) raises :class:`~.unit_base.Terminated`: the master ends the run at that time.
"""
from __future__ import annotations

from ctypes import POINTER, byref, c_bool, c_double
from typing import TYPE_CHECKING, Any, Callable, Dict, Optional, Sequence, Tuple, Type, Union

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model, fmi2Boolean

from ..scenario.system import ResolvedComponent
from .explicit_rk import TABLEAUS, ExplicitRungeKutta, FmuEvaluations, RungeKuttaError
from .jacobians import FmuJacobian, computes_exact_derivatives
from .unit_base import FmuFailure, Terminated, Unit, bare_function, instant_margin

if TYPE_CHECKING:
    from deltafmi.runtime.cvode import Cvode

__all__ = ["ModelExchangeUnit"]

_MAX_EVENT_ITERATIONS = 1000


class ModelExchangeUnit(Unit):
    """An ME FMU plus its own CVODE instance, stepped like a Co-Simulation FMU."""

    interface = "ME"
    fmu_class = FMU2Model

    def __init__(self, component: ResolvedComponent, unzip_dir: str, fmu: Any = None) -> None:
        super().__init__(component, unzip_dir, fmu)
        md = component.info.md
        self.nx = md.numberOfContinuousStates
        self.nz = md.numberOfEventIndicators
        self.needs_completed = bool(md.modelExchange.needsCompletedIntegratorStep)
        self.no_prior_state = 1
        flag = c_bool if self.fmi3 else fmi2Boolean
        self._step_flags = (flag(), flag())  # enterEventMode, terminateSimulation
        #: called as ``on_event(unit, time, after)`` just before and just after every event (recording)
        self.on_event: Callable[["ModelExchangeUnit", float, bool], None] = lambda unit, time, after: None
        self.next_event_time: Optional[float] = None
        #: CVODE restarts after a failure (see :meth:`_advance`)
        self.restarts = 0
        self.solver: Optional[Union[Cvode, ExplicitRungeKutta]] = None
        #: CVODE's error once this unit made a CVODE, none before (a unit on an explicit
        #: Runge-Kutta method never loads the SUNDIALS binding, and nothing raises the error then)
        self._cvode_errors: Tuple[Type[Exception], ...] = ()
        self._pointers: Dict[int, Any] = {}
        self._discrete_inputs: list = []
        self._x = np.zeros(max(self.nx, 1))
        self._x_pointer = self._x.ctypes.data_as(POINTER(c_double))

    def instantiate(self, start: float, stop: float) -> None:
        super().instantiate(start, stop)
        fmu, handle = self.fmu, self.fmu.component
        self._handle = handle
        self._set_time, self._set_states = bare_function(fmu, "fmi2SetTime"), bare_function(fmu, "fmi2SetContinuousStates")
        self._get_indicators = bare_function(fmu, "fmi2GetEventIndicators")
        self._evaluations = FmuEvaluations(fmu, self.nx)
        self._completed_step = bare_function(fmu, "fmi2CompletedIntegratorStep")

    def wire_inputs(self, kind: str, vrs: Sequence[int], bus: np.ndarray, index: Sequence[int],
                    factor: Sequence[float], offset: Sequence[float], elements: Sequence[int] = ()) -> None:
        """Continuous inputs are set before every step; discrete ones (Integer, Boolean, String,
        and Real inputs of variability discrete) only in event mode, as FMI 2.0 ME requires:
        a change at a communication point is an event there."""
        discrete_reals = self.info.discrete_real_inputs
        discrete = [kind != "Real" or vr in discrete_reals for vr in vrs]
        elements = list(elements) or [0] * len(vrs)
        for in_event_mode in (False, True):
            chosen = [i for i, flag in enumerate(discrete) if flag == in_event_mode]
            if chosen:
                super().wire_inputs(kind, [vrs[i] for i in chosen], bus, [index[i] for i in chosen],
                                    [factor[i] for i in chosen], [offset[i] for i in chosen],
                                    [elements[i] for i in chosen])
                if in_event_mode:
                    self._discrete_inputs.append(self.inputs.pop())

    # --- initialization -----------------------------------------------------------------------
    def exit_initialization(self, time: float) -> None:
        """Leave initialization, run the initial event iteration, start CVODE."""
        super().exit_initialization(time)
        self._event_iteration(time)
        for inputs in self._discrete_inputs:
            self.call(inputs.seed)  # the values initialization left: a later change is an event
        self.call(self.fmu.enterContinuousTimeMode)
        self.solver = self._new_solver(time)

    def _new_solver(self, time: float) -> Union[Cvode, ExplicitRungeKutta]:
        options = self.component.spec.solver
        method, max_step = options.get("method", "bdf"), float(options.get("max_step", 0.0))
        if self.nx:
            self.call(self.fmu.getContinuousStates, self._x_pointer, self.nx)
        if method in TABLEAUS:
            return ExplicitRungeKutta(self.fmu, self._x[:self.nx], time, method, max_step,
                                      indicators=self._indicators if self.nz else None)
        from deltafmi.runtime.cvode import Cvode, CvodeError  # here: loading SUNDIALS is for CVODE only

        self._cvode_errors = (CvodeError,)
        default = self.info.md.defaultExperiment
        rtol = options.get("rtol") or (default.tolerance if default is not None and default.tolerance else 1e-6)
        rtol = float(rtol)
        if self.nx:
            nominals = np.ones(self.nx)
            self.call(self.fmu.getNominalsOfContinuousStates, nominals.ctypes.data_as(POINTER(c_double)), self.nx)
            atol = options.get("atol") or rtol * np.abs(nominals)
        else:
            atol = 1.0
        # the Newton matrix from the FMU's directional derivatives, when it provides them
        use = options.get("jacobian", computes_exact_derivatives(self.fmu.unzipDirectory))
        self._newton = FmuJacobian(self.fmu, self.info, exact=bool(use))
        exact = self._newton.exact
        return Cvode(self._rhs, self._x.copy(), time, roots=self._roots if self.nz else None, n_roots=self.nz,
                     rtol=rtol, atol=atol, max_step=max_step, method=method,
                     max_num_steps=int(options.get("max_num_steps", 100000)),
                     jacobian=self._jacobian if self.nx and exact else None)

    # --- CVODE callbacks ----------------------------------------------------------------------
    def _pointer(self, view: np.ndarray) -> Any:
        # CVODE hands over the same few vectors again and again: convert each once
        pointer = self._pointers.get(id(view))
        if pointer is None:
            pointer = self._pointers[id(view)] = view.ctypes.data_as(POINTER(c_double))
        return pointer

    def _rhs(self, t: float, x: np.ndarray, xdot: np.ndarray) -> None:
        if self.nx:
            self._evaluations.derivatives(t, self._pointer(x), self._pointer(xdot), self.nx)
        else:
            self._set_time(self._handle, t)
            xdot[0] = 0.0

    def _jacobian(self, t: float, x: np.ndarray, J: np.ndarray) -> None:
        self._set_time(self._handle, t)
        self._set_states(self._handle, self._pointer(x), self.nx)
        self._newton.fill_state_jacobian(J)

    def _roots(self, t: float, x: np.ndarray, g: np.ndarray) -> None:
        self._roots_at(t, self._pointer(x), self._pointer(g))

    def _roots_at(self, t: float, x: Any, g: Any) -> None:
        if self.nx:
            self._evaluations.indicators(t, x, g, self.nz)
        else:
            self._set_time(self._handle, t)
            self._get_indicators(self._handle, g, self.nz)

    def _indicators(self, t: float, x: np.ndarray) -> np.ndarray:
        # fresh arrays (the Runge-Kutta bisection's trials): their addresses, not the pointer cache
        g = np.empty(self.nz)
        self._roots_at(t, x.ctypes.data, g.ctypes.data)
        return g

    # --- stepping -----------------------------------------------------------------------------
    def pull(self) -> None:
        super().pull()
        if self._discrete_inputs:
            changed = [inputs.update() for inputs in self._discrete_inputs]
            if any(changed):
                self._event(self.solver.t, self._discrete_inputs)

    def do_step(self, time: float, step: float) -> None:
        """Integrate from ``time`` to ``time + step``, handling every event on the way."""
        self._step(time, step)

    def finish_state_event(self, time: float, step: float) -> None:
        """The rest of :meth:`do_step` from ``time`` after the solver's first advance stopped at a
        state event it has located (where :mod:`.native_loop` hands back)."""
        self._step(time, step, located=True)

    def _step(self, time: float, step: float, located: bool = False) -> None:
        t_end = time + step
        eps = instant_margin(t_end)
        stuck, t_previous = 0, time  # events in a row without time advancing
        try:
            while True:
                event_time = self.next_event_time
                t_stop = event_time if event_time is not None and event_time < t_end - eps else t_end
                if located:  # the first advance was made (in C) and stopped at a state event
                    root, located = True, False
                else:
                    root = self._advance(t_stop) if t_stop - self.solver.t > eps else False
                solver = self.solver
                t = solver.t
                self._set_time(self._handle, t)
                if self.nx:
                    self._set_states(self._handle, self._pointer(solver.x), self.nx)
                step_event = False
                if self.needs_completed:
                    enter, terminate = self._step_flags
                    self._completed_step(self._handle, self.no_prior_state, byref(enter), byref(terminate))
                    if terminate.value:
                        raise Terminated(self.name, t)
                    step_event = bool(enter.value)
                if root or step_event or (event_time is not None and t >= event_time - eps):
                    stuck = stuck + 1 if t - t_previous <= eps else 0
                    if stuck > _MAX_EVENT_ITERATIONS:
                        raise FmuFailure(f"{self.name}: {stuck} events at t = {t:.9g} s without time advancing "
                                         "(nextEventTime does not move forward)")
                    self._event(t, root=root)
                if t >= t_end - eps:
                    return
                t_previous = t
        except FMICallException as exc:
            raise self.failure(exc) from None
        except (*self._cvode_errors, RungeKuttaError) as exc:
            raise FmuFailure(f"{self.name}: {exc}") from None

    def finish_step_event(self, t: float) -> None:
        """The rest of :meth:`do_step` after fmi2CompletedIntegratorStep asked for a step event
        at the step's end ``t`` (where :mod:`.native_loop` hands back): the event, in event mode."""
        try:
            self._event(t)
        except FMICallException as exc:
            raise self.failure(exc) from None
        except (*self._cvode_errors, RungeKuttaError) as exc:
            raise FmuFailure(f"{self.name}: {exc}") from None

    def _advance(self, t_stop: float) -> bool:
        """CVODE to ``t_stop``; on a failure, restart it once from where this call began.

        CVODE keeps its step history across communication points. When a held input jumps a lot
        at a tight tolerance, that history can make the error test fail down to the minimum
        step; a fresh start from the last returned point (order 1, new step estimate) gets
        through, and a second failure is real.
        """
        solver = self.solver
        t0, x0 = solver.t, solver.x.copy()
        solver.log_errors = False  # a failure here is retried: only the retry's is an error
        try:
            return solver.advance(t_stop)
        except self._cvode_errors:
            self._set_time(self._handle, t0)
            if self.nx:
                self._set_states(self._handle, self._pointer(x0), self.nx)
            solver.reinit(t0, x0)
            self.restarts += 1
            solver.log_errors = True
            return solver.advance(t_stop)
        finally:
            solver.log_errors = True

    def _event(self, t: float, discrete_inputs: list = (), root: bool = False) -> None:
        """Event mode at ``t``: set discrete inputs, iterate, restart CVODE where needed.

        CVODE restarts when ``valuesOfContinuousStatesChanged`` says the states jumped, when the
        derivatives jumped (a discrete variable switched the right-hand side: its step history
        would describe another function and fail the error test at tight tolerances), and after
        every state event: CVODE finds a root inside a step it has already taken, so its
        internal solution has run past the root on the pre-event equations. Otherwise (a time
        event with no effect on the solution) it keeps its history.
        """
        self.on_event(self, t, False)
        before = self._derivatives()
        self.call(self.fmu.enterEventMode)
        for inputs in discrete_inputs:
            inputs.send()
        states_changed, nominals_changed = self._event_iteration(t)
        self.call(self.fmu.enterContinuousTimeMode)
        if nominals_changed:
            self.solver = self._new_solver(t)
        elif root or states_changed or not np.array_equal(before, self._derivatives()):
            if self.nx:
                self.call(self.fmu.getContinuousStates, self._x_pointer, self.nx)
            self.solver.reinit(t, self._x)
        self.on_event(self, t, True)

    def _derivatives(self) -> np.ndarray:
        dx = np.zeros(max(self.nx, 1))
        if self.nx:
            get = self.fmu.getContinuousStateDerivatives if self.fmi3 else self.fmu.getDerivatives
            self.call(get, dx.ctypes.data_as(POINTER(c_double)), self.nx)
        return dx

    def _event_iteration(self, t: float) -> tuple:
        states_changed = nominals_changed = False
        for _ in range(_MAX_EVENT_ITERATIONS):
            update = self.fmu.updateDiscreteStates if self.fmi3 else self.fmu.newDiscreteStates
            needed, terminate, nominals, values, defined, next_time = self.call(update)
            states_changed |= values
            nominals_changed |= nominals
            if terminate:
                raise Terminated(self.name, t)
            if not needed:
                self.next_event_time = next_time if defined else None
                return states_changed, nominals_changed
        raise FmuFailure(f"{self.name}: event iteration at t = {t:.9g} s did not converge "
                         f"in {_MAX_EVENT_ITERATIONS} rounds")

    # --- rollback -----------------------------------------------------------------------------
    def save_state(self) -> Any:
        return super().save_state(), self.solver.t, self.next_event_time

    def restore_state(self, state: Any) -> None:
        fmu_state, time, self.next_event_time = state
        super().restore_state(fmu_state)
        for inputs in self._discrete_inputs:
            self.call(inputs.seed)  # the restored values: the redone step sees their change again
        if self.nx:
            self.call(self.fmu.getContinuousStates, self._x_pointer, self.nx)
        self.solver.reinit(time, self._x)

    def free_state(self, state: Any) -> None:
        super().free_state(state[0])
