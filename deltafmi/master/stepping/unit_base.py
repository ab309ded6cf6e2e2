"""What every runtime unit of the master shares: the :class:`Unit` base, the value buses it
exchanges with the master, and the ways a unit stops (:class:`FmuFailure`, :class:`Terminated`).

Every unit exchanges values with the master through *buses* (one vector per FMI type that
holds every fetched variable of every unit: numpy numbers for Real, Integer and Boolean, a
numpy object array of ``str`` for String; FMI 3.0's 64-bit integers travel on the Int64 and
UInt64 buses). Wiring is precomputed once, so a step costs one ``fmi2Get<Type>`` (FMI 3.0:
``fmi3Get<Type>``) per unit and type into its bus slice, and one gather plus one set call for
its inputs: no dicts, no per-step allocation (String values excepted: they are Python strings).

The Co-Simulation and Model Exchange units (:mod:`.units`, :mod:`.me_integrator`) both build on
this module and neither imports the other.
"""
from __future__ import annotations

import ctypes
from collections import deque
from ctypes import POINTER
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import _FMU3
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Boolean, fmi2Error, fmi2Integer, fmi2Real,
                       fmi2String, fmi2ValueReference)

from deltafmi.errors import DeltaFmiError

from ..scenario.system import ResolvedComponent, Port

__all__ = ["FmuFailure", "TYPES", "Terminated", "Unit", "bare_function", "decoded", "function_address",
           "instant_margin", "instantiation_reason", "logger_callbacks", "new_bus"]

#: bus -> (FMI 2.0 ctypes element type, numpy dtype of the bus); Enumeration values travel as
#: Integer; Int64 and UInt64 carry FMI 3.0 values that do not fit an int32 (UInt32, Int64, UInt64)
TYPES: Dict[str, Tuple[Any, Any]] = {
    "Real": (fmi2Real, np.float64),
    "Integer": (fmi2Integer, np.int32),
    "Int64": (ctypes.c_int64, np.int64),
    "UInt64": (ctypes.c_uint64, np.uint64),
    "Boolean": (fmi2Boolean, np.int32),
    "String": (fmi2String, object),
}


def instant_margin(t: float) -> float:
    """Two times within this of ``t`` are one instant: their difference is round-off (a unit's
    own ``t + h``, an FMU's accumulated event time against the grid's ``start + k h``)."""
    return 1e-12 * max(1.0, abs(t))


def new_bus(kind: str, size: int) -> np.ndarray:
    """A bus of ``size`` slots for FMI type ``kind`` (zeros, or empty strings)."""
    if kind == "String":
        return np.full(size, "", dtype=object)
    return np.zeros(size, dtype=TYPES[kind][1])


def decoded(texts: Sequence[Any]) -> List[str]:
    """FMI 2.0 strings (UTF-8 bytes, or NULL) as ``str``."""
    return [text.decode("utf-8", "replace") if text is not None else "" for text in texts]


class FmuFailure(DeltaFmiError, RuntimeError):
    """An FMI call failed; the message names the unit, the call and the FMU's last log message."""


class Terminated(Exception):
    """A unit ended the simulation at ``time``, as FMI 2.0 lets an FMU do: Model Exchange sets
    ``terminateSimulation`` (fmi2NewDiscreteStates, fmi2CompletedIntegratorStep); Co-Simulation
    returns fmi2Discard from fmi2DoStep with fmi2GetBooleanStatus(fmi2Terminated) true and
    fmi2GetRealStatus(fmi2LastSuccessfulTime) the time it reached; FMI 3.0 says it with the
    terminateSimulation outputs of fmi3UpdateDiscreteStates, fmi3CompletedIntegratorStep and
    fmi3DoStep (with lastSuccessfulTime). The run ends cleanly there."""

    def __init__(self, unit: str, time: float) -> None:
        super().__init__(f"{unit} terminated the simulation at t = {time:.9g} s")
        self.unit = unit
        self.time = time


#: FMI 2.0 functions whose FMI 3.0 counterpart has another name (and the same C signature)
_FMI3_NAMES = {"fmi2GetDerivatives": "fmi3GetContinuousStateDerivatives"}


def api_name(fmu: Any, name: str) -> str:
    """The name of the FMI function ``name`` (given in FMI 2.0 terms, or already an ``fmi3`` name)
    in the FMI version of the loaded fmpy FMU: ``fmi2SetTime`` is ``fmi3SetTime`` in an FMI 3.0
    FMU, ``fmi2GetDerivatives`` is ``fmi3GetContinuousStateDerivatives``."""
    if not isinstance(fmu, _FMU3) or not name.startswith("fmi2"):
        return name
    return _FMI3_NAMES.get(name, "fmi3" + name[4:])


def function_address(fmu: Any, name: str) -> int:
    """The address of the FMI function ``name`` (see :func:`api_name`) of a loaded fmpy FMU (for
    C code that calls it)."""
    return ctypes.cast(getattr(fmu.dll, api_name(fmu, name)), ctypes.c_void_p).value


def bare_function(fmu: Any, name: str) -> Callable[..., None]:
    """fmpy's ctypes binding of the FMI function ``name`` (see :func:`api_name`) without fmpy's
    Python wrapper around it (call logging, which the master never enables, costs about 1 us a
    call); raises ``FMICallException`` on a status above fmi2Warning as fmpy does."""
    name = api_name(fmu, name)
    function = getattr(fmu.dll, name)  # argtypes and restype as fmpy declared them

    def call(*args: Any) -> None:
        status = function(*args)
        if status > 1:
            raise FMICallException(function=name, status=status)
    return call


class _Layout:
    """Where one set call's values come from: FMI 2.0 sets ``n`` scalars, one per bus slot; FMI 3.0
    sets whole variables (an array's every element, ``sizes``), of which the connected elements
    (``positions`` in the values) come from the bus and the others keep the FMU's values."""

    def __init__(self, n: int, sizes: Optional[Sequence[int]], positions: Optional[Sequence[int]]) -> None:
        #: FMI 3.0's extra argument of fmi3Get/Set: the number of values
        self.tail: Tuple[int, ...] = () if sizes is None else (int(sum(sizes)),)
        self.count = n if sizes is None else int(sum(sizes))
        self.positions = None if positions is None else np.asarray(positions, dtype=np.intp)


class _Inputs:
    """One unit's inputs of one numeric type: ``values = factor * bus[index] + offset``, set in one
    call (FMI 3.0: whole variables, see :class:`_Layout`)."""

    def __init__(self, setter: Callable, getter: Callable, handle: Any, vrs: Sequence[int], bus: np.ndarray,
                 index: Sequence[int], factor: Sequence[float], offset: Sequence[float], ctype: Any,
                 sizes: Optional[Sequence[int]] = None, positions: Optional[Sequence[int]] = None) -> None:
        n = len(vrs)
        self.vrs = (fmi2ValueReference * n)(*vrs)
        self.n = n
        layout = _Layout(n, sizes, positions)
        self.tail, self.positions = layout.tail, layout.positions
        self.values = np.zeros(layout.count, dtype=np.dtype(ctype))
        self.pointer = self.values.ctypes.data_as(POINTER(ctype))
        self.bus = bus
        self.index = np.asarray(index, dtype=np.intp)
        scale, shift = np.asarray(factor, float), np.asarray(offset, float)
        transformed = bool(np.any(scale != 1.0) or np.any(shift != 0.0))
        self.factor = scale if transformed else None
        self.offset = shift
        self.setter, self.getter, self.handle = setter, getter, handle

    def _gather(self) -> None:
        if self.positions is None:
            np.take(self.bus, self.index, out=self.values)
            if self.factor is not None:
                self.values *= self.factor
                self.values += self.offset
        else:  # FMI 3.0: into the variables' elements, converted to their type
            fresh = self.bus[self.index]
            self.values[self.positions] = fresh if self.factor is None else fresh * self.factor + self.offset

    def apply(self) -> None:
        """Gather from the bus, transform, and set in the FMU."""
        self._gather()
        self.setter(self.handle, self.vrs, self.n, self.pointer, *self.tail)

    def update(self) -> bool:
        """Gather from the bus and transform without setting; True when the values changed."""
        before = self.values.copy()
        self._gather()
        return not np.array_equal(before, self.values)

    def send(self) -> None:
        """Set the gathered values in the FMU."""
        self.setter(self.handle, self.vrs, self.n, self.pointer, *self.tail)

    def seed(self) -> None:
        """Take the values the FMU has now (so that :meth:`update` sees real changes only, and the
        elements of an FMI 3.0 array that are not connected keep their values)."""
        self.getter(self.handle, self.vrs, self.n, self.pointer, *self.tail)


class _StringInputs:
    """One unit's String inputs: ``values = bus[index]``, set in one call (no transform; FMI 3.0:
    whole variables, see :class:`_Layout`)."""

    def __init__(self, setter: Callable, getter: Callable, handle: Any, vrs: Sequence[int], bus: np.ndarray,
                 index: Sequence[int], sizes: Optional[Sequence[int]] = None,
                 positions: Optional[Sequence[int]] = None) -> None:
        n = len(vrs)
        self.vrs = (fmi2ValueReference * n)(*vrs)
        self.n = n
        layout = _Layout(n, sizes, positions)
        self.tail = layout.tail
        self.positions = np.arange(n, dtype=np.intp) if layout.positions is None else layout.positions
        self.values = new_bus("String", layout.count)
        self.buffer = (fmi2String * layout.count)()
        self.bus = bus
        self.index = np.asarray(index, dtype=np.intp)
        self.setter, self.getter, self.handle = setter, getter, handle

    def update(self) -> bool:
        """Gather from the bus without setting; True when a value changed."""
        fresh = self.bus[self.index]
        changed = not np.array_equal(fresh, self.values[self.positions])
        self.values[self.positions] = fresh
        return changed

    def send(self) -> None:
        """Set the gathered values in the FMU (UTF-8, as FMI strings are)."""
        self.buffer[:] = [text.encode("utf-8") for text in self.values]
        self.setter(self.handle, self.vrs, self.n, self.buffer, *self.tail)

    def apply(self) -> None:
        """Gather from the bus and set in the FMU."""
        self.update()
        self.send()

    def seed(self) -> None:
        """Take the values the FMU has now (so that :meth:`update` sees real changes only)."""
        self.getter(self.handle, self.vrs, self.n, self.buffer, *self.tail)
        self.values[:] = decoded(self.buffer)


class _Outputs:
    """One unit's fetched variables of one numeric type, read straight into their bus slice (an
    FMI 3.0 variable: all its elements, ``sizes``; a type other than the bus's, e.g. Float32 on the
    Real bus, through a buffer of its own)."""

    def __init__(self, getter: Callable, handle: Any, vrs: Sequence[int], bus: np.ndarray, start: int,
                 ctype: Any, sizes: Optional[Sequence[int]] = None) -> None:
        n = len(vrs)
        self.vrs = (fmi2ValueReference * n)(*vrs)
        self.n = n
        layout = _Layout(n, sizes, None)
        self.tail = layout.tail
        self.staging: Optional[np.ndarray] = None
        if np.dtype(ctype) == bus.dtype:
            self.pointer = ctypes.cast(bus.ctypes.data + start * bus.itemsize, POINTER(ctype))
        else:
            self.staging = np.zeros(layout.count, dtype=np.dtype(ctype))
            self.pointer = self.staging.ctypes.data_as(POINTER(ctype))
        self.bus, self.slots = bus, slice(start, start + layout.count)
        self.getter, self.handle = getter, handle

    def fetch(self) -> None:
        """Read the variables into the bus."""
        self.getter(self.handle, self.vrs, self.n, self.pointer, *self.tail)
        if self.staging is not None:
            self.bus[self.slots] = self.staging


class _StringOutputs:
    """One unit's fetched String variables, decoded into their bus slice."""

    def __init__(self, getter: Callable, handle: Any, vrs: Sequence[int], bus: np.ndarray, start: int,
                 sizes: Optional[Sequence[int]] = None) -> None:
        n = len(vrs)
        self.vrs = (fmi2ValueReference * n)(*vrs)
        self.n = n
        layout = _Layout(n, sizes, None)
        self.tail = layout.tail
        self.buffer = (fmi2String * layout.count)()
        self.bus, self.slots = bus, slice(start, start + layout.count)
        self.getter, self.handle = getter, handle

    def fetch(self) -> None:
        """Read the variables and store them in the bus as ``str`` (the FMU owns its buffers)."""
        self.getter(self.handle, self.vrs, self.n, self.buffer, *self.tail)
        self.bus[self.slots] = decoded(self.buffer)


Inputs = Union[_Inputs, _StringInputs]


class Unit:
    """An instantiated FMU in the master (the base of the CS and ME units)."""

    interface = ""
    fmu_class: type = FMU2Slave

    def __init__(self, component: ResolvedComponent, unzip_dir: str, fmu: Any = None) -> None:
        """``fmu``: an fmpy object already loaded (and maybe instantiated) to use instead of a new one."""
        self.component = component
        self.name = component.name
        self.info = component.info
        md = component.info.md
        #: the FMU's last log messages: (status, category, text)
        self.messages: deque = deque(maxlen=20)
        #: called with (unit name, status, category, text) for every message the FMU logs
        self.on_message: Optional[Callable[[str, int, str, str], None]] = None
        #: fmi2Instantiate's loggingOn: the FMU sends its debug categories too
        self.logging_on = False
        self._callbacks = _callbacks(self)
        try:
            self.fmu = fmu if fmu is not None else self.fmu_class(
                guid=md.guid, unzipDirectory=unzip_dir,
                modelIdentifier=component.info.model_identifier(self.interface), instanceName=self.name)
        except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions (no binary, a failed dlopen)
            raise FmuFailure(f"{self.name} ({component.fmu.name}): cannot load its binary: {exc}") from None
        self.inputs: List[Inputs] = []
        self.outputs: List[Union[_Outputs, _StringOutputs]] = []
        self.step_multiple = component.spec.step_multiple
        self.instantiated = False
        #: out of initialization mode (stepping, event or continuous-time mode): fmi2Terminate allowed
        self.initialized = False
        #: a call returned fmi2Error or fmi2Fatal: the FMU is in its error state, only free it
        self.failed = False

    # --- life cycle ---------------------------------------------------------------------------
    def instantiate(self, start: float, stop: float) -> None:
        """fmi2Instantiate + fmi2SetupExperiment (rtol of the solver options as tolerance).

        A failed fmi2Instantiate (fmpy raises a bare "Failed to instantiate model") becomes an
        :class:`FmuFailure` quoting what the FMU logged while it tried.
        """
        self.messages.clear()
        self.initialized = self.failed = False
        try:
            self._instantiate_fmu()
        except FMICallException as exc:
            raise self.failure(exc) from None
        except Exception as exc:  # noqa: BLE001 - fmpy raises a plain Exception when the instantiation returns NULL
            # any other exception is fmpy's before it called the FMU (a folder name it cannot encode)
            reason = self.instantiation_reason() if type(exc) is Exception else \
                f"fmpy could not call it: {type(exc).__name__}: {exc}"
            raise FmuFailure(f"{self.name} ({self.component.fmu.name}): {self.instantiate_call} failed: "
                             f"{reason}") from None
        self.instantiated = True
        self._set_up_experiment(self.component.spec.solver.get("rtol"), start, stop)

    #: the FMI function that instantiates the FMU (named when it fails)
    instantiate_call = "fmi2Instantiate"

    def _instantiate_fmu(self) -> None:
        self.fmu.instantiate(callbacks=self._callbacks, loggingOn=self.logging_on)

    def _set_up_experiment(self, tolerance: Optional[float], start: float, stop: float) -> None:
        self.call(self.fmu.setupExperiment, tolerance=tolerance, startTime=start, stopTime=stop)

    def apply_start_values(self) -> None:
        """Set the scenario's parameters and start values (before initialization mode): one set
        call per FMI type, each variable once with the last value given for it (a study case's
        value comes after the scenario's)."""
        given: Dict[str, Dict[int, Any]] = {}
        for port, value in self.component.start_values:
            given.setdefault(port.type, {})[port.vr] = value
        setters = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger,
                   "Boolean": self.fmu.setBoolean, "String": self.fmu.setString}
        for kind, values in given.items():
            self.call(setters[kind], list(values), list(values.values()))

    def enter_initialization(self) -> None:
        """fmi2EnterInitializationMode."""
        self.call(self.fmu.enterInitializationMode)

    def exit_initialization(self, time: float) -> None:
        """fmi2ExitInitializationMode (the ME unit continues with its event iteration)."""
        self.call(self.fmu.exitInitializationMode)
        self.initialized = True

    def close(self) -> None:
        """fmi2Terminate where the FMI 2.0 state machine allows it (after initialization, no
        error returned), then free the instance; never raises."""
        if self.instantiated:
            if self.initialized and not self.failed:
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
        """One variable (slow path: initialization and tests); a String comes back as ``str``."""
        getter = {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger,
                  "Boolean": self.fmu.getBoolean, "String": self.fmu.getString}[port.type]
        value = self.call(getter, [port.vr])[0]
        if port.type == "String":
            return decoded([value])[0]
        return bool(value) if port.type == "Boolean" else value

    def set_value(self, port: Port, value: Any) -> None:
        """Set one variable (slow path: start values and initialization)."""
        setter = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger,
                  "Boolean": self.fmu.setBoolean, "String": self.fmu.setString}[port.type]
        self.call(setter, [port.vr], [value])

    def wire_inputs(self, kind: str, vrs: Sequence[int], bus: np.ndarray, index: Sequence[int],
                    factor: Sequence[float], offset: Sequence[float], elements: Sequence[int] = ()) -> None:
        """Take inputs of FMI type ``kind`` from ``bus[index]`` before every step (``elements``:
        each input's place in its FMI 3.0 array variable; FMI 2.0 has none)."""
        setter, getter = bare_function(self.fmu, f"fmi2Set{kind}"), bare_function(self.fmu, f"fmi2Get{kind}")
        handle = self.fmu.component
        if kind == "String":
            self.inputs.append(_StringInputs(setter, getter, handle, vrs, bus, index))
        else:
            self.inputs.append(_Inputs(setter, getter, handle, vrs, bus, index, factor, offset, TYPES[kind][0]))
        self.inputs[-1].kind = kind

    def output_slots(self, kind: str, vrs: Sequence[int]) -> List[Tuple[int, int]]:
        """The (value reference, element) that :meth:`wire_outputs` puts in each slot of its bus
        slice, in order (FMI 2.0: the variables ``vrs`` themselves)."""
        return [(vr, 0) for vr in vrs]

    def wire_outputs(self, kind: str, vrs: Sequence[int], bus: np.ndarray, start: int) -> None:
        """Read variables of type ``kind`` into ``bus[start:start + len(vrs)]`` after every step."""
        getter = bare_function(self.fmu, f"fmi2Get{kind}")
        if kind == "String":
            self.outputs.append(_StringOutputs(getter, self.fmu.component, vrs, bus, start))
        else:
            self.outputs.append(_Outputs(getter, self.fmu.component, vrs, bus, start, TYPES[kind][0]))
        self.outputs[-1].kind = kind

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
        """Advance from ``time`` by ``step``; raises :class:`Terminated` when the FMU ends the run."""
        raise NotImplementedError

    @property
    def can_save_state(self) -> bool:
        """Whether fmi2GetFMUstate/fmi2SetFMUstate work for this unit."""
        return self.info.can_get_set_state(self.interface)

    def save_state(self) -> Any:
        """A snapshot to :meth:`restore_state` (release it with :meth:`free_state`)."""
        return self.call(self.fmu.getFMUState if self.fmi3 else self.fmu.getFMUstate)

    def restore_state(self, state: Any) -> None:
        """Go back to a snapshot."""
        self.call(self.fmu.setFMUState if self.fmi3 else self.fmu.setFMUstate, state)

    def free_state(self, state: Any) -> None:
        """Release a snapshot."""
        self.call(self.fmu.freeFMUState if self.fmi3 else self.fmu.freeFMUstate, state)

    @property
    def fmi3(self) -> bool:
        """Whether this unit runs an FMI 3.0 FMU."""
        return isinstance(self.fmu, _FMU3)

    def call(self, function: Callable, *args: Any, **kwargs: Any) -> Any:
        """Call an fmpy function, turning an FMI error status into :class:`FmuFailure`."""
        try:
            return function(*args, **kwargs)
        except FMICallException as exc:
            raise self.failure(exc) from None

    def failure(self, exc: BaseException) -> FmuFailure:
        """A :class:`FmuFailure` for ``exc`` that quotes the FMU's last log message."""
        if getattr(exc, "status", fmi2Error) >= fmi2Error:
            self.failed = True  # the FMU is in its error (or fatal) state now
        last = ""
        for status, _, message in reversed(self.messages):
            if status >= 2:
                last = message.strip().splitlines()[-1] if message.strip() else ""
                break
        return FmuFailure(f"{self.name}: {str(exc).rstrip('.')}" + (f": {last}" if last else ""))

    def instantiation_reason(self) -> str:
        """What the FMU logged while fmi2Instantiate failed (see :func:`instantiation_reason`)."""
        return instantiation_reason(self.messages)

    def termination_reason(self) -> str:
        """What the FMU said when it ended the simulation: its last fmi2Discard message, if any."""
        for status, _, message in reversed(self.messages):
            if status == 2:
                return message.strip()
        return ""


def instantiation_reason(messages: Sequence[Tuple[int, str, str]]) -> str:
    """What an FMU logged, as ``(status, category, text)``, while its fmi2Instantiate failed: its
    errors (else all its messages), the last line of each (a Python traceback ends with the
    exception), or a note that it said nothing."""
    logged = [m for m in messages if m[0] >= 3] or list(messages)
    lines = [text.strip().splitlines()[-1].strip() for _, _, text in logged if text.strip()]
    return "; ".join(dict.fromkeys(lines)) or ("the FMU logged no reason (a GUID or modelIdentifier that does "
                                               "not match its binary is the usual cause)")


def _callbacks(unit: Unit) -> fmi2CallbackFunctions:
    """The unit's callbacks: the logger keeps the last messages (quoted when a call fails) and
    passes each to ``unit.on_message``."""
    messages = unit.messages

    def record(status: int, category: str, text: str) -> None:
        messages.append((status, category, text))
        if unit.on_message is not None:
            unit.on_message(unit.name, status, category, text)

    return logger_callbacks(record)


def logger_callbacks(record: Callable[[int, str, str], None]) -> fmi2CallbackFunctions:
    """fmi2CallbackFunctions whose logger calls ``record(status, category, text)``; keep the
    result referenced while the instance lives.

    Not fmpy's default callbacks, whose logger prints to stdout. No fmpy ``addLoggerProxy``: it
    keeps ONE process-wide pointer to the last logger it wrapped, so per-unit loggers would
    dangle once freed (a crash at the next message) and every FMU's messages would go to the
    last unit. The message text is used as is (deltafmi FMUs pass it fully formatted).
    """
    def logger(env: Any, instance: bytes, status: int, category: bytes, message: bytes) -> None:
        try:
            record(status, category.decode("utf-8", "replace") if category else "",
                   message.decode("utf-8", "replace") if message else "")
        except Exception:  # noqa: BLE001  (nothing may raise into the FMU's C code)
            pass

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory, callbacks.freeMemory = _memory_callbacks()
    return callbacks


_memory: List[Any] = []


def _memory_callbacks() -> List[Any]:
    """fmi2CallbackAllocateMemory and fmi2CallbackFreeMemory of fmpy's calloc and free, made
    once: they hold no state of a unit, and live as long as the process (as the FMUs that may
    call them)."""
    if not _memory:
        from fmpy import calloc, free

        _memory[:] = [fmi2CallbackAllocateMemoryTYPE(calloc), fmi2CallbackFreeMemoryTYPE(free)]
    return _memory
