"""One FMU instance on the Python side: what the native bridge calls for each fmi2 function.

The native loader owns the FMI state machine and reads/writes the value buffers directly; it
calls into this class only for work that needs the model: evaluation, initialization, event
updates, Co-Simulation steps and FMU state. Methods return an FMI status code (0 OK, 1 warning,
2 discard, 3 error) or raise (the bridge turns exceptions into ``fmi2Error`` plus a traceback).
"""
from __future__ import annotations

import ctypes
import math
import struct
from contextlib import nullcontext
from typing import TYPE_CHECKING, Any, Callable, ContextManager, Optional, Sequence

import numpy as np

from deltafmi.runtime import fmu_logging
from .base import Component
from .clocks import clock_driven
from .cs_native import CsShared, native_cs_wanted
from .native_functions import FunctionSet
from .native_kernels import TRAILING_ROLES, NativeKernelsRuntime
from .partials import DirectionalDerivatives
from .state_bytes import dump_state, load_state

if TYPE_CHECKING:  # loaded by _make_solver: only components that integrate need SUNDIALS
    from .cvode import Cvode

__all__ = ["CO_SIMULATION", "CompiledStep", "EVENTS_AT_STEP_END", "EVENTS_EARLY_RETURN", "EVENTS_INSIDE", "FmuInstance"]

OK, WARNING, DISCARD, ERROR = 0, 1, 2, 3
MODEL_EXCHANGE, CO_SIMULATION, SCHEDULED_EXECUTION = 0, 1, 2
_MAX_EVENT_ITERATIONS = 100
_LOG_EVENTS, _LOG_SOLVER = fmu_logging.BITS["logEvents"], fmu_logging.BITS["logSolver"]
_TINY = 1e-12  # relative time below which intervals are round-off, not integration
#: default ``cs_options["input_jump_tolerance"]``: see FmuInstance._restart_for_inputs
_INPUT_JUMP_TOLERANCE = 10.0
#: :meth:`FmuInstance.do_step`'s ``events``: what a Co-Simulation step does at a state or time
#: event. The native layer passes the same numbers (core.h, DfmiStepEvents).
EVENTS_INSIDE = 0        #: handles every event inside the step (FMI 2.0; FMI 3.0 without eventModeUsed)
EVENTS_EARLY_RETURN = 1  #: stops at the first event and leaves it pending (eventModeUsed, earlyReturnAllowed)
EVENTS_AT_STEP_END = 2   #: handles the events inside the step, leaves one at its end pending (eventModeUsed)

#: what every snapshot of :meth:`FmuInstance.get_state` holds
_STATE_KEYS = frozenset({"real", "int", "str", "internal", "time", "next_time_event", "in_initialization",
                         "terminate_requested"})


class CompiledStep:
    """A component's own Co-Simulation step in C (:meth:`Component._compiled_step`): the FMU's C
    layer calls ``step`` as a compiled step kernel (``outputs`` as its outputs kernel) with
    :attr:`context`, while :attr:`ready` is set."""

    def __init__(self, step: int, outputs: int, size: int) -> None:
        self.step, self.outputs = step, outputs
        #: the functions' context, laid out by the component
        self.context = np.zeros(max(size, 8), dtype=np.uint8)
        #: [0] nonzero: the C layer calls the functions (the component sets it)
        self.ready = np.zeros(1, dtype=np.intc)

    def layout(self) -> tuple:
        """The kernels' fields of :meth:`FmuInstance.native_layout`."""
        return (0, 0, self.outputs, self.step, 0, self.context.ctypes.data, self.ready.ctypes.data,
                *(0,) * len(TRAILING_ROLES))


def _cvode_class(module_context: Callable[[], ContextManager]) -> type[Cvode]:
    """The CVODE wrapper, imported on first use: components that never integrate (no states, or
    Model Exchange only) never load SUNDIALS. The import runs in the FMU's module context, where
    its private ``deltafmi`` copy is in ``sys.modules``; once imported it is kept here."""
    cached = _CVODE.get("class")
    if cached is None:
        with module_context():
            from .cvode import Cvode, CvodeError
        _CVODE["error"] = CvodeError  # before the class: another thread may take the class at once
        cached = _CVODE["class"] = Cvode
    return cached


_CVODE: dict = {}


class FmuInstance:
    """The model side of one ``fmi2Component``."""

    # the Co-Simulation step's state lives in the struct the C step shares (cs_native.py)
    time = property(lambda self: self._cs.time, lambda self, value: setattr(self._cs, "time", value),
                    doc="The instance's time.")
    start_time = property(lambda self: self._cs.start_time,
                          lambda self, value: setattr(self._cs, "start_time", value),
                          doc="Where the communication grid starts (fmi2SetupExperiment's start).")
    _grid_step = property(lambda self: self._cs.grid_step, lambda self, value: setattr(self._cs, "grid_step", value))
    _restart_solver = property(lambda self: bool(self._cs.restart_solver),
                               lambda self, value: setattr(self._cs, "restart_solver", int(value)))
    _jump_tolerance = property(lambda self: self._cs.jump_tolerance,
                               lambda self, value: setattr(self._cs, "jump_tolerance", value))
    _jump_kept = property(lambda self: bool(self._cs.jump_kept),
                          lambda self, value: setattr(self._cs, "jump_kept", int(value)))

    @property
    def _next_time_event(self) -> Optional[float]:
        nte = self._cs.next_time_event
        return None if math.isnan(nte) else nte

    @_next_time_event.setter
    def _next_time_event(self, value: Optional[float]) -> None:
        self._cs.next_time_event = math.nan if value is None else float(value)

    @property
    def _derivatives_after_step(self) -> Optional[list]:
        """CS: the derivatives at the end of the last step, with the inputs CVODE integrated with."""
        return self._cs.after_view.tolist() if self._cs.after_valid else None

    @_derivatives_after_step.setter
    def _derivatives_after_step(self, value: Optional[Sequence[float]]) -> None:
        if value is not None:
            self._cs.after_view[:] = value
        self._cs.after_valid = int(value is not None)

    def __init__(self, component_class: type[Component], instance_name: str = "instance",
                 fmu_type: int = CO_SIMULATION, resources_dir: str = "",
                 module_context: Callable[[], ContextManager] = nullcontext) -> None:
        self.component_class = component_class
        self.instance_name = instance_name
        self.fmu_type = fmu_type
        self.resources_dir = resources_dir
        self._module_context = module_context
        layout = component_class._layout
        self.nx, self.nz = layout.nx, component_class.n_event_indicators
        #: samples only at its input Clocks' ticks (no states, no event indicators): see clock_driven
        self._clock_driven = clock_driven(component_class)
        if fmu_type != CO_SIMULATION and component_class.co_simulation_only:
            raise ValueError(f"{component_class.fmi_model_name()} offers Co-Simulation only")
        if fmu_type == CO_SIMULATION and self.nx and not component_class.overrides_do_step():
            _cvode_class(module_context)  # a missing SUNDIALS fails fmi2Instantiate, not a later step
        self.pending_logs: list = []
        #: what the native loader reads after each call: [0] nonzero when the component ended the
        #: simulation (Component.terminate_simulation), [1] the time it reached (NaN: the step's end),
        #: [2] nonzero when a Co-Simulation step in event mode stopped at an event it left unhandled
        self.control = np.array([0.0, math.nan, 0.0])
        #: the FMI log categories the importer enabled (fmu_logging.BITS), set by the loader
        self.log_mask = fmu_logging.DEFAULT
        self._hooks = fmu_logging.hooks()
        self._module = component_class.__module__
        if self._module.startswith(fmu_logging.MODEL_MODULE_PREFIX):
            self._hooks.adopt(self._module)
        self.event_indicators = np.zeros(max(self.nz, 1))
        self._cs = CsShared()
        compiled = component_class._compiled_step()
        #: the component's own step in C (Component._compiled_step), None without one
        self.compiled_step = CompiledStep(*compiled) if compiled is not None else None
        self._new_component()
        self.time = 0.0
        self.stop_time = math.inf
        self.tolerance: Optional[float] = None
        self.in_initialization = False
        self._solver: Optional[Cvode] = None
        self._next_time_event: Optional[float] = None
        self._restart_solver = False  # an event handled in FMI 3.0 CS event mode changed the model
        self._real_inputs = np.array([s.value_reference for s in layout.scalars
                                      if s.causality == "input" and s.fmi_type == "Real"], dtype=np.intp)
        self._int_inputs = np.array([s.value_reference - layout.n_real for s in layout.scalars
                                     if s.causality == "input" and s.fmi_type not in ("Real", "String")],
                                    dtype=np.intp)
        self._cs.setup(self.nx, self.nz, self._real_inputs, self._int_inputs)
        # the communication grid: where it starts, its step (see _communication_point)
        self.start_time, self._grid_step = 0.0, 0.0
        self._jump_tolerance = _INPUT_JUMP_TOLERANCE
        self._jump_kept = False  # CVODE goes on over an input jump: restart if it fails there
        self.partials = DirectionalDerivatives(component_class)
        self._steps_itself = component_class.overrides_do_step()
        self._has_outputs = component_class.outputs is not Component.outputs  # else nothing to call
        # derivatives returned as a list or tuple are packed straight into the real buffer
        self._pack_derivatives = struct.Struct(f"={self.nx}d")
        #: the component's kernels compiled to C, when its FMU carries them (see native_kernels.py)
        self.native = self._load_kernels() if getattr(component_class, "native", None) is not None else None
        if self.native is not None:
            self.native.attach(self.component._real, self.component._int, self.event_indicators)
            self.partials.native = self.native
        self._hand_functions()
        # the C layer takes the steps (cs_step.c) where it has the kernels a step needs
        self._cs.enabled = int(fmu_type == CO_SIMULATION and self.nx > 0 and not self._steps_itself
                               and self.native is not None and self.native.has("derivatives")
                               and native_cs_wanted())

    def _load_kernels(self) -> Optional[NativeKernelsRuntime]:
        try:
            return NativeKernelsRuntime.load(self.resources_dir)
        except (OSError, ImportError, KeyError, AttributeError, ValueError) as exc:
            self.pending_logs.append((WARNING, "logStatusWarning",
                                      f"the compiled kernels cannot be loaded, the model runs in Python: {exc}"))
            return None

    def _pack_kernels(self) -> None:
        """The attributes the compiled kernels read, copied after the model may have changed them."""
        if self.native is not None:
            self.native.pack(self.component)

    def _pull_kernels(self) -> None:
        """The attributes compiled steps changed, copied back before the model reads them."""
        if self.native is not None:
            self.native.pull(self.component)

    def step_callable(self) -> Callable[[float, float], object]:
        """What the native layer calls for the step of a component that steps itself, when its
        compiled step does not take it: the component's ``do_step``, between copies of the
        attributes from and to the compiled step's struct when it has one."""
        if self.native is None or not self.native.has("step"):
            return self.component.do_step

        def synced(t: float, h: float) -> None:
            self.native.pull(self.component)
            self.component.do_step(t, h)
            self.native.pack(self.component)

        return synced

    def _new_component(self, buffers: Optional[tuple] = None) -> None:
        comp = self.component = self.component_class.__new__(self.component_class)
        if self.compiled_step is not None:
            self.compiled_step.ready[0] = 0  # the new component arms it when it can step in C
            comp._c_step = self.compiled_step
        comp._attach(self.resources_dir, self.pending_logs, buffers, self.control, self._module_context)
        self._hand_functions()

    def _hand_functions(self) -> None:
        """The compiled functions of the FMU's kernel library to the component (its
        ``native_functions``), when the FMU carries them."""
        native = getattr(self, "native", None)  # not yet loaded while the first component is made
        declared = self.component_class.native.functions if native is not None else {}
        if not declared:
            return
        try:
            functions = FunctionSet.load(native.library, native.function_descriptions, declared)
        except (AttributeError, KeyError, TypeError, ValueError) as exc:
            self.pending_logs.append((WARNING, "logStatusWarning",
                                      f"the compiled functions cannot be loaded, they run in Python: {exc}"))
            functions = FunctionSet.python(declared)
        self.component._native_functions = functions

    @property
    def terminate_requested(self) -> bool:
        """Whether the component ended the simulation (:meth:`Component.terminate_simulation`)."""
        return bool(self.control[0])

    @terminate_requested.setter
    def terminate_requested(self, value: bool) -> None:
        self.control[0] = 1.0 if value else 0.0
        if not value:
            self.control[1] = math.nan

    def set_log_categories(self, mask: int) -> int:
        """The categories the importer enabled (fmi2Instantiate's loggingOn, fmi2SetDebugLogging):
        the runtime formats its own messages only for these, and the model's logger makes DEBUG
        and INFO records only while some instance wants logComponent."""
        self.log_mask = mask
        if self._module.startswith(fmu_logging.MODEL_MODULE_PREFIX):
            self._hooks.want_debug(self._module, id(self), bool(mask & fmu_logging.BITS["logComponent"]))
        return OK

    def _store_derivatives(self, values: Sequence[float]) -> None:
        comp = self.component
        cls = type(values)
        if cls is list or cls is tuple:
            try:
                self._pack_derivatives.pack_into(comp._real, 8 * self.nx, *values)
                return
            except Exception:
                pass  # not a flat sequence of nx numbers: numpy converts it, or says what is wrong
        comp._real[self.nx:2 * self.nx] = _exactly(values, self.nx, "derivatives", "states")

    def _store_event_indicators(self, values: Sequence[float]) -> None:
        self.event_indicators[:] = _exactly(values, self.nz, "event_indicators", "event indicators")

    # --- what the native layer needs to know ------------------------------------------------
    def native_layout(self) -> tuple:
        """Addresses and sizes of the buffers the native layer reads and writes directly.

        Fields (bridge.c parses them in this order, format ``KnKnKnnnnKnKpppK|KnKKpKKKKKKKK``): real
        buffer, n_real, int buffer, n_int, flags (uint8 per real and int scalar), n_str, nx,
        x_offset, dx_offset, event indicators (double[nz]), nz, nominals (double[nx]), watches
        drift, steps itself, evaluates after a step, control (double[3]: terminated, time reached,
        event pending); then, for FMI 3.0: sizes3 (uint32[n_real + n_int + n_str], the element
        count of the variable whose value reference is the index, 0 inside an array), n_clocks,
        and per Clock the real-buffer index of its period Parameter (int64, -1: constant) and its
        constant interval (double, NaN where a Parameter gives it), and whether the component is
        clock-driven (:func:`.clocks.clock_driven`); then the compiled kernels' addresses
        (derivatives, event indicators, outputs, step, update; 0 for none), their attributes' struct and
        its ready flag (int[1]), all 0 without compiled kernels
        (:class:`.native_kernels.NativeKernelsRuntime`); then the step's shared state
        (:class:`.cs_native.CsShared`) where the C layer takes the Co-Simulation steps, else 0.
        FMI 3.0 value references after the scalars: ``time`` = n_real + n_int + n_str, then the
        n_clocks Clocks, then one Float64 per event indicator (Layout.first_indicator_vr)."""
        comp, layout = self.component, self.component_class._layout
        return (comp._real.ctypes.data, layout.n_real, comp._int.ctypes.data, layout.n_int,
                layout.flags.ctypes.data, layout.n_str, layout.nx, layout.x_offset,
                layout.dx_offset, self.event_indicators.ctypes.data, self.nz,
                layout.nominals.ctypes.data, self.component_class.watches_drift(), self._steps_itself,
                bool(self.nx or self.nz or self._has_outputs), self.control.ctypes.data,
                layout.sizes3.ctypes.data, layout.n_clocks, layout.clock_period_index.ctypes.data,
                layout.clock_interval.ctypes.data, self._clock_driven,
                *(self.native.layout() if self.native is not None else
                  self.compiled_step.layout() if self.compiled_step is not None else (0,) * (7 + len(TRAILING_ROLES))),
                ctypes.addressof(self._cs) if self._cs.enabled else 0)

    # --- initialization ---------------------------------------------------------------------
    def enter_initialization(self, start: float, stop: float, tolerance: float) -> int:
        """``fmi2SetupExperiment`` values (stop/tolerance NaN when undefined), then init mode."""
        self.time = self.start_time = start
        self._grid_step = 0.0
        self.stop_time = stop if not math.isnan(stop) else math.inf
        self.tolerance = tolerance if not math.isnan(tolerance) else None
        self.in_initialization = True
        self.component.setup_experiment(start, None if math.isinf(self.stop_time) else self.stop_time)
        return OK

    def exit_initialization(self, event_mode_used: float = 0.0) -> int:
        """Leave initialization mode with consistent outputs; prepare the Co-Simulation solver.

        In FMI 3.0 Co-Simulation with ``event_mode_used`` the FMU goes to Event Mode instead, and
        the importer's fmi3UpdateDiscreteStates calls do the event iteration (as in ME)."""
        self.evaluate(self.time)
        self._keep_indicators()
        self.in_initialization = False
        if self.fmu_type == CO_SIMULATION and not event_mode_used:
            self._event_iteration()
        self._pack_kernels()
        return OK

    # --- evaluation -------------------------------------------------------------------------
    def evaluate(self, t: float) -> int:
        """Compute derivatives, event indicators and outputs at ``t`` into the buffers."""
        self._pull_kernels()
        if self.native is not None and not self.in_initialization and self.native.evaluate(t, self.nx, self.nz):
            return OK
        self.evaluate_derivatives(t)
        if self._has_outputs:
            self.component.outputs(t)
        return OK

    def evaluate_derivatives(self, t: float) -> int:
        """Only what an integrator asks for: derivatives and event indicators (not outputs).

        The native layer does the same itself in Model Exchange's event and continuous-time
        modes (bridge_derivatives), calling ``derivatives`` and ``event_indicators`` directly and
        handing results that are not lists or tuples to ``_store_derivatives`` and
        ``_store_event_indicators``."""
        comp = self.component
        if self.in_initialization:
            comp.initialize(t)
        if self.nx:
            self._store_derivatives(comp.derivatives(t))
        if self.nz:
            self._store_event_indicators(comp.event_indicators(t))
        return OK

    def evaluate_outputs(self, t: float) -> int:
        """Outputs only, for getters (in initialization everything: the model initializes)."""
        self._pull_kernels()
        if self.in_initialization:
            return self.evaluate(t)
        if self._has_outputs:
            self.component.outputs(t)
        return OK

    def event_update(self, t: float) -> tuple:
        """``fmi2NewDiscreteStates``: one discrete update at ``t``.

        Returns (newDiscreteStatesNeeded, terminateSimulation, nominalsChanged,
        valuesOfContinuousStatesChanged, nextEventTimeDefined, nextEventTime).
        """
        comp, nx = self.component, self.nx
        self.partials.invalidate()
        self._pull_kernels()
        self._restart_solver = self.fmu_type == CO_SIMULATION
        handled_reported, self._cs.handled_reported = self._cs.handled_reported, 0
        states_before = comp._real[:nx].copy() if nx else None  # none: a sampled component's tick
        if self.fmu_type == MODEL_EXCHANGE and comp.needs_projection(t):
            comp.project(t)
        self.evaluate(t)
        derivatives_before = comp._real[nx: 2 * nx].copy() if nx else None
        values_before = (comp._real.copy(), comp._int.copy()) if handled_reported else None
        again = bool(comp.update(t))
        self._pack_kernels()  # the compiled kernels evaluate after the update with its attributes
        self.evaluate(t)
        self._keep_indicators()
        if values_before is not None and not again and np.array_equal(values_before[0], comp._real) \
                and np.array_equal(values_before[1], comp._int):
            # the Event Mode after events the step handled and reported: nothing left to do, and
            # the solver goes on as it would have without event mode
            self._restart_solver = False
        # A mode switch that leaves the states but changes their derivatives (a ball that starts
        # touching) is reported as changed states too: an importer that restarts its integrator
        # only on that flag (the Reference FMUs' fmusim) would otherwise go on with the solver's
        # pre-event history and miss the switch. Restarting where nothing moved costs one restart.
        changed = nx > 0 and not (np.array_equal(states_before, comp._real[:nx])
                                  and np.array_equal(derivatives_before, comp._real[nx: 2 * nx]))
        nte = comp.next_time_event(t)
        self._next_time_event = nte
        self._pack_kernels()
        if self.log_mask & _LOG_EVENTS:
            self.log(OK, "logEvents", f"event at t = {t}: another iteration {again}, states changed "
                     f"{changed}, next time event {nte}, terminate {self.terminate_requested}")
        return (again, self.terminate_requested, False, changed, nte is not None,
                float(nte) if nte is not None else 0.0)

    def activate_model_partition(self, clock: float, t: float) -> int:
        """``fmi3ActivateModelPartition`` (Scheduled Execution): the partition of Clock ``clock``
        (0-based) at its tick ``t``, with the inputs set before: the component's discrete update
        at ``t`` (its samples due there), iterated as an event iteration would, outputs evaluated."""
        self.time = t
        for _ in range(_MAX_EVENT_ITERATIONS):
            again, terminate, _, _, _, _ = self.event_update(t)
            if terminate or not again:
                return OK
        raise RuntimeError(f"the partition of Clock {int(clock) + 1} at t = {t} did not settle in "
                           f"{_MAX_EVENT_ITERATIONS} updates")

    def directional_derivative(self, t: float, unknowns: bytes, knowns: bytes, seed: bytes) -> bytes:
        """``fmi2GetDirectionalDerivative`` at ``t``: value references as uint32 bytes, the seed
        and the result as float64 bytes (see :mod:`.partials`)."""
        self._pull_kernels()
        if self.in_initialization:
            self.component.initialize(t)
        return self.partials.directional(self.component, t, unknowns, knowns, seed)

    def completed_integrator_step(self, t: float) -> bool:
        """``fmi2CompletedIntegratorStep``: True asks for a step event (the states drifted)."""
        return bool(self.component.needs_projection(t))

    # --- co-simulation ----------------------------------------------------------------------
    def do_step(self, t: float, h: float, events: float = EVENTS_INSIDE) -> int:
        """``fmi2DoStep``/``fmi3DoStep`` from ``t`` to ``t + h``: integrate with CVODE.

        ``events`` says what the step does at a state or time event in (t, t + h]:

        - ``EVENTS_INSIDE``: it handles each one inside the step (the event iteration, a solver
          restart) and goes on to ``t + h``.
        - ``EVENTS_EARLY_RETURN`` (FMI 3.0, eventModeUsed and earlyReturnAllowed): it stops at
          the first one without handling it.
        - ``EVENTS_AT_STEP_END`` (FMI 3.0, eventModeUsed without earlyReturnAllowed): it must
          reach ``t + h``, so it handles the events before that inside, as ``EVENTS_INSIDE``
          (the importer could no longer handle them at their time), and reports them at ``t + h``
          (eventHandlingNeeded: the importer's Event Mode there finds them handled, and the
          solver goes on unless it changes something); one at ``t + h`` itself (a time event on
          the communication point, a root found there) it leaves to the importer.

        The contract with the native layer, in ``control`` (any loop that replaces this one, in C
        too, keeps it): [0] nonzero when the component ended the simulation, [1] then the time it
        ended at; [2] = 1 when the step left an event pending, [1] then the time reached, where
        the event is (0 otherwise, reset at each step's start); [1] NaN: the step's end. An event
        left pending is handled by the importer's Event Mode (:meth:`event_update`), and the next
        step restarts the solver there. In event mode (either value) a clock-driven component's
        events are its Clocks' ticks, which the importer activates in Event Mode: its steps report
        none.

        The native layer has checked that ``t`` is the FMU's time. A component that steps itself
        never comes here: the native layer calls its ``do_step``, sets ``time`` before anything
        reads it and calls :meth:`evaluate` when there is something to evaluate (bridge.c,
        step_itself; ``native_layout`` tells it which components)."""
        comp = self.component
        t_end = self._communication_point(t, h)
        self.control[2] = 0.0
        inputs_changed = self._inputs_changed()  # since the last step (kept: the next step compares with these)
        if self._solver is not None and ((inputs_changed and self._restart_for_inputs(t_end)) or self._restart_solver):
            # a zero-order-hold input jumped too far for CVODE's history (the right-hand side is
            # discontinuous at t), or the importer handled an event here
            self._reinit(self.time, comp._real[: self.nx])
        if self._restart_solver:
            self._cs.event_time = self.time  # the solver starts here after the importer's Event Mode
        self._restart_solver = False
        handled = False
        if inputs_changed and self._indicators_crossed():
            # the inputs set at t moved an event indicator across zero (a `when` on an input, a
            # relay's threshold): an event at t, before anything moves
            self._event_iteration()
            handled = True
        while self.time < t_end and not self.terminate_requested:
            nte = None if events != EVENTS_INSIDE and self._clock_driven else self._next_time_event
            t_stop = min(t_end, nte) if nte is not None and nte > self.time else t_end
            root = False
            if t_stop - self.time <= _TINY * max(1.0, abs(t_stop)):
                self.time = t_stop  # a round-off sliver (a time event at a step end): no motion
            elif self.nx:
                root = self._integrate_to(t_stop)
            else:
                # no states, no solver to find roots: an indicator that crossed zero over the step
                # (with time) is an event at its end
                self.time = t_stop
                root = self._indicators_crossed()
            time_event = nte is not None and self.time >= nte - _TINY * max(1.0, abs(nte))
            at_end = self.time >= t_end - _TINY * max(1.0, abs(t_end))
            # a root within round-off of the event the solver restarted at is that event's own
            # indicator crossing back (CVODE returns a root just past the crossing, where the
            # indicator has its new sign; the event's update sends it back over zero): handled
            # inside like any event, never reported to the importer a second time
            echo = root and abs(self.time - self._cs.event_time) <= _TINY * max(1.0, abs(self.time))
            if (time_event or (root and not echo)) and (
                    events == EVENTS_EARLY_RETURN or (events == EVENTS_AT_STEP_END and at_end)):
                self.control[1:] = self.time, 1.0  # fmi3DoStep: eventHandlingNeeded here
                self.evaluate(self.time)
                self._keep_indicators()
                self._derivatives_after_step = None  # the event restarts the solver
                return OK
            if root or time_event:
                self._event_iteration()
                handled = True
        if self.terminate_requested:
            self.control[1] = self.time  # fmi2LastSuccessfulTime
        else:
            self.time = t_end  # remove round-off so the next doStep matches exactly
        self.evaluate(self.time)
        self._keep_indicators()
        if handled and events == EVENTS_AT_STEP_END and not self.terminate_requested:
            self.control[1:] = self.time, 1.0  # eventHandlingNeeded for the events handled inside
            self._cs.handled_reported = 1
        if self.nx:
            self._derivatives_after_step = comp._real[self.nx: 2 * self.nx].tolist()
        return DISCARD if self.terminate_requested else OK

    def _communication_point(self, t: float, h: float) -> float:
        """``t + h``, or the grid point ``start + k H`` where it differs from that by round-off.

        Importers add up time differently (fmpy: ``t += h``; the Reference FMUs' fmusim:
        ``t = start + k h``), so the same step can end an ulp or a few apart. CVODE's steps are
        sensitive to that: where its proposed step and the rest of the interval to the stop time
        agree to round-off, an ulp decides between clipping a step and taking it whole, and the
        step sequences (and results, at the tolerance's level) part. On a grid every importer
        gives CVODE the same stop times, bit for bit. The grid's step H is the one the steps
        so far ended on (a step cut short at an event, in FMI 3.0 event mode, and the rest of it
        end on the grid of the full steps), else this step's ``h``."""
        t_end = t + h
        for step in (self._grid_step, h):
            if step > 0.0:
                on_grid = self.start_time + round((t_end - self.start_time) / step) * step
                if abs(on_grid - t_end) <= _TINY * max(1.0, abs(t_end)):
                    self._grid_step = step
                    return on_grid
        return t_end

    def _integrate_to(self, t_stop: float) -> bool:
        if self._solver is None:
            self._solver = self._make_solver()
        solver, comp = self._solver, self.component
        root = self._advance_over_jump(t_stop) if self._jump_kept else solver.advance(t_stop)
        self._cs.solver_t = solver.t
        comp._real[: self.nx] = solver.x
        self.time = solver.t if root else t_stop
        return root

    def _advance_over_jump(self, t_stop: float) -> bool:
        # the first advance on a history kept over an input jump: should CVODE's error test still
        # fail down to the minimum step there (the jump was larger for its steps than judged),
        # a restart from where this call began gets through, and a second failure is real
        solver = self._solver
        t0, x0 = self._cs.solver_t, solver.x.copy()
        self._jump_kept = False
        solver.log_errors = False  # recovered from below: no error for the importer's log
        try:
            return solver.advance(t_stop)
        except _CVODE["error"]:
            solver.log_errors = True
            self._reinit(t0, x0)
            return solver.advance(t_stop)
        finally:
            solver.log_errors = True

    def _inputs_changed(self) -> bool:
        comp, cs = self.component, self._cs  # lists: cheaper to compare than arrays, at a handful of inputs
        current = comp._real.take(self._real_inputs).tolist() + comp._int.take(self._int_inputs).tolist()
        changed = not cs.inputs_valid or current != cs.inputs_view.tolist()
        cs.inputs_view[:] = current  # as floats, as cs_step.c keeps them
        cs.inputs_valid = 1
        return changed

    def _reinit(self, t: float, x: np.ndarray) -> None:
        """Restart the solver at ``(t, x)`` (its time kept where a step in C reads it)."""
        self._solver.reinit(t, x)
        self._cs.solver_t = t

    def _keep_indicators(self) -> None:
        """The event indicators as they stand now (after a step or an event), for the next step to
        tell whether its inputs or its time moved one across zero."""
        if self.nz:
            self._cs.pre_indicators_view[:] = self.event_indicators[: self.nz]
            self._cs.pre_indicators_valid = 1

    def _indicators_crossed(self) -> bool:
        """Whether an event indicator, evaluated now, is on the other side of zero than where the
        last step or event left it (the FMI domain: ``z > 0`` or ``z <= 0``)."""
        if not self.nz or not self._cs.pre_indicators_valid:
            return False
        self._pull_kernels()
        now = self.component.event_indicators(self.time)
        self._store_event_indicators(now)
        before = self._cs.pre_indicators_view.tolist()
        return any((a > 0.0) != (b > 0.0) for a, b in zip(before, self.event_indicators[: self.nz].tolist()))

    def _restart_for_inputs(self, t_end: float) -> bool:
        """Whether CVODE must restart because the held inputs changed since the last step.

        A zero-order-hold input that jumps makes the right-hand side f discontinuous at the
        communication point, and CVODE's history (order, step size, Nordsieck array) describes
        the solution before it. A restart (order 1, a tiny first step) at every change made a
        chain of CS units, each driven by the last one's output, 4-6x as costly as the same
        units unconnected. So the history is kept where the jump is small: its first-order
        effect over the step, ``h (f_new - f_old)`` at the current state in CVODE's error norm
        (1 = the tolerance), is at most ``cs_options["input_jump_tolerance"]``
        (default 10; 0 restarts at every change). CVODE's error test then takes the kink in its
        stride (at worst it retries with a smaller step); a larger jump (a step input, a
        switching controller's torque) restarts as before. docs/components.md has the figures.
        Asked only when the inputs changed (:meth:`_inputs_changed`)."""
        before = self._derivatives_after_step
        if self._jump_tolerance <= 0 or before is None or self._restart_solver:
            restart = True
        else:
            # over the whole step, not CVODE's next one: that one shrinks after a kink, which made
            # the next jump look small: the decision depends on inputs and states, not on that history
            jump = [new - old for new, old in zip(self._derivatives_now(), before)]
            restart = (t_end - self.time) * self._solver.error_norm(jump) > self._jump_tolerance
        self._jump_kept = not restart
        return restart

    def _derivatives_now(self) -> Sequence[float]:
        """The derivatives at the current time and states (by the compiled kernel where there is one)."""
        if self.native is not None and self.native.derivatives(self.time):
            return self.component._real[self.nx: 2 * self.nx].tolist()
        return self.component.derivatives(self.time)

    def _make_solver(self) -> Cvode:
        Cvode = _cvode_class(self._module_context)
        options = dict(self.component_class.cs_options)
        rtol = options.pop("rtol", self.tolerance or self.component_class.default_experiment.tolerance)
        rtol *= options.pop("rtol_factor", 1.0)
        self._jump_tolerance = float(options.pop("input_jump_tolerance", _INPUT_JUMP_TOLERANCE))
        # as ME importers do: absolute tolerance from the states' nominal values
        atol = options.pop("atol", rtol * self.component_class._layout.nominals)
        comp, nx = self.component, self.nx

        def rhs(t: float, x: np.ndarray, xdot: np.ndarray) -> None:
            comp._real[:nx] = x
            xdot[:] = comp.derivatives(t)

        def roots(t: float, x: np.ndarray, g: np.ndarray) -> None:
            comp._real[:nx] = x
            g[:] = comp.event_indicators(t)

        def project(t: float, x: np.ndarray, correction: np.ndarray) -> None:
            comp._real[:nx] = x
            comp.project(t)
            correction[:] = comp._real[:nx] - x

        if self.component_class.overrides_project():
            options["project"] = project
        if self.component_class.provides_jacobian():
            partials = self.partials

            def jacobian(t: float, x: np.ndarray, J: np.ndarray) -> None:
                comp._real[:nx] = x
                J[:, :] = partials.state_jacobian(comp, t)

            options["jacobian"] = jacobian
        if self.native is not None and self.native.has("derivatives"):
            layout = self.component_class._layout
            options["native"] = self.native.cvode_callbacks(layout.x_offset, layout.dx_offset, nx, self.nz)
        if self.log_mask & _LOG_SOLVER:
            self.log(OK, "logSolver", f"CVODE ({options.get('method', 'bdf')}) from t = {self.time}: "
                     f"{nx} states, {self.nz} event indicators, rtol = {rtol:g}, "
                     f"atol = {np.array2string(np.atleast_1d(atol), precision=3)}")
        solver = Cvode(rhs, comp._real[:nx].copy(), self.time, roots=roots if self.nz else None,
                       n_roots=self.nz, rtol=rtol, atol=atol, **options)
        self._cs.attach_solver(solver)
        return solver

    def _event_iteration(self) -> None:
        for _ in range(_MAX_EVENT_ITERATIONS):
            again, terminate, _, _, _, _ = self.event_update(self.time)
            if terminate or not again:
                if self._solver is not None:
                    # unlike an ME importer, our own solver restarts after every event: the
                    # right-hand side may jump even when no state does
                    self._reinit(self.time, self.component._real[: self.nx])
                    self._restart_solver = False
                    self._cs.event_time = self.time
                return
        raise RuntimeError(f"event iteration at t = {self.time} did not converge in "
                           f"{_MAX_EVENT_ITERATIONS} iterations")

    # --- what the C step (native/cs_step.c) asks of Python --------------------------------------
    def cs_prepare(self) -> int:
        """A step in C needs a solver: made here, as the Python step makes it (:meth:`_integrate_to`)."""
        self._solver = self._make_solver()
        self._solver.callback_error = None
        return OK

    def cs_event(self) -> int:
        """A step in C reached a state or time event at :attr:`time`: the event iteration."""
        self._event_iteration()
        return OK

    def cs_failed(self, flag: float, t: float, retry: float) -> int:
        """CVODE failed in a step in C (``flag`` < 0, at ``t``): raises what the Python step
        raises; with ``retry`` (the first advance over a kept input jump), OK unless a callback
        raised: the C step then restarts the solver and tries once more."""
        solver = self._solver
        error, solver.callback_error = solver.callback_error, None
        if error is not None:
            raise error
        if retry:
            return OK
        raise _CVODE["error"](f"CVODE failed with flag {int(flag)} at t = {t:.9g}: {solver.last_message}")

    # --- strings ----------------------------------------------------------------------------
    def get_string(self, index: int) -> str:
        """Value of the ``index``-th string scalar."""
        return self.component._str[index]

    def set_string(self, index: int, value: str) -> int:
        """Set the ``index``-th string scalar."""
        self.component._str[index] = value
        return OK

    # --- FMU state --------------------------------------------------------------------------
    def get_state(self) -> dict:
        """A snapshot of everything: buffers, internal component attributes, time, mode.

        The CS solver starts afresh here too, so that continuing from this point and restoring
        this snapshot later follow exactly the same path: CVODE's history and saved Newton matrix
        cannot be saved, and even ``CVodeReInit`` keeps the latter.
        """
        comp = self.component
        self._drop_solver()
        self._pull_kernels()
        return {
            "real": comp._real.copy(), "int": comp._int.copy(), "str": list(comp._str),
            "internal": comp.internal_state(), "time": self.time,
            "stop_time": self.stop_time, "tolerance": self.tolerance,
            "next_time_event": self._next_time_event, "in_initialization": self.in_initialization,
            "terminate_requested": self.terminate_requested,
            "pre_indicators": self._cs.pre_indicators_view.copy() if self._cs.pre_indicators_valid else None,
        }

    def set_state(self, state: dict) -> int:
        """Restore a snapshot from :meth:`get_state`; the CS solver restarts from it. A snapshot
        that does not fit (deserialized from damaged bytes) raises before anything changes (the
        component's own part: before it changes, by default)."""
        comp = self.component
        self._check_state(state)
        comp._real[:] = state["real"]
        comp._int[:] = state["int"]
        comp._str[:] = state["str"]
        comp.restore_internal_state(state["internal"])
        self.time = state["time"]
        # the experiment's set-up it was taken under (a snapshot from an older runtime has none)
        self.stop_time = state.get("stop_time", self.stop_time)
        self.tolerance = state.get("tolerance", self.tolerance)
        self.partials.invalidate()
        self._next_time_event = state["next_time_event"]
        self.in_initialization = state["in_initialization"]
        self.terminate_requested = state["terminate_requested"]
        pre_indicators = state.get("pre_indicators")  # a snapshot from an older runtime has none
        if pre_indicators is not None:
            self._cs.pre_indicators_view[:] = pre_indicators
        self._cs.pre_indicators_valid = int(pre_indicators is not None)
        self._drop_solver()  # a fresh solver, as in get_state()
        self._pack_kernels()
        return OK

    def _check_state(self, state: Any) -> None:
        comp = self.component
        if not isinstance(state, dict) or not _STATE_KEYS <= state.keys():
            raise ValueError("not an FMU state of this FMU: it lacks the values of a snapshot")
        arrays = [("real", comp._real), ("int", comp._int)]
        if state.get("pre_indicators") is not None:
            arrays.append(("pre_indicators", self._cs.pre_indicators_view))
        for key, buffer in arrays:
            value = state[key]
            if not isinstance(value, np.ndarray) or value.shape != buffer.shape or value.dtype != buffer.dtype:
                raise ValueError(f"not an FMU state of this FMU: its {key} values are not {buffer.shape[0]} "
                                 f"{buffer.dtype} values")
        strings = state["str"]
        if not isinstance(strings, list) or len(strings) != len(comp._str) or \
                not all(isinstance(text, str) for text in strings):
            raise ValueError(f"not an FMU state of this FMU: its string values are not {len(comp._str)} strings")
        if not isinstance(state["time"], (float, int)):
            raise ValueError("not an FMU state of this FMU: its time is not a number")

    def serialize_state(self, state: dict) -> bytes:
        """Bytes for ``fmi2SerializeFMUstate``."""
        if not self.component_class.can_serialize_state:
            raise RuntimeError(f"{self.component_class.fmi_model_name()} cannot serialize its FMU state "
                               "(canSerializeFMUstate is false); get and set it instead")
        # a component given functions may keep them in its state (an estimator its kernels)
        functions = FunctionSet if "_native_functions" in vars(self.component) else None
        with self._module_context():
            return dump_state(state, functions)

    def deserialize_state(self, data: bytes) -> dict:
        """Inverse of :meth:`serialize_state`."""
        with self._module_context():
            return load_state(data, self.component_class.__module__, self.resources_dir,
                              self.component.native_functions)

    # --- life cycle -------------------------------------------------------------------------
    def terminate(self) -> int:
        """``fmi2Terminate``."""
        return OK

    def reset(self) -> int:
        """``fmi2Reset``: back to the freshly instantiated state (same buffer addresses)."""
        old = self.component
        self._new_component((old._real, old._int, old._str))
        self.time, self.stop_time, self.tolerance = 0.0, math.inf, None
        self.in_initialization = self.terminate_requested = False
        self._drop_solver()
        self._cs.pre_indicators_valid = 0
        self._next_time_event = None
        self._pack_kernels()  # the fresh component's (C runs the kernels only after initialization)
        return OK

    def free(self) -> None:
        """``fmi2FreeInstance``: release the solver now rather than at the next garbage collection."""
        self._drop_solver()
        if self._module.startswith(fmu_logging.MODEL_MODULE_PREFIX):
            self._hooks.want_debug(self._module, id(self), None)

    def _drop_solver(self) -> None:
        self._cs.detach_solver()
        if self._solver is not None:
            self._solver.free()
            self._solver = None
        self._derivatives_after_step, self._jump_kept = None, False

    def log(self, status: int, category: str, message: str) -> None:
        """Queue a message for the importer's logger."""
        self.pending_logs.append((status, category, message))


def _exactly(values: Sequence[float], n: int, hook: str, what: str) -> np.ndarray:
    """``values`` as n floats; a clear error rather than numpy broadcasting a wrong count."""
    array = np.asarray(values, dtype=float)
    if array.size != n:
        raise ValueError(f"{hook}() returned {array.size} values for {n} {what}")
    return array.reshape(n)
