"""A system FMU's doStep taken in C, from the FMU's C layer into the master's C loop.

``native/system_step.c`` is the component's compiled step (:meth:`.Component._compiled_step`):
while the component arms it (:meth:`DirectStep.arm`), the FMU's ``fmi2DoStep``/``fmi3DoStep``
calls it, and it sets the inputs the importer changed on their units and runs the master's fixed
steps through the C loop's plan of this run, with no Python, writing the exported outputs from
the buses. Whatever the Python step would do more (an input C cannot set, a step off the master's
grid, an event, a failure, a NaN, a unit's message to pass on) it leaves to Python: untouched,
or with the C loop's return pending, which
:meth:`DirectStep.finish` completes as the master's own loop does. Python takes the master's
position back (:meth:`DirectStep.catch_up`) before anything else touches the master.
"""
from __future__ import annotations

import ctypes
import os
from ctypes import c_double, c_int, c_long, c_void_p
from pathlib import Path
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np

from deltafmi.master.scenario.system import Port
from deltafmi.master.stepping.c_loop import NativeLoop
from deltafmi.master.stepping.unit_base import Unit, function_address
from deltafmi.toolchain import BuildError, plain_c_library

__all__ = ["DirectStep", "compiled_step"]

_SOURCE = Path(__file__).parent / "native" / "system_step.c"


class _SystemStep(ctypes.Structure):
    """system_step.c's SystemStep, field for field."""

    _fields_ = [("run", c_void_p), ("plan", c_void_p), ("rows", c_void_p), ("capacity", c_long), ("width", c_long),
                ("k", c_long), ("n_steps", c_long), ("start", c_double), ("h", c_double), ("stop", c_double),
                ("check_finite", c_int), ("pending", c_int), ("why", c_int),
                ("run_k", c_long), ("done", c_long), ("n_rows", c_long), ("k_end", c_long),
                ("recorded_until", c_double),
                ("n_inputs", c_long), ("input_index", c_void_p), ("input_is_int", c_void_p), ("applied", c_void_p),
                ("set_kind", c_void_p), ("setter", c_void_p), ("unit", c_void_p), ("vr", c_void_p),
                ("n_outputs", c_long), ("source", c_void_p), ("source_int", c_void_p), ("target", c_void_p),
                ("target_int", c_void_p), ("real_bus", c_void_p), ("n_real_bus", c_long),
                ("real_columns", c_void_p), ("n_real_columns", c_long), ("messages", c_void_p),
                ("messages_seen", ctypes.c_int64)]


_library: List[Any] = []
#: system_step.c's ways of setting an input on its unit
SET_PYTHON, SET_REAL2, SET_INT2, SET_REAL3, SET_INT3, SET_BOOL3 = range(6)
_SET3 = {"Float64": ("fmi3SetFloat64", SET_REAL3), "Int32": ("fmi3SetInt32", SET_INT3),
         "Boolean": ("fmi3SetBoolean", SET_BOOL3)}
_SET2 = {"Real": ("fmi2SetReal", SET_REAL2), "Integer": ("fmi2SetInteger", SET_INT2),
         "Boolean": ("fmi2SetBoolean", SET_INT2)}


def _setter(unit: Any, port: Port) -> Tuple[int, int, int, int]:
    """(kind, FMI setter, component, value reference) that set ``port`` of ``unit`` in C as
    :meth:`.Unit.set_value` does: one scalar of FMI 2.0, or of an FMI 3.0 Float64, Int32 or Boolean
    variable that is no array; (SET_PYTHON, 0, 0, 0) for what Python sets."""
    if not isinstance(unit, Unit):
        return SET_PYTHON, 0, 0, 0
    if unit.fmi3:
        variable = unit._variable(port.vr)
        name, kind = _SET3.get(variable.type, ("", SET_PYTHON))
        if unit._size(port.vr) != 1:
            kind = SET_PYTHON
    else:
        name, kind = _SET2.get(port.type, ("", SET_PYTHON))
    if kind == SET_PYTHON:
        return SET_PYTHON, 0, 0, 0
    return kind, function_address(unit.fmu, name), unit.fmu.component, port.vr


def compiled_step() -> Optional[Tuple[int, int, int]]:
    """(step, outputs, context size) of system_step.c for :meth:`.Component._compiled_step`, or
    None where it cannot be loaded (no compiler and no prebuilt copy) or ``DELTAFMI_SYSTEM_C_STEP=0``
    is set (for comparisons): then every doStep runs through Python."""
    if os.environ.get("DELTAFMI_SYSTEM_C_STEP") == "0":
        return None
    if not _library:
        try:
            _library.append(ctypes.CDLL(str(plain_c_library(_SOURCE))))
        except (BuildError, OSError):
            _library.append(None)
    library = _library[0]
    if library is None:
        return None
    return (ctypes.cast(library.dfmi_system_step, c_void_p).value,
            ctypes.cast(library.dfmi_system_outputs, c_void_p).value, ctypes.sizeof(_SystemStep))


class DirectStep:
    """The C step of one master run inside a system FMU (see the module docstring).

    ``slot``: the instance's :class:`~deltafmi.runtime.instance.CompiledStep`; ``inputs``: per
    exported input, its (real or int) buffer index, whether it is an int, and its unit's port;
    ``outputs``: per exported output, in the order of the master's recorded variables, its buffer
    index and whether it is an int; ``messages``: the counter the master's message callback
    increments. Raises ValueError where an output cannot be read from the buses (Python then
    takes every step).
    """

    def __init__(self, slot: Any, master: Any, inputs: Sequence[Tuple[int, bool, Port]],
                 outputs: Sequence[Tuple[int, bool]], messages: np.ndarray) -> None:
        self.slot, self.master = slot, master
        native: NativeLoop = master._fixed_native
        self.native = native
        grid = master._fixed_grid
        self.applied = np.zeros(max(1, len(inputs)))
        self._input_index = np.array([i for i, _, _ in inputs] or [0], dtype=np.int64)
        self._input_is_int = np.array([int(b) for _, b, _ in inputs] or [0], dtype=np.int32)
        units = {unit.name: unit for unit in master.units}
        setters = [_setter(units[port.component], port) for _, _, port in inputs] or [(SET_PYTHON, 0, 0, 0)]
        self._set_kind = np.array([kind for kind, _, _, _ in setters], dtype=np.int32)
        self._setter = np.array([function for _, function, _, _ in setters], dtype=np.uintp)
        self._unit = np.array([handle for _, _, handle, _ in setters], dtype=np.uintp)
        self._vr = np.array([vr for _, _, _, vr in setters], dtype=np.uint32)
        column_source = {}
        for bus, index, columns in master.sampler._parts:
            for slot_index, column in zip(index, columns):
                column_source[int(column)] = (bus.ctypes.data + int(slot_index) * bus.itemsize,
                                              int(bus.dtype != np.float64))
        if any(c not in column_source for c in range(len(outputs))):
            raise ValueError("an exported output is not on the master's buses")
        self._source = np.array([column_source[c][0] for c in range(len(outputs))] or [0], dtype=np.intp)
        self._source_int = np.array([column_source[c][1] for c in range(len(outputs))] or [0], dtype=np.int32)
        self._target = np.array([i for i, _ in outputs] or [0], dtype=np.int64)
        self._target_int = np.array([int(b) for _, b in outputs] or [0], dtype=np.int32)
        real_bus = master.buses["Real"]
        self._real_columns = np.asarray(master._real_columns, dtype=np.int64)
        self._messages = messages
        self.context = _SystemStep.from_buffer(slot.context)
        self.context.__init__(
            run=native.entry(), plan=ctypes.addressof(native.plan), rows=native.rows.ctypes.data,
            capacity=len(native.rows), width=native.rows.shape[1] - 1, k=master.steps, n_steps=grid.n_steps,
            start=grid.start, h=grid.h, stop=grid.stop, check_finite=int(master.check_finite),
            recorded_until=float("nan"), pending=0,
            n_inputs=len(inputs), input_index=self._input_index.ctypes.data,
            input_is_int=self._input_is_int.ctypes.data, applied=self.applied.ctypes.data,
            set_kind=self._set_kind.ctypes.data, setter=self._setter.ctypes.data, unit=self._unit.ctypes.data,
            vr=self._vr.ctypes.data,
            n_outputs=len(outputs), source=self._source.ctypes.data, source_int=self._source_int.ctypes.data,
            target=self._target.ctypes.data, target_int=self._target_int.ctypes.data,
            real_bus=real_bus.ctypes.data, n_real_bus=len(real_bus),
            real_columns=self._real_columns.ctypes.data if len(self._real_columns) else None,
            n_real_columns=len(self._real_columns), messages=messages.ctypes.data)
        self._keep = real_bus

    @staticmethod
    def possible(master: Any) -> bool:
        """Whether the master's run can take its steps from the FMU's C layer: its fixed steps
        in the C loop, run by the calling thread alone (no parallel groups)."""
        native = master._fixed_native
        return native is not None and master.threads <= 1 and not native.plan.pace \
            and not native.plan.gil_released

    def arm(self, applied: Sequence[float]) -> None:
        """Let the C layer take the next steps, from where the master stands, with the FMU's
        inputs as ``applied`` (the values their units have)."""
        if not self.native.ready():
            return
        self.native.enter()
        context = self.context
        context.k, context.pending = self.master.steps, 0
        context.messages_seen = int(self._messages[0])
        self.applied[:len(applied)] = applied
        self.slot.ready[0] = 1

    def catch_up(self) -> Optional[List[float]]:
        """Python takes over: the master where the C steps left it (the steps taken, the time);
        returns the inputs' values their units have now (C may have set some), None when the C
        layer had nothing to take."""
        if not self.slot.ready[0] or self.context.plan != ctypes.addressof(self.native.plan):
            return None  # not armed, or armed by a later run of the instance
        self.slot.ready[0] = 0
        self.native.leave()
        context, master = self.context, self.master
        if context.k != master.steps:
            grid = master._fixed_grid
            master.steps = k = context.k
            master.time = master.step_end = grid.start + k * grid.h if k < grid.n_steps else grid.stop
        if context.recorded_until == context.recorded_until:
            master.recorded_until = context.recorded_until
        return self.applied[:context.n_inputs].tolist()

    def pending(self) -> bool:
        """Whether the C step left a run of the C loop for :meth:`finish`."""
        return bool(self.context.pending)

    def finish(self) -> None:
        """The step the C layer began: the C loop's run it left completed as the master's loop
        completes one, then the master's steps up to the step's end."""
        context, master = self.context, self.master
        context.pending = 0
        master.after_c_run(self.native, master._fixed_grid, context.run_k, context.why, context.done,
                           context.n_rows)
        master.advance(context.k_end)
