"""FMI 3.0 FMUs as master units (fmpy ``FMU3Slave`` and ``FMU3Model``), next to FMI 2.0 ones.

What differs from FMI 2.0 lives here; the rest is shared with :mod:`.unit_base`, :mod:`.units`
and :mod:`.me_integrator` (the Model Exchange unit is the FMI 2.0 one: the FMI 3.0 calls it makes
have the same C signatures, see :func:`.unit_base.api_name`).

* Values: one ``fmi3Get/Set<Type>`` per unit and FMI 3.0 type with every variable's value
  reference and ``nValues`` = all their elements. An array is set whole, as FMI 3.0 requires:
  the elements no connection drives keep the FMU's values (read after initialization).
  Enumerations travel as ``Int64``, as FMI 3.0 defines them.
* Life cycle: no ``fmi2SetupExperiment``: tolerance, start and stop go to
  ``fmi3EnterInitializationMode``.
* Co-Simulation events (:class:`CoSimulationUnit3`): an FMU that has ``hasEventMode`` is
  instantiated with ``eventModeUsed`` and ``earlyReturnAllowed``; after initialization and
  whenever ``fmi3DoStep`` says ``eventHandlingNeeded`` it goes through Event Mode
  (``fmi3UpdateDiscreteStates`` until no update is needed) and back to Step Mode, and a step that
  returned early (``earlyReturn``, at ``lastSuccessfulTime``) is continued from there to the
  master's communication point, so the master's grid stays what it was; the master records a
  row just before and after each such event, as for Model Exchange. ``terminateSimulation``
  raises :class:`.Terminated` at ``lastSuccessfulTime``.
* Clocks (:mod:`.clocks`): the periodic input Clocks of a unit are activated at their ticks
  (``fmi3SetClock`` in Event Mode, then ``fmi3UpdateDiscreteStates``). Model Exchange: each tick
  is a time event of the unit (the tick at the start in the initial Event Mode). Co-Simulation
  (instantiated with ``eventModeUsed``, which FMI 3.0 requires of an FMU with clocks): the ticks
  in ``[t, t + h)`` are taken inside the step from ``t`` (a tick at ``t`` with the inputs given
  at ``t``, as FMI 2.0 Co-Simulation FMUs sample in fmi2DoStep; one inside the step after an
  fmi3DoStep to it, with a row before and after it). Clocks ticking at one instant are
  activated together, also at an event the FMU itself reports there. Output Clocks are read
  (fmi3GetClock) in every Event Mode before the update. Co-Simulation ticks at communication
  points are taken by the C loop too (:mod:`.native_loop`).
"""
from __future__ import annotations

import ctypes
from collections import defaultdict
from functools import cached_property
from ctypes import byref, c_bool, c_double
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model, FMU3Slave, fmi3Discard

from ..scenario.system import Port
from .clocks import UnitClocks, unit_clocks
from .me_integrator import ModelExchangeUnit
from .unit_base import (FmuFailure, Terminated, Unit, _Inputs, _Outputs, _StringInputs, _StringOutputs, bare_function,
                        decoded, instant_margin)

__all__ = ["CoSimulationUnit3", "ModelExchangeUnit3", "unsettled"]

#: FMI 3.0 type -> ctypes type of its values; Enumeration values are Int64
CTYPES: Dict[str, Any] = {
    "Float64": ctypes.c_double, "Float32": ctypes.c_float, "Int8": ctypes.c_int8, "UInt8": ctypes.c_uint8,
    "Int16": ctypes.c_int16, "UInt16": ctypes.c_uint16, "Int32": ctypes.c_int32, "UInt32": ctypes.c_uint32,
    "Int64": ctypes.c_int64, "UInt64": ctypes.c_uint64, "Boolean": ctypes.c_bool, "String": ctypes.c_char_p,
}
_MAX_EVENT_ITERATIONS = 1000  # native/fixed_step.c MAX_EVENT_ITERATIONS


def unsettled(unit: str, time: float) -> str:
    """The failure of an event iteration that does not settle."""
    return f"{unit}: event iteration at t = {time:.9g} s did not converge in {_MAX_EVENT_ITERATIONS} rounds"


def _api_type(variable_type: str) -> str:
    """The FMI 3.0 function family of a variable type (``fmi3Get<this>``)."""
    return "Int64" if variable_type == "Enumeration" else variable_type


class Fmi3Values(Unit):
    """What an FMI 3.0 unit does differently from an FMI 2.0 :class:`.Unit`."""

    #: the unit's Clocks (None: it has none), see :mod:`.clocks`
    clocks: Optional[UnitClocks] = None

    # --- life cycle ---------------------------------------------------------------------------
    def _set_up_experiment(self, tolerance: Optional[float], start: float, stop: float) -> None:
        """FMI 3.0 has no fmi2SetupExperiment: the experiment goes to :meth:`enter_initialization`."""
        self._experiment = dict(tolerance=tolerance, startTime=start, stopTime=stop)

    def _log_message(self, environment: Any, status: int, category: bytes, message: bytes) -> None:
        """fmi3LogMessageCallback: keep the message (quoted when a call fails), pass it on."""
        try:
            entry = (int(status), category.decode("utf-8", "replace") if category else "",
                     message.decode("utf-8", "replace") if message else "")
            self.messages.append(entry)
            if self.on_message is not None:
                self.on_message(self.name, *entry)
        except Exception:  # noqa: BLE001  (nothing may raise into the FMU's C code)
            pass

    def enter_initialization(self) -> None:
        """fmi3EnterInitializationMode with tolerance, start and stop time."""
        self.call(self.fmu.enterInitializationMode, **self._experiment)

    def exit_initialization(self, time: float) -> None:
        """fmi3ExitInitializationMode; then the inputs' current values, so that the elements of an
        array no connection drives keep them. The clocks' intervals and shifts are asked for
        before (in Initialization Mode, as FMI 3.0 says)."""
        if self.clocks is not None:
            self.clocks.schedule(self, time)
        self.call(self.fmu.exitInitializationMode)
        self.initialized = True
        for inputs in self.inputs:
            self.call(inputs.seed)

    # --- FMU state: the clocks' ticks go back with it ------------------------------------------
    def save_state(self) -> Any:
        return super().save_state(), self.clocks.state() if self.clocks is not None else None

    def restore_state(self, state: Any) -> None:
        super().restore_state(state[0])
        if self.clocks is not None:
            self.clocks.restore(state[1])

    def free_state(self, state: Any) -> None:
        super().free_state(state[0])

    # --- values -------------------------------------------------------------------------------
    @cached_property
    def _by_vr(self) -> Dict[int, Any]:
        """The FMU's variables (arrays whole) by value reference."""
        return {v.valueReference: v for v in self.info.md.modelVariables}

    def _variable(self, vr: int) -> Any:
        return self._by_vr[vr]

    def _size(self, vr: int) -> int:
        return self.info.sizes[vr]

    def get_value(self, port: Port) -> Any:
        """One element (slow path: initialization and tests); a String comes back as ``str``."""
        kind = _api_type(self._variable(port.vr).type)
        value = self.call(getattr(self.fmu, f"get{kind}"), [port.vr], self._size(port.vr))[port.index]
        if kind == "String":
            return value if isinstance(value, str) else decoded([value])[0]
        return bool(value) if kind == "Boolean" else value

    def set_value(self, port: Port, value: Any) -> None:
        """Set one element (slow path): an array is read, changed and set whole."""
        kind = _api_type(self._variable(port.vr).type)
        values = [value]
        if self._size(port.vr) > 1:
            values = list(self.call(getattr(self.fmu, f"get{kind}"), [port.vr], self._size(port.vr)))
            values[port.index] = value
        self.call(getattr(self.fmu, f"set{kind}"), [port.vr], values)

    def apply_start_values(self) -> None:
        """Set the scenario's parameters and start values before initialization (where FMI 3.0
        allows no get): each variable once, an array's elements not given keep their start values."""
        given: Dict[int, Dict[int, Any]] = defaultdict(dict)
        for port, value in self.component.start_values:
            given[port.vr][port.index] = value
        for vr, elements in given.items():
            variable = self._variable(vr)
            kind = _api_type(variable.type)
            values = _start_values(self.info, variable) if self._size(vr) > 1 else [None]
            for index, value in elements.items():
                values[index] = value
            self.call(getattr(self.fmu, f"set{kind}"), [vr], values)

    def _by_type(self, vrs: Sequence[int]) -> Dict[str, List[int]]:
        """Positions in ``vrs`` grouped by FMI 3.0 function family, in order."""
        groups: Dict[str, List[int]] = defaultdict(list)
        for i, vr in enumerate(vrs):
            groups[_api_type(self._variable(vr).type)].append(i)
        return groups

    def wire_inputs(self, kind: str, vrs: Sequence[int], bus: np.ndarray, index: Sequence[int],
                    factor: Sequence[float], offset: Sequence[float], elements: Sequence[int] = ()) -> None:
        """One set call per FMI 3.0 type: whole variables, the connected elements from the bus."""
        elements = list(elements) or [0] * len(vrs)
        handle = self.fmu.component
        for api, chosen in self._by_type(vrs).items():
            variables = list(dict.fromkeys(vrs[i] for i in chosen))
            sizes = [self._size(vr) for vr in variables]
            first = dict(zip(variables, np.cumsum([0] + sizes[:-1]).tolist()))
            positions = [first[vrs[i]] + elements[i] for i in chosen]
            setter, getter = bare_function(self.fmu, f"fmi3Set{api}"), bare_function(self.fmu, f"fmi3Get{api}")
            picked = [index[i] for i in chosen]
            if api == "String":
                inputs = _StringInputs(setter, getter, handle, variables, bus, picked, sizes, positions)
            else:
                inputs = _Inputs(setter, getter, handle, variables, bus, picked, [factor[i] for i in chosen],
                                 [offset[i] for i in chosen], CTYPES[api], sizes, positions)
            inputs.kind = kind
            self.inputs.append(inputs)

    def output_slots(self, kind: str, vrs: Sequence[int]) -> List[Tuple[int, int]]:
        """Every element of each variable, grouped by FMI 3.0 type (one get call each)."""
        return [(vrs[i], element) for chosen in self._by_type(vrs).values() for i in chosen
                for element in range(self._size(vrs[i]))]

    def wire_outputs(self, kind: str, vrs: Sequence[int], bus: np.ndarray, start: int) -> None:
        """One get call per FMI 3.0 type into consecutive slots from ``start`` (see :meth:`output_slots`)."""
        handle = self.fmu.component
        for api, chosen in self._by_type(vrs).items():
            variables = [vrs[i] for i in chosen]
            sizes = [self._size(vr) for vr in variables]
            getter = bare_function(self.fmu, f"fmi3Get{api}")
            if api == "String":
                outputs = _StringOutputs(getter, handle, variables, bus, start, sizes)
            else:
                outputs = _Outputs(getter, handle, variables, bus, start, CTYPES[api], sizes)
            outputs.kind = kind
            self.outputs.append(outputs)
            start += sum(sizes)


def _start_values(info: Any, variable: Any) -> List[Any]:
    """An array variable's start values from its modelDescription, as Python values."""
    convert = {"Boolean": lambda text: text in ("true", "1"), "String": str}.get(
        variable.type, float if variable.type.startswith("Float") else int)
    names = info.arrays[variable.name]
    return [convert(info.variables[name].start) if info.variables[name].start is not None
            else convert("0") if variable.type != "String" else "" for name in names]


class CoSimulationUnit3(Fmi3Values):
    """An FMI 3.0 Co-Simulation FMU stepped with fmi3DoStep (event mode and early return: see the module)."""

    interface = "CS"
    fmu_class = FMU3Slave

    def __init__(self, component: Any, unzip_dir: str, fmu: Any = None) -> None:
        super().__init__(component, unzip_dir, fmu)
        self.clocks = unit_clocks(self.name, unzip_dir, self.interface)
        self.event_mode = bool(component.info.md.coSimulation.hasEventMode)
        self.no_prior_state = True
        self._flags = (c_bool(), c_bool(), c_bool(), c_double())  # eventHandlingNeeded, terminate, early, last
        self._do_step = self.fmu.dll.fmi3DoStep  # raw: its outputs matter with fmi3Discard too
        #: called as ``on_event(unit, time, after)`` just before and after every event it handles (recording)
        self.on_event: Callable[["CoSimulationUnit3", float, bool], None] = lambda unit, time, after: None

    instantiate_call = "fmi3InstantiateCoSimulation"

    def _instantiate_fmu(self) -> None:
        self.fmu.instantiate(loggingOn=self.logging_on, eventModeUsed=self.event_mode,
                             earlyReturnAllowed=self.event_mode, logMessage=self._log_message)

    def exit_initialization(self, time: float) -> None:
        """With event mode, the FMU is in Event Mode now: its discrete states first, then Step Mode."""
        super().exit_initialization(time)
        if self.event_mode:
            self._event_iteration(time)
            if self.clocks is not None:
                self.clocks.refresh(self, time)
            self.call(self.fmu.enterStepMode)

    def do_step(self, time: float, step: float) -> None:
        """fmi3DoStep to ``time + step``, through every event and early return on the way, and
        every clock tick in ``[time, time + step)`` (see the module)."""
        end = time + step
        clocks = self.clocks
        if clocks is None:
            self._carry_on(time, end)
            return
        now = time
        while clocks.next_tick() < end - instant_margin(end):
            tick = clocks.next_tick()
            inside = tick > now + instant_margin(now)
            if inside:
                self._carry_on(now, tick)
                now = tick
                self.on_event(self, now, False)
            self.call(self.fmu.enterEventMode)
            clocks.activate(self, now)
            self._event_iteration(now)
            clocks.refresh(self, now)
            self.call(self.fmu.enterStepMode)
            if inside:
                self.on_event(self, now, True)
        self._carry_on(now, end)

    def finish_step(self, time: float, step: float, status: int, flags: int, last: float) -> None:
        """The rest of :meth:`do_step` from ``time`` after an fmi3DoStep (made in C, see
        :mod:`.native_loop`) returned ``status``, ``flags`` (eventHandlingNeeded 1,
        terminateSimulation 2, earlyReturn 4) and lastSuccessfulTime ``last``."""
        end = time + step
        self._carry_on(self._returned(time, end, status, bool(flags & 1), bool(flags & 2), bool(flags & 4), last),
                       end)

    def _carry_on(self, now: Optional[float], end: float) -> None:
        event, terminate, early, last = self._flags
        while now is not None:
            status = self._do_step(self.fmu.component, now, end - now, self.no_prior_state, byref(event),
                                   byref(terminate), byref(early), byref(last))
            now = self._returned(now, end, status, event.value, terminate.value, early.value, last.value)

    def _returned(self, now: float, end: float, status: int, event: bool, terminate: bool, early: bool,
                  last: float) -> Optional[float]:
        """What an fmi3DoStep from ``now`` to ``end`` returned means: the time to step on from, or
        None when the step is done; raises :class:`.Terminated` or a failure."""
        reached = last if (early or status == fmi3Discard or terminate) else end
        if terminate:
            raise Terminated(self.name, reached)
        if status >= fmi3Discard:  # fmi3Discard without terminateSimulation: the step could not be done
            raise self.failure(FMICallException(function="fmi3DoStep", status=status))
        if event and self.event_mode:
            self.on_event(self, reached, False)
            self.call(self.fmu.enterEventMode)
            clocks = self.clocks
            if clocks is not None:  # a tick at the FMU's own event: in this Event Mode, not another
                clocks.activate(self, reached)
            self._event_iteration(reached)
            if clocks is not None:
                clocks.refresh(self, reached)
            self.call(self.fmu.enterStepMode)
            self.on_event(self, reached, True)
        if not early or reached >= end - instant_margin(end):
            return None
        if reached <= now:
            raise FmuFailure(f"{self.name}: fmi3DoStep returned early at t = {reached:.9g} s without advancing")
        return reached

    def _event_iteration(self, time: float) -> None:
        if self.clocks is not None:
            self.clocks.read_outputs(self)
        for _ in range(_MAX_EVENT_ITERATIONS):
            needed, terminate, _, _, _, _ = self.call(self.fmu.updateDiscreteStates)
            if terminate:
                raise Terminated(self.name, time)
            if not needed:
                return
        raise FmuFailure(unsettled(self.name, time))


class ModelExchangeUnit3(ModelExchangeUnit, Fmi3Values):
    """An FMI 3.0 Model Exchange FMU integrated as :class:`.ModelExchangeUnit` integrates FMI 2.0."""

    interface = "ME"
    fmu_class = FMU3Model

    def __init__(self, component: Any, unzip_dir: str, fmu: Any = None) -> None:
        super().__init__(component, unzip_dir, fmu)
        self.clocks = unit_clocks(self.name, unzip_dir, self.interface)

    instantiate_call = "fmi3InstantiateModelExchange"

    def _instantiate_fmu(self) -> None:
        self.fmu.instantiate(loggingOn=self.logging_on, logMessage=self._log_message)

    def _event_iteration(self, t: float) -> tuple:
        """The clocks ticking at ``t`` first, then the event iteration; the next tick is a time
        event of the unit."""
        clocks = self.clocks
        if clocks is None:
            return super()._event_iteration(t)
        clocks.activate(self, t)
        clocks.read_outputs(self)
        changed = super()._event_iteration(t)
        clocks.refresh(self, t)
        self.next_event_time = clocks.earliest(self.next_event_time)
        return changed
