"""Runtime FMU instances as the master steps them: a common :class:`Unit` base and the
Co-Simulation :class:`CoSimulationUnit` (fmpy ``FMU2Slave``).

Every unit exchanges values with the master through *buses* (one numpy vector per FMI type that
holds every fetched variable of every unit). Wiring is precomputed once, so a step costs one
``fmi2Get<Type>`` per unit and type into its bus slice, and one gather plus one ``fmi2Set<Type>`` for
its inputs: no dicts, no per-step allocation.
"""
from __future__ import annotations

import ctypes
from collections import deque
from ctypes import POINTER
from typing import Any, Callable, Dict, List, Sequence, Tuple

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Boolean, fmi2Integer, fmi2Real,
                       fmi2ValueReference)

from .resolve import Component, Port

#: FMI type -> (ctypes element type, numpy dtype)
TYPES: Dict[str, Tuple[Any, Any]] = {
    "Real": (fmi2Real, np.float64),
    "Integer": (fmi2Integer, np.int32),
    "Boolean": (fmi2Boolean, np.int32),
}


class FmuFailure(RuntimeError):
    """An FMI call failed; the message names the unit, the call and the FMU's last log message."""


def bare_function(fmu: Any, name: str) -> Callable[..., None]:
    """fmpy's ctypes binding of the fmi2 function ``name`` without fmpy's Python wrapper around
    it (call logging, which the master never enables, costs about 1 us a call); raises
    ``FMICallException`` on an error status as fmpy does."""
    function = getattr(fmu.dll, name)  # argtypes and restype as fmpy declared them

    def call(*args: Any) -> None:
        status = function(*args)
        if status > 1:
            raise FMICallException(function=name, status=status)
    return call


class _Inputs:
    """One unit's inputs of one type: ``values = factor * bus[index] + offset``, set in one call."""

    def __init__(self, setter: Callable, handle: Any, vrs: Sequence[int], bus: np.ndarray,
                 index: Sequence[int], factor: Sequence[float], offset: Sequence[float], ctype: Any) -> None:
        n = len(vrs)
        self.vrs = (fmi2ValueReference * n)(*vrs)
        self.n = n
        self.values = np.zeros(n, dtype=bus.dtype)
        self.pointer = self.values.ctypes.data_as(POINTER(ctype))
        self.bus = bus
        self.index = np.asarray(index, dtype=np.intp)
        factor, offset = np.asarray(factor, float), np.asarray(offset, float)
        transformed = bool(np.any(factor != 1.0) or np.any(offset != 0.0))
        self.factor = factor if transformed else None
        self.offset = offset
        self.setter, self.handle = setter, handle

    def apply(self) -> None:
        """Gather from the bus, transform, and set in the FMU."""
        np.take(self.bus, self.index, out=self.values)
        if self.factor is not None:
            self.values *= self.factor
            self.values += self.offset
        self.setter(self.handle, self.vrs, self.n, self.pointer)


class _Outputs:
    """One unit's fetched variables of one type, read straight into their bus slice."""

    def __init__(self, getter: Callable, handle: Any, vrs: Sequence[int], bus: np.ndarray, start: int,
                 ctype: Any) -> None:
        n = len(vrs)
        self.vrs = (fmi2ValueReference * n)(*vrs)
        self.n = n
        self.pointer = ctypes.cast(bus.ctypes.data + start * bus.itemsize, POINTER(ctype))
        self.getter, self.handle = getter, handle

    def fetch(self) -> None:
        """Read the variables into the bus."""
        self.getter(self.handle, self.vrs, self.n, self.pointer)


class Unit:
    """An instantiated FMU in the master (the base of the CS and ME units)."""

    interface = ""
    fmu_class: type = FMU2Slave

    def __init__(self, component: Component, unzip_dir: str) -> None:
        self.component = component
        self.name = component.name
        self.info = component.info
        md = component.info.md
        self.messages: deque = deque(maxlen=20)
        self._callbacks = _callbacks(self.messages)
        self.fmu = self.fmu_class(guid=md.guid, unzipDirectory=unzip_dir,
                                  modelIdentifier=component.info.model_identifier(self.interface),
                                  instanceName=self.name)
        self.inputs: List[_Inputs] = []
        self.outputs: List[_Outputs] = []
        self.step_multiple = component.spec.step_multiple
        self.instantiated = False

    # --- life cycle ---------------------------------------------------------------------------
    def instantiate(self, start: float, stop: float) -> None:
        """fmi2Instantiate + fmi2SetupExperiment (rtol of the solver options as tolerance)."""
        self.call(self.fmu.instantiate, callbacks=self._callbacks)
        self.instantiated = True
        self.call(self.fmu.setupExperiment, tolerance=self.component.spec.solver.get("rtol"),
                  startTime=start, stopTime=stop)

    def apply_start_values(self) -> None:
        """Set the scenario's parameters and start values (before initialization mode)."""
        for port, value in self.component.start_values:
            self.set_value(port, value)

    def enter_initialization(self) -> None:
        """fmi2EnterInitializationMode."""
        self.call(self.fmu.enterInitializationMode)

    def exit_initialization(self, time: float) -> None:
        """fmi2ExitInitializationMode (the ME unit continues with its event iteration)."""
        self.call(self.fmu.exitInitializationMode)

    def close(self) -> None:
        """fmi2Terminate and free the instance; never raises."""
        if self.instantiated:
            try:
                self.fmu.terminate()
            except Exception:  # noqa: BLE001 - closing after a failure must not hide it
                pass
            try:
                self.fmu.freeInstance()
            except Exception:  # noqa: BLE001
                pass
            self.instantiated = False

    # --- values -------------------------------------------------------------------------------
    def get_value(self, port: Port) -> Any:
        """One variable (slow path: initialization and tests)."""
        getter = {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger,
                  "Boolean": self.fmu.getBoolean, "String": self.fmu.getString}[port.type]
        value = self.call(getter, [port.vr])[0]
        return bool(value) if port.type == "Boolean" else value

    def set_value(self, port: Port, value: Any) -> None:
        """Set one variable (slow path: start values and initialization)."""
        setter = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger,
                  "Boolean": self.fmu.setBoolean, "String": self.fmu.setString}[port.type]
        self.call(setter, [port.vr], [value])

    def wire_inputs(self, kind: str, vrs: Sequence[int], bus: np.ndarray, index: Sequence[int],
                    factor: Sequence[float], offset: Sequence[float]) -> None:
        """Take inputs of FMI type ``kind`` from ``bus[index]`` before every step."""
        ctype = TYPES[kind][0]
        setter = bare_function(self.fmu, f"fmi2Set{kind}")
        self.inputs.append(_Inputs(setter, self.fmu.component, vrs, bus, index, factor, offset, ctype))

    def wire_outputs(self, kind: str, vrs: Sequence[int], bus: np.ndarray, start: int) -> None:
        """Read variables of type ``kind`` into ``bus[start:start + len(vrs)]`` after every step."""
        getter = bare_function(self.fmu, f"fmi2Get{kind}")
        self.outputs.append(_Outputs(getter, self.fmu.component, vrs, bus, start, TYPES[kind][0]))

    def pull(self) -> None:
        """Set this unit's inputs from the buses."""
        try:
            for inputs in self.inputs:
                inputs.apply()
        except FMICallException as exc:
            raise self.failure(exc) from None

    def fetch(self) -> None:
        """Read this unit's outputs (and recorded variables) into the buses."""
        try:
            for outputs in self.outputs:
                outputs.fetch()
        except FMICallException as exc:
            raise self.failure(exc) from None

    # --- stepping and state -------------------------------------------------------------------
    def do_step(self, time: float, step: float) -> None:
        """Advance from ``time`` by ``step``."""
        raise NotImplementedError

    @property
    def can_save_state(self) -> bool:
        """Whether fmi2GetFMUstate/fmi2SetFMUstate work for this unit."""
        return self.info.can_get_set_state(self.interface)

    def save_state(self) -> Any:
        """A snapshot to :meth:`restore_state` (release it with :meth:`free_state`)."""
        return self.call(self.fmu.getFMUstate)

    def restore_state(self, state: Any) -> None:
        """Go back to a snapshot."""
        self.call(self.fmu.setFMUstate, state)

    def free_state(self, state: Any) -> None:
        """Release a snapshot."""
        self.call(self.fmu.freeFMUstate, state)

    def call(self, function: Callable, *args: Any, **kwargs: Any) -> Any:
        """Call an fmpy function, turning an FMI error status into :class:`FmuFailure`."""
        try:
            return function(*args, **kwargs)
        except FMICallException as exc:
            raise self.failure(exc) from None

    def failure(self, exc: BaseException) -> FmuFailure:
        """A :class:`FmuFailure` for ``exc`` that quotes the FMU's last log message."""
        last = ""
        for status, message in reversed(self.messages):
            if status >= 2:
                last = message.strip().splitlines()[-1] if message.strip() else ""
                break
        return FmuFailure(f"{self.name}: {str(exc).rstrip('.')}" + (f": {last}" if last else ""))


class CoSimulationUnit(Unit):
    """A Co-Simulation FMU stepped with fmi2DoStep."""

    interface = "CS"
    fmu_class = FMU2Slave

    def __init__(self, component: Component, unzip_dir: str) -> None:
        super().__init__(component, unzip_dir)
        self._do_step = bare_function(self.fmu, "fmi2DoStep")
        self._handle = None
        self.no_prior_state = 1

    def instantiate(self, start: float, stop: float) -> None:
        super().instantiate(start, stop)
        self._handle = self.fmu.component

    def do_step(self, time: float, step: float) -> None:
        try:
            self._do_step(self._handle, time, step, self.no_prior_state)
        except FMICallException as exc:
            raise self.failure(exc) from None


def _callbacks(messages: deque) -> fmi2CallbackFunctions:
    """fmi2CallbackFunctions whose logger keeps the last messages (quoted when a call fails).

    No fmpy ``addLoggerProxy``: it keeps ONE process-wide pointer to the last logger it wrapped,
    so per-unit loggers would dangle once freed (a crash at the next message) and every FMU's
    messages would go to the last unit. The message text is used as is (deltafmi FMUs pass it
    fully formatted).
    """
    from fmpy import calloc, free

    def logger(env: Any, instance: bytes, status: int, category: bytes, message: bytes) -> None:
        text = message.decode("utf-8", "replace") if message else ""
        messages.append((status, text))

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    return callbacks


def model_exchange_class() -> type:
    """The ME unit class (imported late: it pulls in SUNDIALS)."""
    from .me_integrator import ModelExchangeUnit
    return ModelExchangeUnit


def unit_for(component: Component, unzip_dir: str) -> Unit:
    """The right unit class for the component's interface."""
    cls = CoSimulationUnit if component.interface == "CS" else model_exchange_class()
    return cls(component, unzip_dir)

