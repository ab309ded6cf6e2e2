"""The master's fixed-step loop run in C (``native/fixed_step.c``) for the common case.

A communication step of the Python loop costs a dozen ctypes calls and their Python around
them (the flagship: about 30 us a step, more than the trajectory and controller FMUs' own work).
:class:`NativeLoop` lays the same calls out once as a plan (per unit, in stepping order: the
batched fmi2Set<Type> of its inputs, fmi2DoStep or a Model Exchange unit's Runge-Kutta step,
the batched fmi2Get<Type> of its outputs) and runs many steps per foreign call, the recorded
rows gathered into a block the result writer takes at once. The calls, their order and their
arguments are those of the Python loop, bit for bit.

It covers Co-Simulation units and Model Exchange units on a fixed-step Runge-Kutta method
without time events or discrete inputs (event indicators are compared after every Runge-Kutta
step, as :class:`.ExplicitRungeKutta` does), with numeric (not String) values and no algebraic
loop; FMI 3.0 units too where their values are Float64, Int32 or Boolean (an fmi3DoStep that
returns an event, an early return or a termination hands its step back), and the ticks of a
Co-Simulation unit's periodic input Clocks at communication points (a tick inside a step hands
the step back; :mod:`.clocks`). Anything else runs in
Python; so do the steps after a C run stopped at an event (a state event is located by the
solver's bisection), a failure or a termination, which the master finishes exactly as its
Python loop would.
"""
from __future__ import annotations

import ctypes
import threading
from ctypes import POINTER, c_double, c_int, c_long, c_size_t, c_void_p
from pathlib import Path
from typing import Any, Callable, List, Optional, Sequence, Tuple

import numpy as np

from deltafmi.toolchain import plain_c_library

from .explicit_rk import ExplicitRungeKutta
from .parallel import pooled
from .unit_base import Unit, _Inputs, _Outputs, function_address

__all__ = ["BEHIND", "CLOCK_INSIDE", "FETCH", "LIVE", "NativeLoop", "PULL", "RAN", "RK_FAILED", "ROWS_FULL",
           "STATE_EVENT", "STEP", "STEP_EVENT", "STEP_RETURNED", "TERMINATED", "UNSETTLED"]

SET_REAL, GET_REAL, SET_INT, GET_INT, DO_STEP, ME_STEP, SET_BOOL3, GET_BOOL3, CLOCK_TICK = range(9)
#: why a C run stopped
RAN, FAILED, STEP_EVENT, TERMINATED, RK_FAILED, ROWS_FULL, STATE_EVENT, STEP_RETURNED, CLOCK_INSIDE, UNSETTLED, \
    BEHIND, LIVE = range(12)
#: the FMI 3.0 type the C loop exchanges on each bus (others: the Python loop)
_FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
_SET, _GET = {"Real": SET_REAL, "Integer": SET_INT, "Boolean": SET_INT}, \
    {"Real": GET_REAL, "Integer": GET_INT, "Boolean": GET_INT}
#: the ME_STEP call that failed (Plan.call)
ME_CALLS = ("fmi2SetTime", "fmi2SetContinuousStates", "fmi2CompletedIntegratorStep", "fmi2GetEventIndicators")
#: the CLOCK_TICK call that failed (Plan.call)
CLOCK_CALLS = ("fmi3EnterEventMode", "fmi3SetClock", "fmi3UpdateDiscreteStates", "fmi3EnterStepMode")
#: the actions of a unit in a step, in the Python loop's terms
PULL, STEP, FETCH = "pull", "do_step", "fetch"


class _Op(ctypes.Structure):
    _fields_ = [("kind", c_int), ("multiple", c_int), ("function", c_void_p), ("component", c_void_p),
                ("vrs", c_void_p), ("n", c_size_t), ("values", c_void_p), ("bus", c_void_p), ("index", c_void_p),
                ("factor", c_void_p), ("offset", c_void_p), ("no_prior_state", c_int),
                ("erk", c_void_p), ("erk_plan", c_void_p), ("erk_current", c_void_p), ("holds_end", c_int),
                ("x", c_void_p), ("nx", c_size_t), ("t", c_void_p),
                ("max_step", c_double), ("set_time", c_void_p), ("set_states", c_void_p), ("completed", c_void_p),
                ("nz", c_size_t), ("get_indicators", c_void_p), ("z", c_void_p), ("z_last", c_void_p),
                ("z_valid", c_void_p), ("x0", c_void_p),
                ("fmi3", c_int), ("positions", c_void_p), ("n_index", c_size_t), ("n_values", c_size_t),
                ("flags", c_int), ("step_status", c_int), ("last_time", c_double),
                ("clock_first", c_void_p), ("clock_count", c_void_p), ("clock_interval", c_void_p),
                ("clock_activated", c_void_p), ("due_vrs", c_void_p), ("on", c_void_p),
                ("enter_event_mode", c_void_p), ("update_discrete_states", c_void_p), ("enter_step_mode", c_void_p),
                ("group", c_int), ("group_status", c_int)]


class _RowPart(ctypes.Structure):
    _fields_ = [("bus", c_void_p), ("is_int", c_int), ("n", c_size_t), ("index", c_void_p), ("columns", c_void_p)]


class _Component(ctypes.Structure):
    _fields_ = [("ops", c_void_p), ("n_ops", c_size_t), ("parts", POINTER(_RowPart)), ("n_parts", c_size_t)]


class _Pace(ctypes.Structure):
    _fields_ = [("t0", c_double), ("wall0", c_double), ("speed", c_double), ("spin", c_double), ("period", c_double),
                ("released", c_double), ("lateness", c_void_p), ("count", c_void_p), ("capacity", c_long),
                ("late", c_void_p), ("busy", c_void_p), ("behind", c_void_p), ("stop_behind", c_int),
                ("last_busy", c_double), ("cpu", c_double), ("wall", c_double), ("polled", c_double),
                ("stream", c_int), ("stop_request", c_int), ("published", c_long), ("taken", c_long),
                ("lead", c_double), ("sample", c_void_p), ("sample_context", c_void_p)]


class _Plan(ctypes.Structure):
    _fields_ = [("ops", POINTER(_Op)), ("n_ops", c_size_t), ("parts", POINTER(_RowPart)), ("n_parts", c_size_t),
                ("width", c_size_t), ("start", c_double), ("h", c_double), ("stop", c_double),
                ("n_steps", c_long), ("last", c_long), ("every", c_long),
                ("op", c_long), ("status", c_int), ("call", c_int), ("time", c_double), ("rk_time", c_double),
                ("rk_step", c_double), ("op_seconds", c_void_p), ("pace", POINTER(_Pace)), ("threads", c_int),
                ("pool", c_void_p), ("gil_released", c_int), ("step_start", c_void_p),
                ("components", POINTER(_Component)), ("n_components", c_size_t), ("fixed_parts", POINTER(_RowPart)),
                ("n_fixed_parts", c_size_t), ("sink_put", c_void_p), ("sink", c_void_p), ("sink_every", c_long),
                ("sink_finite", c_int), ("sink_rows", c_long), ("sink_queued", c_long), ("deadline", c_double)]


_kernels: dict = {}
_end: Optional[Any] = None


def _steps_function(release_gil: bool = False) -> Any:
    """The C loop's entry, called with the GIL held (an FMU that runs Python enters it without
    taking the GIL again) or, for a paced run that mostly waits, released (the process's other
    Python threads run meanwhile; our FMUs take the GIL where they run Python)."""
    global _end
    kernel = _kernels.get(release_gil)
    if kernel is None:
        loader = ctypes.CDLL if release_gil else ctypes.PyDLL
        library = loader(str(plain_c_library(Path(__file__).parent / "native" / "fixed_step.c")))
        if _end is None:
            _end = library.deltafmi_fixed_steps_end
            _end.argtypes = [POINTER(_Plan)]
            _end.restype = None
        kernel = _kernels[release_gil] = library.deltafmi_fixed_steps
        kernel.argtypes = [POINTER(_Plan), c_long, c_long, c_void_p, c_long, POINTER(c_long), POINTER(c_long)]
        kernel.restype = c_int
    return kernel


def _address(handle: Any) -> Any:
    """An instance handle's address (fmpy keeps an int, or a ctypes pointer)."""
    return getattr(handle, "value", handle)


def _pointer(array: Optional[np.ndarray]) -> Optional[int]:
    return None if array is None else array.ctypes.data


def _fits(unit: Unit) -> bool:
    """Whether the C loop can step ``unit`` as the Python loop does (see the module docstring; an
    FMI 3.0 unit's values must be Float64 on the Real bus, Int32 on the Integer bus or Boolean)."""
    if unit.fmi3 and not (all(i.values.dtype in (i.bus.dtype, np.bool_) for i in unit.inputs if isinstance(i, _Inputs))
                          and all(o.staging is None or o.staging.dtype == np.bool_
                                  for o in unit.outputs if isinstance(o, _Outputs))):
        return False
    if not all(isinstance(i, _Inputs) and i.kind in _SET for i in unit.inputs):
        return False
    if any(i.factor is not None and i.kind != "Real" for i in unit.inputs):
        return False
    if not all(isinstance(o, _Outputs) and o.kind in _GET for o in unit.outputs):
        return False
    clocks = getattr(unit, "clocks", None)
    if unit.interface == "CS":
        return clocks is None or clocks.steps_in_c
    return unit.interface == "ME" and not unit._discrete_inputs and isinstance(unit.solver, ExplicitRungeKutta)


def _slice_address(outputs: _Outputs) -> int:
    """The address of the first bus slot of ``outputs``."""
    return outputs.bus.ctypes.data + outputs.slots.start * outputs.bus.itemsize


def _function(unit: Unit, verb: str, kind: str) -> str:
    """The FMI function that sets or gets (``verb``) values of bus ``kind`` for ``unit``."""
    return f"fmi3{verb}{_FMI3_TYPES[kind]}" if unit.fmi3 else f"fmi2{verb}{kind}"


class _Indicators:
    """An ME unit's event indicators as the C loop compares them, and the solver's copy of the
    last ones (``ExplicitRungeKutta._z``: None until first read) handed over around each run."""

    def __init__(self, nz: int, nx: int) -> None:
        self.z, self.z_last = np.zeros(max(nz, 1)), np.zeros(max(nz, 1))
        self.valid = np.zeros(1, dtype=np.intc)
        self.x0 = np.zeros(max(nx, 1))
        self.nz = nz

    def take(self, solver: ExplicitRungeKutta) -> None:
        last = solver.last_indicators
        self.valid[0] = last is not None
        if last is not None:
            self.z_last[:self.nz] = last

    def give(self, solver: ExplicitRungeKutta) -> None:
        solver.last_indicators = self.z_last[:self.nz].copy() if self.valid[0] else None


class NativeLoop:
    """The fixed-step loop of one master run as a C plan; see the module docstring.

    ``actions``: (unit, PULL | STEP | FETCH, step multiple) in the order one step runs them;
    ``sampler``: the master's row sampler (its parts are gathered in C as it gathers them);
    ``groups``: per action, the group of a STEP that ``threads`` threads take at once with the
    consecutive STEPs of its group (0: none; :mod:`.parallel` says which).
    """

    def __init__(self, actions: Sequence[Tuple[Unit, str, int]], sampler: Any, start: float, h: float,
                 stop: float, n_steps: int, last: int, every: int, block_rows: int = 256,
                 groups: Sequence[int] = (), threads: int = 1) -> None:
        self.actions = list(actions)
        self._keep: List[Any] = []  # what the plan points into
        ops: List[_Op] = []
        self.op_action: List[int] = []
        self.op_function: List[str] = []  # the fmi2 function of each operation (for messages)
        self._me: List[Tuple[Any, int, np.ndarray]] = []  # (unit, op index, its solver time box)
        self._indicators: dict = {}  # ME unit name -> its _Indicators
        for a, (unit, action, m) in enumerate(self.actions):
            for op, function in self._ops(unit, action, m):
                if op.kind == DO_STEP and a < len(groups):
                    op.group = groups[a]
                self.op_action.append(a)
                self.op_function.append(function)
                ops.append(op)
        self._ops_array = (_Op * max(1, len(ops)))(*ops)
        #: what it was laid out for, :meth:`key_of` (None: not kept for :meth:`renew`)
        self.key: Optional[Tuple[Any, ...]] = None
        parts = [_RowPart(_pointer(bus), int(bus.dtype != np.float64), len(index), _pointer(index), _pointer(columns))
                 for bus, index, columns in sampler._parts]
        self._keep.append(sampler)
        self._parts_array = (_RowPart * max(1, len(parts)))(*parts)
        width = len(sampler.row)
        self.rows = np.empty((block_rows, width + 1))
        self.plan = _Plan(self._ops_array, len(ops), self._parts_array, len(parts), width, start, h, stop,
                          n_steps, last, every, 0, 0, 0, 0.0, 0.0, 0.0, None, None, threads, None, 0, None)
        self._pace: Optional[_Pace] = None
        self._paced: Optional[Any] = None
        self._count = np.zeros(1, dtype=np.int_)
        self._count_before = 0
        #: set :meth:`timed` to have the C loop add up the wall time of each operation
        self.op_seconds: Optional[np.ndarray] = None
        #: set :meth:`keep_step_start` to have the C loop gather the recorded values at each step's start here
        self.step_start: Optional[np.ndarray] = None
        self._run = _steps_function()
        self._k_done, self._n_rows = c_long(0), c_long(0)
        #: the units of each component stepped in blocks (:meth:`_plan_components`; empty: none)
        self.components: List[List[str]] = []
        if threads > 1:
            self._plan_components(sampler)
        # the plan and its operations as laid out, for renew (C writes its outputs into both)
        self._pristine = (bytes(self.plan), bytes(self._ops_array), len(self._keep))

    @staticmethod
    def key_of(actions: Sequence[Tuple[Unit, str, int]], sampler: Any, start: float, h: float, stop: float,
               n_steps: int, last: int, every: int, block_rows: int = 256, groups: Sequence[int] = (),
               threads: int = 1) -> Tuple[Any, ...]:
        """What a plan made with these arguments depends on: the units by name, FMU instance and
        instance handle (their value holders and functions go with them, see :meth:`renew`),
        the actions, the row sampler and the grid."""
        units = tuple((unit.name, action, m, id(unit.fmu), _address(unit.fmu.component), unit.interface,
                       getattr(unit, "clocks", None) is None) for unit, action, m in actions)
        return units, id(sampler), start, h, stop, n_steps, last, every, block_rows, tuple(groups), threads

    def renew(self, actions: Sequence[Tuple[Unit, str, int]]) -> None:
        """Make the plan run again as new, for the units ``actions`` of a later run whose
        :meth:`key_of` is :attr:`key` (a study's next case on the same FMU instances and wiring: the
        same value holders, buses, functions and handles, new unit objects and solvers): the plan
        and its operations set back to what construction laid out, then each unit's own part
        (a Model Exchange unit's solver, the ``noSetFMUStatePriorToCurrentPoint`` flags) taken
        from the new units. Not for plans stepping on threads (``threads`` > 1)."""
        plan_bytes, ops_bytes, kept = self._pristine
        ctypes.memmove(ctypes.addressof(self.plan), plan_bytes, len(plan_bytes))
        ctypes.memmove(ctypes.addressof(self._ops_array), ops_bytes, len(ops_bytes))
        del self._keep[kept:]
        self.actions = list(actions)
        ops = self._ops_array
        for i, a in enumerate(self.op_action):
            if ops[i].kind == DO_STEP:
                ops[i].no_prior_state = self.actions[a][0].no_prior_state
        me = []
        for _, index, box in self._me:
            unit = self.actions[self.op_action[index]][0]
            solver, op = unit.solver, ops[index]
            op.erk, op.erk_plan, op.erk_current = solver.kernel
            op.x, op.max_step, op.no_prior_state = solver.x.ctypes.data, solver.max_step, unit.no_prior_state
            box[0] = solver.t
            me.append((unit, index, box))
            self._keep.append(solver)
        self._me = me
        self._pace = self._paced = None
        self._count[0] = self._count_before = 0
        self.op_seconds = self.step_start = None
        self._run = _steps_function()
        self._k_done.value = self._n_rows.value = 0

    def _plan_components(self, sampler: Any) -> None:
        """Blocks of steps (``native/fixed_step.c``): when every unit steps on the threads
        (:func:`.parallel.pooled`) and they fall into two or more components that exchange no
        values (no unit's input reads a bus slot another component's outputs write), each
        component's ops and the recorded values its outputs write; the recorded values no op
        writes are the calling thread's."""
        units = list(dict.fromkeys(unit for unit, _, _ in self.actions))
        if len(units) < 2 or not all(pooled(u) for u in units):
            return
        parent = list(range(len(units)))

        def root(i: int) -> int:
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        writer: dict = {}  # (bus address, slot) -> the unit whose outputs write it
        for u, unit in enumerate(units):
            for outputs in unit.outputs:
                for slot in range(outputs.slots.start, outputs.slots.stop):
                    writer[(outputs.bus.ctypes.data, slot)] = u
        for u, unit in enumerate(units):
            for inputs in unit.inputs:
                for slot in inputs.index.tolist():
                    w = writer.get((inputs.bus.ctypes.data, slot))
                    if w is not None:
                        parent[root(w)] = root(u)
        roots = list(dict.fromkeys(root(u) for u in range(len(units))))
        if len(roots) < 2:
            return
        component_of = {unit.name: roots.index(root(u)) for u, unit in enumerate(units)}
        ops: List[List[int]] = [[] for _ in roots]
        for i, a in enumerate(self.op_action):
            ops[component_of[self.actions[a][0].name]].append(i)
        owned: List[List[Tuple[np.ndarray, List[int], List[int]]]] = [[] for _ in roots]
        fixed: List[Tuple[np.ndarray, List[int], List[int]]] = []
        for bus, index, columns in sampler._parts:
            split: dict = {}
            for slot, column in zip(index.tolist(), columns.tolist()):
                w = writer.get((bus.ctypes.data, slot))
                entry = split.setdefault(-1 if w is None else roots.index(root(w)), ([], []))
                entry[0].append(slot)
                entry[1].append(column)
            for c, (slots, cols) in split.items():
                (fixed if c < 0 else owned[c]).append((bus, slots, cols))

        def row_parts(parts: Sequence[Tuple[np.ndarray, List[int], List[int]]]) -> Any:
            made = []
            for bus, slots, cols in parts:
                index, columns = np.array(slots, dtype=np.intp), np.array(cols, dtype=np.intp)
                self._keep += [index, columns]
                made.append(_RowPart(_pointer(bus), int(bus.dtype != np.float64), len(index), _pointer(index),
                                     _pointer(columns)))
            return (_RowPart * max(1, len(made)))(*made), len(made)

        components = []
        for c in range(len(roots)):
            indices = np.array(ops[c], dtype=np.int_)
            parts, n = row_parts(owned[c])
            self._keep += [indices, parts]
            components.append(_Component(_pointer(indices), len(indices), parts, n))
        self._components = (_Component * len(components))(*components)
        fixed_parts, n_fixed = row_parts(fixed)
        self._keep.append(fixed_parts)
        self.plan.components, self.plan.n_components = self._components, len(components)
        self.plan.fixed_parts, self.plan.n_fixed_parts = fixed_parts, n_fixed
        self.components = [[unit.name for u, unit in enumerate(units) if roots.index(root(u)) == c]
                           for c in range(len(roots))]

    @staticmethod
    def fits(units: Sequence[Any], sampler: Any) -> bool:
        """Whether a run of ``units`` (and recording with ``sampler``) can use the C loop."""
        return (sampler.row.dtype == np.float64 and all(isinstance(u, Unit) and _fits(u) for u in units)
                and all(bus.dtype in (np.float64, np.int32) for bus, _, _ in sampler._parts))

    def _ops(self, unit: Unit, action: str, m: int) -> List[Tuple[_Op, str]]:
        handle = unit.fmu.component
        booleans = unit.fmi3  # FMI 3.0 Booleans are one byte: converted in C
        if action == PULL:
            return [(self._value_op(unit, inputs, SET_BOOL3 if booleans and inputs.kind == "Boolean" else
                                    _SET[inputs.kind], _function(unit, "Set", inputs.kind), m,
                                    inputs.values, inputs.bus, inputs.index, inputs.factor, inputs.offset),
                     _function(unit, "Set", inputs.kind)) for inputs in unit.inputs]
        if action == FETCH:
            return [(self._value_op(unit, outputs, GET_BOOL3 if booleans and outputs.kind == "Boolean" else
                                    _GET[outputs.kind], _function(unit, "Get", outputs.kind), m, None,
                                    None, None, None, None,
                                    values_address=ctypes.cast(outputs.pointer, c_void_p).value,
                                    bus_address=_slice_address(outputs)),
                     _function(unit, "Get", outputs.kind)) for outputs in unit.outputs]
        if unit.interface == "CS":
            name = "fmi3DoStep" if unit.fmi3 else "fmi2DoStep"
            step = (_Op(kind=DO_STEP, multiple=m, function=function_address(unit.fmu, name), component=handle,
                        no_prior_state=unit.no_prior_state, fmi3=unit.fmi3), name)
            return [step] if getattr(unit, "clocks", None) is None else [self._clock_op(unit, m), step]
        solver = unit.solver
        erk, erk_plan, erk_current = solver.kernel
        box = np.array([solver.t])
        self._keep.append(box)
        self._me.append((unit, len(self.op_action), box))
        fmu = unit.fmu
        indicators = _Indicators(unit.nz, unit.nx)
        self._indicators[unit.name] = indicators
        return [(_Op(kind=ME_STEP, multiple=m, component=handle, no_prior_state=unit.no_prior_state,
                     erk=erk, erk_plan=erk_plan, erk_current=erk_current, x=_pointer(solver.x), nx=unit.nx, t=_pointer(box),
                     max_step=solver.max_step, set_time=function_address(fmu, "fmi2SetTime"),
                     set_states=function_address(fmu, "fmi2SetContinuousStates"),
                     completed=function_address(fmu, "fmi2CompletedIntegratorStep") if unit.needs_completed else None,
                     nz=unit.nz, get_indicators=function_address(fmu, "fmi2GetEventIndicators"), z=_pointer(indicators.z),
                     z_last=_pointer(indicators.z_last), z_valid=_pointer(indicators.valid),
                     x0=_pointer(indicators.x0), fmi3=unit.fmi3),
                 "")]

    def _clock_op(self, unit: Unit, m: int) -> Tuple[_Op, str]:
        """The CLOCK_TICK before a Co-Simulation unit's fmi3DoStep: its input Clocks' ticks due at
        the step's start, on the unit's own schedule arrays (:class:`.clocks.UnitClocks`)."""
        clocks, fmu = unit.clocks, unit.fmu
        vrs = np.array(clocks.vrs, dtype=np.uint32)
        scratch = (np.zeros(len(vrs), dtype=np.uint32), np.ones(len(vrs), dtype=np.bool_))
        self._keep += [clocks, vrs, scratch]
        op = _Op(kind=CLOCK_TICK, multiple=m, function=function_address(fmu, "fmi3SetClock"),
                 component=fmu.component, vrs=_pointer(vrs), n=len(vrs), fmi3=1,
                 clock_first=_pointer(clocks.first), clock_count=_pointer(clocks.count),
                 clock_interval=_pointer(clocks.interval), clock_activated=_pointer(clocks.activated),
                 due_vrs=_pointer(scratch[0]), on=_pointer(scratch[1]),
                 enter_event_mode=function_address(fmu, "fmi3EnterEventMode"),
                 update_discrete_states=function_address(fmu, "fmi3UpdateDiscreteStates"),
                 enter_step_mode=function_address(fmu, "fmi3EnterStepMode"))
        return op, ""

    def _value_op(self, unit: Unit, holder: Any, kind: int, function: str, m: int, values: Optional[np.ndarray],
                  bus: Optional[np.ndarray], index: Optional[np.ndarray], factor: Optional[np.ndarray],
                  offset: Optional[np.ndarray], values_address: Optional[int] = None,
                  bus_address: Optional[int] = None) -> _Op:
        self._keep.append(holder)
        # the op of a holder used again (a study's next case on the same wiring) is made once:
        # every field comes from the holder's own arrays and its unit's instance
        key = (kind, function, m, unit.fmu.component, values_address, bus_address)
        made = holder.__dict__.setdefault("_c_ops", {})
        op = made.get(key)
        if op is None:
            op = made[key] = self._new_value_op(unit, holder, kind, function, m, values, bus, index, factor, offset,
                                                values_address, bus_address)
        return op

    @staticmethod
    def _new_value_op(unit: Unit, holder: Any, kind: int, function: str, m: int, values: Optional[np.ndarray],
                      bus: Optional[np.ndarray], index: Optional[np.ndarray], factor: Optional[np.ndarray],
                      offset: Optional[np.ndarray], values_address: Optional[int],
                      bus_address: Optional[int]) -> _Op:
        positions = getattr(holder, "positions", None)
        return _Op(kind=kind, multiple=m, function=function_address(unit.fmu, function), component=unit.fmu.component,
                   vrs=ctypes.cast(holder.vrs, c_void_p).value, n=holder.n,
                   values=values_address if values is None else _pointer(values),
                   bus=bus_address if bus is None else _pointer(bus),
                   index=_pointer(index), factor=_pointer(factor), offset=_pointer(offset), fmi3=unit.fmi3,
                   positions=_pointer(positions), n_index=holder.n if index is None else len(index),
                   n_values=holder.tail[0] if holder.tail else holder.n)

    def ready(self) -> bool:
        """Whether the next steps can run in C: no time event pending in a Model Exchange unit
        and its solver still the one planned (an event may have replaced it)."""
        for unit, index, box in self._me:
            if unit.next_event_time is not None or not isinstance(unit.solver, ExplicitRungeKutta):
                return False
            op = self._ops_array[index]
            if op.x != unit.solver.x.ctypes.data:
                erk, erk_plan, erk_current = unit.solver.kernel
                op.erk, op.erk_plan, op.erk_current = erk, erk_plan, erk_current
                op.x, op.max_step = unit.solver.x.ctypes.data, unit.solver.max_step
                self._keep.append(unit.solver)
        return True

    def release_gil(self) -> None:
        """Run the steps with the GIL released (the process's other Python threads run meanwhile;
        an FMU that runs Python takes the GIL there)."""
        self._run = _steps_function(release_gil=True)
        self.plan.gil_released = 1

    def pace(self, pacer: Any, slots: Sequence[Optional[int]], readers: Optional[Any] = None) -> None:
        """Wait for every point's wall-clock time in C, as ``pacer`` (a started
        :class:`~deltafmi.master.live.pacing.Pacer`) would, writing its lateness record and the
        measurements to the Real bus addresses ``slots`` (lateness, busy, behind; None: not on
        the bus); ``readers``: the live sources' C readers (:class:`~deltafmi.master.live.native_udp.
        NativeReaders`), called at every point once it is released, before its row (a run
        stopped with LIVE: they need Python at the point it reached, whose row is not recorded)."""
        self._paced = pacer
        self._pace = _Pace(t0=pacer._t0, wall0=pacer._wall0, speed=pacer.speed, spin=pacer.spin, period=pacer.period,
                           released=pacer.released, lateness=pacer._lateness.ctypes.data,
                           count=self._count.ctypes.data, capacity=len(pacer._lateness),
                           late=slots[0], busy=slots[1], behind=slots[2], stop_behind=int(pacer.behind_is_error),
                           lead=pacer.lead, sample=None if readers is None else readers.function,
                           sample_context=None if readers is None else readers.context)
        self._keep.append(readers)
        self.plan.pace = ctypes.pointer(self._pace)
        self.rows.fill(0.0)  # its pages faulted in now, not at the first paced points that write them
        self._run = _steps_function(release_gil=True)
        self.plan.gil_released = 1

    def _before_paced(self) -> None:
        pacer = self._paced
        self._count[0] = self._count_before = pacer._count
        self._pace.t0, self._pace.wall0, self._pace.released = pacer._t0, pacer._wall0, pacer.released

    def _after_paced(self, k: int) -> None:
        """The pacer's record of the points a C run from step ``k`` released so far (the end
        points of steps k, k + 1, ...)."""
        pacer, plan = self._paced, self.plan
        first, pacer._count = pacer._count, int(self._count[0])
        pacer.released, pacer._wall0 = self._pace.released, self._pace.wall0  # C anchors the clock at its first point
        lateness = pacer._lateness[first:pacer._count]
        if len(lateness):
            pacer.late, pacer.busy = float(lateness[-1]), self._pace.last_busy
        pacer.cpu, pacer.wall, pacer.polled = self._pace.cpu, self._pace.wall, self._pace.polled
        point = k + 1 + first - self._count_before
        if len(lateness) == 1:  # a run handing back at every point (live sources): no arrays made
            late = pacer.late
            if late > pacer.period or (pacer._behind and pacer._behind[-1][1] is None):
                pacer._episode(plan.start + point * plan.h if point < plan.n_steps else plan.stop, late)
            return
        points = point + np.arange(len(lateness))
        pacer.note_released(np.where(points < plan.n_steps, plan.start + points * plan.h, plan.stop), lateness)

    def run_streamed(self, k: int, k_end: int, take: Callable[[np.ndarray], None], stopped: Callable[[], bool],
                     poll: float = 0.05) -> Tuple[int, int, int]:
        """A paced :meth:`run` on a thread of its own while this one takes its rows every ``poll``
        seconds of wall time, or four times while the loop fills the rows block (``take(rows)``, a
        copy), notes its points (the pacer's warnings) and looks at ``stopped()`` (True: the run
        stops after the point being released), so that no hand-back to Python comes between two
        paced points. Returns as :meth:`run` does, every row taken (0 rows)."""
        poll = min(poll, max(1e-3, len(self.rows) * self._paced.period / 4))
        pace = self._pace
        self.enter()
        self._before_paced()
        pace.stream, pace.stop_request, pace.published, pace.taken = 1, 0, 0, 0
        ring, taken = len(self.rows), 0
        why: List[int] = []
        # its own flag, not Thread.join/is_alive: a join interrupted by a stop signal leaves the
        # thread marked as stopped while it still runs (CPython's _wait_for_tstate_lock)
        finished = threading.Event()

        def steps() -> None:
            try:
                why.append(self._run(ctypes.byref(self.plan), k, k_end, self.rows.ctypes.data, ring,
                                     ctypes.byref(self._k_done), ctypes.byref(self._n_rows)))
            finally:
                finished.set()

        def stop_and_wait() -> None:  # the loop stops after the point it releases: within a paced step
            pace.stop_request = 1
            while True:
                try:
                    if finished.wait(0.05):
                        return
                except KeyboardInterrupt:  # one more stop signal: the loop is stopping already
                    pass

        def take_published() -> int:
            published = pace.published  # the rows up to it are written (C stores it after them)
            if published > taken:
                rows = self.rows[np.arange(taken, published) % ring]  # a copy: C writes the ring on
                pace.taken = published
                take(rows)
            return published

        threading.Thread(target=steps, name="deltafmi-paced-steps", daemon=True).start()
        try:
            while True:
                running = not finished.is_set()
                taken = take_published()
                self._after_paced(k)
                if not running:
                    break
                if stopped():
                    pace.stop_request = 1
                finished.wait(poll)
        except KeyboardInterrupt:  # a second stop signal: the rows so far kept
            stop_and_wait()
            take_published()
            self._after_paced(k)
            raise
        except BaseException:
            stop_and_wait()
            raise
        finally:
            pace.stream = 0
            self.leave()
        self._after_paced(k)
        return why[0], self._k_done.value, 0

    def steps_done(self) -> int:
        """The first step the last run did not complete (after :meth:`run_streamed` was
        interrupted: where its thread stopped)."""
        return self._k_done.value

    def hand_rows_to(self, sink: Optional[Tuple[int, int]], every: int = 256, finite: bool = True) -> None:
        """From the next run on, hand every ``every`` rows to ``sink`` as they are recorded, while
        the run goes on (None: none; the caller takes every row after the run): (the address of
        a ``long put(void *sink, const double *rows, long n)``, the sink), as
        :meth:`.BackgroundRows.c_sink` gives, and the last rows of a run that returns RAN or
        ROWS_FULL too; ``finite``: only while all their values are finite (the rest then comes
        back to the caller, who looks at them). Unpaced runs only."""
        plan = self.plan
        plan.sink_put, plan.sink = sink if sink is not None else (None, None)
        plan.sink_every, plan.sink_finite = every, int(finite)

    def return_by(self, deadline: float) -> None:
        """Unpaced runs from now on return (RAN) after the first step that ends past ``deadline``
        (``time.monotonic()`` seconds; 0: none), looked at every few steps."""
        self.plan.deadline = deadline

    def handed(self) -> Tuple[int, int]:
        """The rows of the last run handed to the sink (its first rows), and the sink's count of
        blocks queued after them."""
        return self.plan.sink_rows, self.plan.sink_queued

    def keep_step_start(self) -> None:
        """From now on gather the recorded row (time first) at the start of every step into
        :attr:`step_start`: after a stop inside a step, the values every unit had when it began."""
        self.step_start = np.zeros(len(self.rows[0]))
        self.plan.step_start = self.step_start.ctypes.data

    def timed(self) -> None:
        """From now on add each operation's wall seconds to :attr:`op_seconds` (for benchmarks)."""
        self.op_seconds = np.zeros(max(1, len(self.op_action)))
        self.plan.op_seconds = self.op_seconds.ctypes.data

    def unit_seconds(self) -> dict:
        """Wall seconds spent in each unit's operations since :meth:`timed`."""
        spent: dict = {}
        for i, a in enumerate(self.op_action):
            name = self.actions[a][0].name
            spent[name] = spent.get(name, 0.0) + float(self.op_seconds[i])
        return spent

    def run(self, k: int, k_end: int) -> Tuple[int, int, int]:
        """Steps ``k`` ... ``k_end - 1`` in C: (why it stopped, first step not completed, rows in
        :attr:`rows`). The Model Exchange units' solvers are up to date on return."""
        self.enter()
        if self._paced is not None:
            self._before_paced()
        why = self._run(ctypes.byref(self.plan), k, k_end, self.rows.ctypes.data, len(self.rows),
                        ctypes.byref(self._k_done), ctypes.byref(self._n_rows))
        self.leave()
        done = self._k_done.value
        if self._paced is not None:
            self._after_paced(k)
        return why, done, self._n_rows.value

    def enter(self) -> None:
        """Before C takes steps: the Model Exchange units' solvers (time, last event indicators)
        handed to the plan."""
        for unit, _, box in self._me:
            box[0] = unit.solver.t
            self._indicators[unit.name].take(unit.solver)

    def leave(self) -> None:
        """After C took steps: the Model Exchange units' solvers brought up to date from the plan."""
        for unit, _, box in self._me:
            unit.solver.t = float(box[0])
            self._indicators[unit.name].give(unit.solver)

    def entry(self) -> int:
        """The address of the C loop's entry (``deltafmi_fixed_steps``) this plan runs through."""
        return ctypes.cast(self._run, c_void_p).value

    def close(self) -> None:
        """Stop the threads that stepped groups of units (see :mod:`.parallel`); call once the run is over."""
        if self.plan.pool:
            _end(ctypes.byref(self.plan))

    def locate(self, unit: Any) -> None:
        """After a STATE_EVENT in ``unit``: bisect the Runge-Kutta step that crossed, as
        :meth:`.ExplicitRungeKutta.advance` does (the solver then stands just past the crossing)."""
        unit.solver.locate(self.plan.rk_time, self._indicators[unit.name].x0.copy(), self.plan.rk_step)

    def stopped_op(self) -> _Op:
        """The operation the last run stopped at (its outputs: an FMI 3.0 step's flags)."""
        return self._ops_array[self.plan.op]

    def stopped_at(self) -> Tuple[Unit, str, int, str]:
        """Where the last run stopped: the action (unit, PULL | STEP | FETCH, its index in
        ``actions``) and the fmi2 function that failed, if one did."""
        plan = self.plan
        a = self.op_action[plan.op]
        unit, action, _ = self.actions[a]
        calls = CLOCK_CALLS if self._ops_array[plan.op].kind == CLOCK_TICK else ME_CALLS
        return unit, action, a, self.op_function[plan.op] or calls[plan.call]
