"""The co-simulation master: instantiate, initialize and step the units of a resolved :class:`System`.

* Initialization: start values and parameters, then inside initialization mode every connected
  input is set from its source output in dependency order (outputs that depend directly on
  inputs are read after those inputs are set), so the closed loop starts consistent.
* Stepping: Gauss-Seidel in the system's stepping order (default) or Jacobi; a unit with
  ``step_multiple`` m steps every m-th communication step over m steps.
* Algebraic loops are solved at initialization and at every step (:mod:`deltafmi.master.stepping.algebraic_loops`):
  the units of a loop step as one block.
* Optional adaptive communication step with rollback (:mod:`deltafmi.master.stepping.adaptive`).
* Results stream to CSV; events of ME units (and of FMI 3.0 CS units in event mode) add rows at
  the event instant: the event unit's values there, every other unit's latest at or before it (a
  co-simulation knows them only at communication points): inside a step those of the step's
  start, at the step's end those of the units that reached it. No row shows a value of a time
  after its own.
* FMI 2.0 and FMI 3.0 FMUs run side by side (:mod:`.fmi3_units`): an FMI 3.0 array variable is
  its elements on the buses, each with a slot keyed (bus, unit, value reference, element).
* Fixed steps run in C where :mod:`deltafmi.master.stepping.c_loop` can (the same FMI calls, 64
  steps per foreign call); the step where C stops (an event, a failure) is finished here.
"""
from __future__ import annotations

import math
import shutil
import signal
import tempfile
import time as _time
from pathlib import Path
from typing import Any, Callable, Dict, List, NamedTuple, Optional, Sequence, Tuple

import fmpy
import numpy as np

from deltafmi.errors import BadInput, Interrupted, SimulationError
from deltafmi.toolchain import BuildError

from ..live.pacing import FellBehind
from ..results.background import BackgroundRows
from ..results.csv_file import CsvWriter, RowSampler
from ..results.safe_file import check_writable
from ..results.writers import write_rows_to, writer_for
from ..results.progress import Progress, Summary, Termination
from ..scenario.system import ResolvedComponent, Port, System
from ..scenario.spec import grid_steps, too_many_steps
from .adaptive import run_adaptive
from .explicit_rk import RungeKuttaError, step_failure
from .initial_links import copy_initial_links
from deltafmi.master.stepping.algebraic_loops import InitialLoops, LoopBlock, LoopStatistics, Stepper
from deltafmi.master.stepping.c_loop import (CLOCK_INSIDE, FETCH, PULL, RAN, RK_FAILED, ROWS_FULL, STATE_EVENT, STEP, STEP_EVENT,
                          STEP_RETURNED, TERMINATED, UNSETTLED, BEHIND, LIVE, NativeLoop)
from .stop_signals import StopSignals
from .unit_base import _Inputs, _Outputs, instant_margin
from .parallel import StepPool, group_actions
from .unpacked import kept_unpacked
from .units import TYPES, CoSimulationUnit, FmuFailure, Terminated, Unit, new_bus, unit_for

__all__ = ["Master", "NativeLoop"]

#: an unpaced call of the C loop goes on until the run's end or its rows block is full, and
#: returns after _C_RETURN_SECONDS of wall time (stop signals and progress are looked at in
#: between: a stop signal is answered within that, or one step of a slower model). Each hand-back
#: to Python costs far more than a step of compiled units (the Python, and the C loop's data out of
#: the caches when it goes on). Paced: steps of the first call; while a call is shorter than
#: _C_SECONDS the next takes as many steps as would fill _C_SECONDS at its pace, between twice and
#: _C_GROWTH times as many, up to _C_MAX_STEPS.
_C_RETURN_SECONDS = 0.05
_C_STEPS = 64
_C_GROWTH = 8
_C_MAX_STEPS = 4096
_C_SECONDS = 0.005
_C_ROWS_BYTES = 8 << 20
#: rows the C loop hands to the CSV writer's thread of C at once, while it steps on (each hand-over
#: wakes the thread: a system call on the stepping thread, dearer on a virtual machine)
_C_SINK_ROWS = 1024


class _FixedGrid(NamedTuple):
    start: float
    stop: float
    h: float
    n_steps: int
    last: int  # steps from k with k + m < last are m * h long, later ones end at stop


def _address(handle: Any) -> Any:
    """An instance handle's address (fmpy keeps an int, or a ctypes pointer)."""
    return getattr(handle, "value", handle)


class _Wiring:
    """The buses and the units' input and output wiring of one run, for a later run of the same
    system on the same FMU instances (a study's pooled FMUs, reset between cases): the wiring is
    a function of the system's links and recorded variables and of the instances (their value
    references, functions and handles), none of which changes between such runs. Used again,
    the buses and the inputs' and outputs' value buffers are set back to what new ones hold, so
    the run sees exactly what a fresh wiring gives it. Only FMI 2.0 units of the master's own
    classes, with no String inputs or outputs, are kept."""

    #: wirings kept per dict (the least recently made dropped beyond)
    KEEP = 8

    def __init__(self, system: System, units: Sequence[Unit], buses: Dict[str, np.ndarray],
                 slot: Dict[Tuple[str, str, int, int], int]) -> None:
        self.links, self.recorded = system.links, system.recorded
        self.fmus = [unit.fmu for unit in units]
        self.handles = [_address(unit.fmu.component) for unit in units]
        self.buses, self.slot = buses, slot
        self.pristine = {kind: bus.copy() for kind, bus in buses.items()}
        self.wired = [(list(unit.inputs), list(unit.outputs), list(getattr(unit, "_discrete_inputs", ())))
                      for unit in units]
        #: runs that used it again
        self.reuses = 0
        #: what the master derives from the wiring for recording (its row sampler, the columns
        #: not each event unit's own, the Real columns, the names of the Real bus's slots)
        self.recording: Optional[Tuple[RowSampler, Dict[str, np.ndarray], np.ndarray, List[str]]] = None
        #: the C loop of the last run on this wiring, renewed by a later run with the same
        #: :meth:`NativeLoop.key_of` (the plan points into the buses, the value holders and the row sampler)
        self.native: Optional[NativeLoop] = None

    @staticmethod
    def _key(units: Sequence[Unit]) -> Tuple[int, ...]:
        return tuple(id(unit.fmu) for unit in units)

    @staticmethod
    def _own_classes(units: Sequence[Unit]) -> bool:
        """Whether every unit is of the master's own FMI 2.0 classes (whose wiring is kept)."""
        from .me_integrator import ModelExchangeUnit
        return all(type(unit) in (CoSimulationUnit, ModelExchangeUnit) for unit in units)

    @classmethod
    def _eligible(cls, units: Sequence[Unit]) -> bool:
        """Whether ``units``, not wired yet, may take a kept wiring."""
        return cls._own_classes(units) and not any(
            unit.inputs or unit.outputs or getattr(unit, "_discrete_inputs", None) for unit in units)

    @classmethod
    def find(cls, wirings: Optional[Dict[Any, Any]], system: System, units: Sequence[Unit]) -> Optional["_Wiring"]:
        """The kept wiring of ``system`` on these very FMU instances, if any."""
        if wirings is None:
            return None
        kept = wirings.get(cls._key(units))
        if kept is None or kept.links is not system.links or kept.recorded is not system.recorded \
                or not cls._eligible(units) \
                or any(fmu is not unit.fmu for fmu, unit in zip(kept.fmus, units)) \
                or any(handle != _address(unit.fmu.component) for handle, unit in zip(kept.handles, units)):
            return None
        return kept

    @classmethod
    def keep(cls, wirings: Optional[Dict[Any, Any]], system: System, units: Sequence[Unit],
             buses: Dict[str, np.ndarray], slot: Dict[Tuple[str, str, int, int], int]) -> Optional["_Wiring"]:
        """Keep the wiring just made (when its units qualify); returns it (None: not kept)."""
        if wirings is None or not all(type(io) in (_Inputs, _Outputs) for unit in units
                                      for io in unit.inputs + unit.outputs + getattr(unit, "_discrete_inputs", [])):
            return None
        if not cls._own_classes(units):
            return None
        key = cls._key(units)
        wirings.pop(key, None)
        kept = wirings[key] = cls(system, units, buses, slot)
        while len(wirings) > cls.KEEP:
            try:
                wirings.pop(next(iter(wirings)), None)
            except (StopIteration, RuntimeError):  # another thread's run changed it meanwhile
                break
        return kept

    def reuse(self, master: "Master") -> Dict[Tuple[str, str, int, int], int]:
        """Give ``master``'s units and buses this wiring, as new; returns the bus slots."""
        for kind, bus in self.buses.items():
            bus[...] = self.pristine[kind]
        master.buses = self.buses
        self.reuses += 1
        for unit, (inputs, outputs, discrete) in zip(master.units, self.wired):
            for io in inputs + discrete:
                io.values[...] = 0
            for io in outputs:
                if io.staging is not None:
                    io.staging[...] = 0
            unit.inputs, unit.outputs = list(inputs), list(outputs)
            if discrete:
                unit._discrete_inputs = list(discrete)  # type: ignore[attr-defined]
        return self.slot


class Master:
    """Runs one :class:`System`; create, then call :meth:`run` once."""

    def __init__(self, system: System, result: Optional[Path] = None, stop: Optional[float] = None,
                 algorithm: Optional[str] = None, progress: bool = False,
                 warn: Callable[[str], None] = lambda message: None,
                 fmus: Optional[Callable[[ResolvedComponent], Any]] = None,
                 writer_class: Optional[Callable[..., Any]] = None, native: bool = True,
                 on_message: Optional[Callable[[str, int, str, str], None]] = None,
                 debug_logging: bool = False, replay: Optional[Path] = None,
                 progress_lines: bool = False, wirings: Optional[Dict[Any, Any]] = None) -> None:
        """``fmus`` lends each component a loaded fmpy FMU object (default: extract and load every
        FMU for this run; deltafmi.apps.studies keeps them loaded across runs and resets them);
        ``on_message(component, status, category, text)`` gets every message the FMUs log
        (default: none is shown); ``debug_logging``: instantiate with loggingOn, so the FMUs send
        their debug categories too;
        ``writer_class(path, names, kinds=...)`` makes the result writer (default: chosen by the
        result file's extension, :func:`~deltafmi.master.results.writers.writer_for`, which also
        gets ``units=``; an unknown extension is a :class:`BadInput` here, before anything runs);
        ``native``: run fixed steps in C where :mod:`.native_loop` can (same calls, same results);
        ``replay``: a results file of an earlier run of this scenario whose recorded live inputs
        stand in for the live sources (:mod:`deltafmi.master.live.replay`); ``progress``: a bar on
        a terminal, ``progress_lines``: a line every 30 s instead (a log); ``wirings``: a dict the
        caller keeps across runs of one system with ``fmus`` (a study's cases): the buses and the
        units' input and output wiring are kept in it and used again by a later run that gets
        the same FMU instances (:class:`_Wiring`)."""
        scenario = system.scenario
        self.system = system
        self.start = scenario.experiment.start
        self.stop = scenario.experiment.stop if stop is None else float(stop)
        if self.stop <= self.start:
            raise BadInput(f"stop time {self.stop} is not after start time {self.start}")
        self.step = scenario.experiment.step
        if not all(map(math.isfinite, (self.start, self.stop, self.step))):
            raise BadInput(f"start {self.start:g} s, stop {self.stop:g} s and step {self.step:g} s must be finite "
                           "numbers")
        if not scenario.master.adaptive.enabled:
            why = too_many_steps(self.start, self.stop, self.step, scenario.master.max_steps)
            if why:
                raise BadInput(why)
        self.algorithm = algorithm or scenario.master.algorithm
        self.result_path = Path(result) if result is not None else scenario.result.file
        self.every = scenario.result.every
        self._writer_for_file = writer_for(self.result_path) if writer_class is None else None
        if writer_class is None:
            check_writable(self.result_path)
        self.progress = Progress(self.start, self.stop, progress, lines=progress_lines)
        self.warn = warn
        self.on_message = on_message
        self.debug_logging = debug_logging
        self.units: List[Unit] = []
        #: one block per algebraic loop solved at every step, and the loops of the initialization
        self.loops: List[LoopBlock] = []
        self.initial_loops: Optional[InitialLoops] = None
        self.writer: Optional[Any] = None  # a writer of ..results.writers, or the caller's
        self.sampler: Optional[RowSampler] = None
        self.buses: Dict[str, np.ndarray] = {}
        self.time = self.start
        self.steps = 0
        self.rejected = 0
        self.events = 0
        self._deferred: Optional[List[Tuple[float, Optional[np.ndarray], bool]]] = None
        #: the recorded row at the start of the step under way (time first), kept when a unit
        #: may have events inside a step and other units' columns to show with them
        self._step_start: Optional[np.ndarray] = None
        #: each event unit's name -> the recorded columns that are not its own (bool mask)
        self._others: Dict[str, np.ndarray] = {}
        self.step_end = self.start
        self._unzip_root = ""
        self._by_name: Dict[str, Unit] = {}
        self.fmus = fmus
        self.wirings = wirings if fmus is not None else None
        self.writer_class = writer_class
        self.native = native
        #: threads stepping independent units at once (master.threads; parallel.py)
        self.threads = scenario.master.threads
        self._groups: Optional[Tuple[List[Any], List[int]]] = None  # (actions, their groups) of the fixed grid
        self._pool: Optional[StepPool] = None
        self._native: Optional[NativeLoop] = None  # the C loop of a fixed-step run (its threads closed with the run)
        self._wiring: Optional[_Wiring] = None  # the wiring kept for later runs (wirings), if any
        #: Ctrl-C / SIGTERM: checked between steps (see :mod:`.stop_signals`)
        self.stop_signals = StopSignals()
        #: time of the last row written, None before the first
        self.recorded_until: Optional[float] = None
        #: check every recorded row and the Real bus for NaN/inf (see :meth:`_check_finite`)
        self.check_finite = not scenario.master.allow_nan
        self._real_names: List[str] = []  # the variable in each slot of the Real bus
        self._real_columns = np.zeros(0, np.intp)  # the Real columns of a recorded row
        self._zeros = np.zeros(1)
        #: live sources, pacing and streams (:mod:`deltafmi.master.live`); None for a plain run
        self.live: Optional[Any] = None
        if system.live:
            from ..live.run import LiveRun
            if scenario.master.adaptive.enabled:
                raise BadInput("live sources and real-time pacing need a fixed communication step: "
                               "master.adaptive is enabled")
            self.live = LiveRun(system, self.start, self.stop, self.step, replay=replay, warn=warn,
                                stopped=lambda: bool(self.stop_signals.received))
        elif replay is not None:
            raise BadInput(f"--replay {replay}: the scenario has no live source to take from it")

    # --- public -------------------------------------------------------------------------------
    def run(self) -> Summary:
        """Simulate from start to stop; raises :class:`SimulationError` with a one-line reason.

        The result file is replaced only when the run completes or is interrupted (with the rows
        up to there); a failed run keeps what it recorded under the failed name (``r.failed.csv``,
        which its message names) and leaves an earlier ``r.csv`` as it was. A component that
        ends the simulation (:class:`Terminated`) ends the run cleanly at its time.
        """
        wall = _time.perf_counter()
        terminated = None
        setup = closing = 0.0
        finished = interrupted = False
        try:
            with self.stop_signals:
                try:
                    self.open()
                    setup = _time.perf_counter() - wall
                    if self.system.scenario.master.adaptive.enabled and self._can_roll_back():
                        run_adaptive(self, self.system.scenario.master.adaptive)
                    else:
                        self._run_fixed()
                except Terminated as exc:
                    terminated = self._end_early(exc)
        except FellBehind as exc:
            raise SimulationError(f"{exc.message}{self._partial_note()} (master.realtime.behind: warn goes on)") \
                from None
        except (FmuFailure, fmpy.fmi1.FMICallException, RuntimeError, OSError, ValueError, KeyboardInterrupt) as exc:
            # a stop signal may come back from inside an FMU as its failure
            if self.stop_signals.received is None and not isinstance(exc, KeyboardInterrupt):
                raise SimulationError(f"simulation failed at t = {self.time:.9g} s: {exc}"
                                      f"{self._partial_note()}") from exc
            interrupted = True
            with self.stop_signals:  # a further signal breaks the writing (asked for twice)
                self.close()
            raise self._interrupted() from None
        else:
            finished = True
        finally:
            closing = _time.perf_counter()
            # a signal while the results are written (a .mat is written whole at the end) is
            # noted, not raised in the middle of the writing: the rows computed reach the file
            with self.stop_signals:
                if not finished and not interrupted:
                    self._fail_result()
                self.close()
            if not finished and self.live is not None and self.live.started:
                self.warn(f"live run up to t = {self.time:.9g} s: {self.live.report()}")  # what the summary says
        if self.stop_signals.received is not None:
            raise self._interrupted()  # at the end, while the results were written: they are whole
        end = _time.perf_counter()
        return Summary(self.steps, self.rejected, self.events, end - wall, self.time - self.start,
                       self.writer.rows_written, self.result_path, terminated, setup, self.loop_statistics(),
                       end - closing, self.live.report() if self.live is not None else None)

    def open(self) -> None:
        """Load, instantiate, wire and initialize every unit; record the first row.

        :meth:`run` calls it; call it yourself only to drive :meth:`step_all` by hand (and then
        :meth:`close`).
        """
        self._load()
        for unit in self.units:
            unit.instantiate(self.start, self.stop)
            unit.apply_start_values()
        self._wire()
        self._initialize()
        # the result file is opened only now, with a first row to write: a run that fails
        # before leaves an earlier result file as it was
        if self.live is not None:
            self.live.open_streams()
        recorded = self.system.recorded
        names, kinds = [p.ref for p in recorded], [p.type for p in recorded]
        if self.writer_class is not None:
            self.writer = self.writer_class(self.result_path, names, kinds=kinds)
        else:
            self.writer = self._writer_for_file(self.result_path, names, kinds=kinds,
                                                units=[p.unit for p in recorded])
        self._record(self.start)
        if self.live is not None:
            self.live.begin(self.start, self.sampler.sample)

    def close(self) -> None:
        """Flush the results and free every unit (safe after a failure, and twice)."""
        self.progress.close(self.time)
        if self.live is not None:
            self.live.close()
        try:
            if self.writer is not None:
                self.writer.close()  # may raise ResultWriteError (the last rows did not fit)
        finally:
            for unit in self.units:
                unit.close()
            if self._pool is not None:
                self._pool.close()
                self._pool = None
            if self._native is not None:
                self._native.close()
                self._native = None
            if self._unzip_root:
                shutil.rmtree(self._unzip_root, ignore_errors=True)
                self._unzip_root = ""

    def _end_early(self, stop: Terminated) -> Termination:
        """A unit ended the simulation at ``stop.time``: write the rows held back, then the last
        row with every unit's current values (the terminating unit's at the time it reached)."""
        self.time = stop.time
        if self.writer is not None and self.sampler is not None:
            if self._deferred is not None:
                self.commit_events()
            for unit in self.units:
                unit.fetch()
            self._record(stop.time)
        unit = self._by_name.get(stop.unit)
        return Termination(stop.unit, stop.time, unit.termination_reason() if unit is not None else "")

    def _interrupted(self) -> Interrupted:
        """The run was stopped by a signal (results flushed by :meth:`close`)."""
        kept = (self._nothing_kept() if self.recorded_until is None else
                f"results up to {self.recorded_until:.9g} in {self.result_path}")
        return Interrupted(f"interrupted at t = {self.time:.9g} s ({kept})",
                           self.stop_signals.received or signal.SIGINT)

    def _partial_note(self) -> str:
        if self.writer is None:
            return f" ({self._nothing_kept()})" if self.result_path.exists() else ""
        if self._deferred is not None:
            try:
                self.commit_events()  # the failing step's events came before the failure
            except SimulationError:  # a NaN in one of them: the failure at hand is the one to tell
                pass
        self.writer.flush()
        return f" (results up to the failure in {self._kept_after_failure()})"

    def _fail_result(self) -> Path:
        """The run failed: the writer keeps its rows under the failed name; where they are."""
        fail = getattr(self.writer, "fail", None)
        kept = fail() if fail is not None else None
        return Path(kept) if kept is not None else self.result_path

    def _kept_after_failure(self) -> str:
        """Where a failed run's rows are, and that an earlier result stays as it was."""
        kept = self._fail_result()
        if kept != self.result_path and self.result_path.exists():
            return f"{kept}; {self.result_path} left as it was"
        return str(kept)

    def _nothing_kept(self) -> str:
        existing = self.result_path.exists() and self.writer is None
        return f"no rows computed; {self.result_path} left as it was" if existing else "no rows computed"

    # --- set-up -------------------------------------------------------------------------------
    def _load(self) -> None:
        extracted: Dict[Path, str] = {}
        for component in self.system.components:
            fmu = self.fmus(component) if self.fmus is not None else None
            if fmu is None and component.fmu not in extracted:
                kept = kept_unpacked(component.fmu)  # a built FMU: unpacked once, by the first run
                if kept is not None:
                    extracted[component.fmu] = kept
                else:
                    if not self._unzip_root:  # FMUs lent by a study's pool need none
                        self._unzip_root = tempfile.mkdtemp(prefix="deltafmi-run-")
                    target = Path(self._unzip_root) / f"{len(extracted)}-{component.fmu.stem}"
                    extracted[component.fmu] = fmpy.extract(str(component.fmu), unzipdir=str(target))
            unit = unit_for(component, extracted[component.fmu] if fmu is None else fmu.unzipDirectory, fmu)
            if hasattr(unit, "on_event"):  # ME units, and FMI 3.0 CS units in event mode
                unit.on_event = self._on_event
            unit.on_message = self.on_message
            unit.logging_on = self.debug_logging
            self.units.append(unit)
            self._by_name[unit.name] = unit
        for unit in self.live.units if self.live is not None else ():
            self.units.append(unit)
            self._by_name[unit.name] = unit

    def _wire(self) -> None:
        """Lay out one bus per FMI type and precompute every unit's fetch and gather/set.

        Runs after instantiation: the precomputed calls hold the instance handles.
        """
        kept = self._wiring = _Wiring.find(self.wirings, self.system, self.units)
        if kept is not None:
            slot = kept.reuse(self)
        else:
            slot = self._wire_outputs()
        links = self.system.links

        def at(port: Port) -> int:
            return slot[(port.type, port.component, port.vr, port.index)]

        if kept is None:
            for unit in self.units:
                for kind in TYPES:
                    mine = [l for l in links if l.target.component == unit.name and l.target.type == kind]
                    if mine:
                        unit.wire_inputs(kind, [l.target.vr for l in mine], self.buses[kind],
                                         [at(l.source) for l in mine], [l.factor for l in mine],
                                         [l.offset for l in mine], [l.target.index for l in mine])
            kept = self._wiring = _Wiring.keep(self.wirings, self.system, self.units, self.buses, slot)
        if kept is not None and kept.recording is not None:
            # the row sampler and the names of the recorded and bus columns, as the run before
            # made them (they depend on the system and the slots alone; the row set back to zeros)
            self.sampler, self._others, self._real_columns, self._real_names = kept.recording
            self.sampler.row[...] = 0
        else:
            recorded = self.system.recorded
            parts = []
            for kind in TYPES:
                columns = [i for i, p in enumerate(recorded) if p.type == kind]
                parts.append((self.buses[kind], [at(recorded[i]) for i in columns], columns))
            self.sampler = RowSampler(parts, len(recorded))
            owners = np.array([p.component for p in recorded], dtype=object)
            self._others = {unit.name: owners != unit.name for unit in self.units
                            if hasattr(unit, "on_event") and (owners != unit.name).any()}
            self._real_columns = np.asarray([i for i, p in enumerate(recorded) if p.type == "Real"], np.intp)
            names = [""] * len(self.buses["Real"])
            for port in [link.source for link in links] + list(recorded):
                if port.type == "Real":
                    names[at(port)] = port.ref
            self._real_names = names
            if kept is not None:
                kept.recording = (self.sampler, self._others, self._real_columns, self._real_names)
        self._zeros = np.zeros(len(self._real_names))
        self.loops = [LoopBlock(loop, [self._by_name[name] for name in loop.members], self.buses,
                                [at(port) for port in loop.tears], self.system.scenario.master.loops, self)
                      for loop in self.system.loops]

    def _wire_outputs(self) -> Dict[Tuple[str, str, int, int], int]:
        """Give every connected or recorded variable a bus slot; returns (type, unit, vr, element)
        -> slot (an FMI 3.0 array is fetched whole: each of its elements has a slot)."""
        fetched: Dict[str, Dict[str, List[int]]] = {kind: {u.name: [] for u in self.units} for kind in TYPES}
        for port in [link.source for link in self.system.links] + list(self.system.recorded):
            vrs = fetched[port.type][port.component]
            if port.vr not in vrs:
                vrs.append(port.vr)
        slot: Dict[Tuple[str, str, int, int], int] = {}
        for kind in TYPES:
            layouts = {unit.name: unit.output_slots(kind, fetched[kind][unit.name]) for unit in self.units}
            bus = self.buses[kind] = new_bus(kind, max(1, sum(map(len, layouts.values()))))
            start = 0
            for unit in self.units:
                vrs, layout = fetched[kind][unit.name], layouts[unit.name]
                if vrs:
                    unit.wire_outputs(kind, vrs, bus, start)
                    slot.update({(kind, unit.name, vr, element): start + i for i, (vr, element) in enumerate(layout)})
                    start += len(layout)
        return slot

    def _initialize(self) -> None:
        for unit in self.units:
            unit.enter_initialization()
        by_name = self._by_name
        loops = self.initial_loops = InitialLoops(self.system.init_loops, by_name, self.system.scenario.master.loops)
        copy_initial_links(self.system.init_links, by_name, loops)
        for unit in self.units:
            unit.exit_initialization(self.start)
        for unit in self.units:
            unit.fetch()
        self._settle_inputs()

    def _settle_inputs(self) -> None:
        """Set every connected input from its source once more, sources before targets, and read
        the outputs again: leaving initialization mode a unit may change its outputs (a sampled
        controller takes its first sample) after the inputs they feed were set, and the first row
        must hold the inputs the units integrate with over the first step, as every later row
        holds those of the step it ends. A Model Exchange unit's discrete inputs are left to its
        first step, where a change is an event (with its rows)."""
        order = [self._by_name[name] for name in self.system.order if name in self._by_name]
        order += [unit for unit in self.units if all(unit is not known for known in order)]
        for unit in order:
            if hasattr(unit, "_discrete_inputs"):
                Unit.pull(unit)  # the continuous inputs; setting a discrete one is an event
            else:
                unit.pull()
            unit.fetch()

    def _can_roll_back(self) -> bool:
        lacking = [u.name for u in self.units if not u.can_save_state]
        if lacking:
            self.warn(f"adaptive step needs fmi2GetFMUstate/fmi2SetFMUstate, which {', '.join(lacking)} "
                      f"cannot do: running with the fixed step {self.step:g} s")
        return not lacking

    # --- stepping -----------------------------------------------------------------------------
    def ordered_units(self) -> List[Unit]:
        """Units in stepping order (Gauss-Seidel order, or scenario order for Jacobi)."""
        if self.algorithm == "gauss-seidel":
            return [self._by_name[name] for name in self.system.order]
        return list(self.units)

    def stepping_blocks(self) -> List[Stepper]:
        """:meth:`ordered_units`, each algebraic loop's units replaced by their :class:`LoopBlock`."""
        block_of = {unit.name: block for block in self.loops for unit in block.units}
        blocks: List[Stepper] = []
        for unit in self.ordered_units():
            block = block_of.get(unit.name, unit)
            if not any(b is block for b in blocks):
                blocks.append(block)
        return blocks

    def step_all(self, units: Sequence[Stepper], t: float, step: float) -> None:
        """One communication step of ``units`` (units or loop blocks) from ``t``, all the same step size."""
        self._mark_step_start(t)
        if self.algorithm == "gauss-seidel":
            for unit in units:
                unit.pull()
                unit.do_step(t, step)
                unit.fetch()
        else:
            for unit in units:
                unit.pull()
            for unit in units:
                unit.do_step(t, step)
            for unit in units:
                unit.fetch()

    def _run_fixed(self) -> None:
        self.begin_fixed_steps()
        self.advance(self._fixed_grid.n_steps)

    def begin_fixed_steps(self) -> None:
        """Lay out the fixed-step loop from start to stop (after :meth:`open`); :meth:`advance`
        takes its steps. :meth:`run` does both; a caller that steps a run piece by piece (a
        scenario exported as one FMU) calls them itself."""
        start, stop, h = self.start, self.stop, self.step
        n_steps = grid_steps(start, stop, h)
        ordered = self.stepping_blocks()
        # on an exact grid every step is m * h (bit for bit what a plain loop passes to doStep)
        last = n_steps + 1 if abs(start + n_steps * h - stop) <= 1e-9 * h else n_steps
        groups: List[int] = []
        if self.threads > 1:  # independent units grouped to step at once (parallel.py)
            actions, groups = group_actions(ordered, self.algorithm, self.system.links)
        elif self.algorithm == "gauss-seidel":
            actions = [(u, action, u.step_multiple) for u in ordered for action in (PULL, STEP, FETCH)]
        else:
            actions = [(u, action, u.step_multiple) for action in (PULL, STEP, FETCH) for u in ordered]
        self._groups = (actions, groups) if any(groups) else None
        native, live, most = None, self.live, _C_MAX_STEPS
        if self.native and (live is None or live.paced_in_c()):
            # a live source's unit has nothing to step: the C loop leaves it out (its values reach
            # the bus when it is sampled between the C loop's runs)
            stepped = [u for u in ordered if getattr(u, "interface", None) != "LIVE"]
            if NativeLoop.fits(stepped, self.sampler):
                # room for a call's rows, at most _C_ROWS_BYTES (a call with more rows ends early: ROWS_FULL)
                rows = min(_C_MAX_STEPS, n_steps + 1, max(64, _C_ROWS_BYTES // (8 * (len(self.sampler.row) + 1))))
                kept = [(a, g) for a, g in zip(actions, groups or [0] * len(actions))
                        if getattr(a[0], "interface", None) != "LIVE"]
                arguments = ([a for a, _ in kept], self.sampler, start, h, stop, n_steps, last, self.every,
                             rows, [g for _, g in kept] if groups else (), self.threads)
                # a run on a kept wiring (a study's next case) takes the C loop of the run before,
                # renewed, when it is laid out alike (not one stepping on threads, nor a paced one)
                wiring = self._wiring if self.threads <= 1 and live is None else None
                key = NativeLoop.key_of(*arguments) if wiring is not None else None
                try:
                    if wiring is not None and wiring.native is not None and wiring.native.key == key:
                        native = self._native = wiring.native
                        native.renew(arguments[0])
                    else:
                        native = self._native = NativeLoop(*arguments)
                        if wiring is not None:
                            native.key, wiring.native = key, native
                    if self._others:
                        native.keep_step_start()
                except BuildError as exc:  # no compiler and no prebuilt loop: the same steps in Python
                    self.warn(f"stepping in Python: {exc}")
        if native is not None:
            if type(self.writer) is CsvWriter:
                # the C loop's blocks become text on a thread of their own while it steps on
                # (it releases the GIL for that)
                self.writer = BackgroundRows(self.writer)
                native.release_gil()
        self._streamed = False
        if native is not None and live is not None:
            native.pace(live.pacer, live.clock_slots(), live.read_in_c())
            live.pacer.restart()
            most = live.points_between_samples()
            # nothing sampled between points: the whole run in one call, its rows taken meanwhile
            # on this thread: a hand-back to Python between two points costs milliseconds
            self._streamed = most > 1
            most = n_steps if self._streamed else most
        self._fixed_actions, self._fixed_native = actions, native
        self._fixed_grid = _FixedGrid(start, stop, h, n_steps, last)
        # steps per call of the C loop: it grows while a call is short (see _C_STEPS)
        self._fixed_chunk, self._fixed_most = min(_C_STEPS if live is None else most, most), most

    def advance(self, k_end: int) -> None:
        """Take the fixed steps of :meth:`begin_fixed_steps` until :attr:`steps` is ``k_end``."""
        actions, native, fixed = self._fixed_actions, self._fixed_native, self._fixed_grid
        n_steps = min(k_end, fixed.n_steps)
        stop_signals, progress, live = self.stop_signals, self.progress, self.live
        k, chunk, most = self.steps, self._fixed_chunk, self._fixed_most
        background = isinstance(self.writer, BackgroundRows)
        while k < n_steps:
            if stop_signals.received:
                raise KeyboardInterrupt
            if native is not None and native.ready():
                begin, k_begin = _time.perf_counter(), k
                # unpaced, the C loop itself returns after _C_RETURN_SECONDS (every step it takes
                # between hand-backs to Python saves one)
                unpaced = live is None and not self._streamed
                end = n_steps if unpaced else min(n_steps, k + chunk)
                native.return_by(_time.monotonic() + _C_RETURN_SECONDS if unpaced else 0.0)
                sink = self.writer.c_sink() if background and unpaced else None
                native.hand_rows_to(sink, _C_SINK_ROWS, self.check_finite)
                if background and sink is None and end == n_steps and n_steps - k > 4 * _C_STEPS \
                        and not self._streamed:
                    # the last rows become text after the stepping: a short last call leaves few
                    end = n_steps - max(_C_STEPS, (n_steps - k) // 8)
                try:
                    k = self._steps_in_c(native, fixed, k, end)
                finally:  # the plan is left as others run it (a system FMU's C step)
                    native.return_by(0.0)
                    native.hand_rows_to(None)
                spent = _time.perf_counter() - begin
                if chunk < most and spent < _C_SECONDS:
                    fill = int((k - k_begin) * _C_SECONDS / max(spent, 1e-9))
                    chunk = self._fixed_chunk = min(max(2 * chunk, min(fill, _C_GROWTH * chunk)), most)
                progress.update(self.time)
            else:
                self._step_in_python(actions, fixed, k)
                if k & 63 == 0:
                    progress.update(self.time)
                k += 1
        if background:
            self.writer.drain()  # the stepping ends with its rows written

    def _step_pool(self) -> StepPool:
        if self._pool is None:
            self._pool = StepPool(self.threads)
        return self._pool

    def _step_in_python(self, actions: Sequence[Tuple[Any, str, int]], grid: "_FixedGrid", k: int,
                        first: int = 0, held: Optional[Tuple[bool, int]] = None) -> None:
        """Step ``k`` of the fixed grid from action ``first`` on (earlier ones done), and its row;
        the step's event rows are held (from ``held``, a :meth:`hold_events` mark, when the step
        began elsewhere) and written in time order before it: units step one after the other,
        and a later one's event may come earlier in the step."""
        held = self.hold_events() if held is None else held
        t = self.time = grid.start + k * grid.h
        if first == 0:
            self._mark_step_start(t)
        n_steps, last, h = grid.n_steps, grid.last, grid.h
        self.step_end = grid.start + (k + 1) * h if k + 1 < n_steps else grid.stop
        groups = self._groups[1] if self._groups is not None and self._groups[0] is actions else None
        i = first
        while i < len(actions):
            unit, action, m = actions[i]
            group = groups[i] if groups else 0
            if group and (i == 0 or groups[i - 1] != group):  # a group from its start: at once, on the pool
                end = i + 1
                while end < len(actions) and groups[end] == group:
                    end += 1
                due = [(u, n) for u, _, n in actions[i:end] if k % n == 0]
                self._step_pool().step([u for u, _ in due], t,
                                       [n * h if k + n < last else grid.stop - t for _, n in due])
                i = end
                continue
            i += 1
            if k % m:
                continue
            if action == STEP:
                unit.do_step(t, m * h if k + m < last else grid.stop - t)
            elif action == PULL:
                unit.pull()
            else:
                unit.fetch()
        self.release_events(held)
        self.steps = k + 1
        t_next = self.time = self.step_end
        recorded = (k + 1) % self.every == 0 or k + 1 == n_steps
        if self.live is not None:
            self.live.at_point(t_next, self._record if recorded else None)
        elif recorded:
            self._record(t_next)

    def _steps_in_c(self, native: NativeLoop, grid: "_FixedGrid", k: int, k_end: int) -> int:
        """Steps ``k`` ... ``k_end - 1`` in C as far as they go, the step where C stopped (an
        event, a failure, a termination) finished here; returns the next step to take."""
        if self._streamed:
            try:
                why, done, rows = native.run_streamed(k, k_end, self._take_rows,
                                                      lambda: self.stop_signals.received is not None)
            except KeyboardInterrupt:  # the steps taken meanwhile are the run's (their rows recorded)
                done = native.steps_done()
                if done > k:
                    self.steps = done
                    self.time = self.step_end = grid.start + done * grid.h if done < grid.n_steps else grid.stop
                raise
        else:
            why, done, rows = native.run(k, k_end)
        return self.after_c_run(native, grid, k, why, done, rows)

    def _take_rows(self, rows: np.ndarray) -> None:
        """Rows a streamed paced run of the C loop wrote (:meth:`NativeLoop.run_streamed`)."""
        self._record_rows(rows)
        self.progress.update(float(rows[-1, 0]))

    def after_c_run(self, native: NativeLoop, grid: "_FixedGrid", k: int, why: int, done: int, rows: int) -> int:
        """What follows a run of the C loop from step ``k`` that returned ``why``, ``done`` and
        ``rows`` (:meth:`NativeLoop.run`): its rows recorded, the master moved to where it
        stopped and the step where it stopped finished here; returns the next step to take."""
        live = self.live
        if live is not None and done > k:
            t_done = grid.start + done * grid.h if done < grid.n_steps else grid.stop
            live.after_c_points(t_done, why == LIVE)
            if rows and native.rows[rows - 1, 0] == t_done:  # its row shows what the sources gave by then
                native.rows[rows - 1, 1:] = self.sampler.sample()
        if rows:
            if isinstance(self.writer, BackgroundRows):  # the block goes to the text thread as it is
                block = native.rows[:rows]
                if done < grid.n_steps:  # C fills another block next (none after the last step)
                    native.rows = self.writer.spare(native.rows)
                handed, queued = native.handed()  # the first rows went to its thread of C already
                if handed:
                    self.writer.handed(block[:handed], queued)
                    self.recorded_until = float(block[handed - 1, 0])
                if handed < rows:
                    self._record_rows(block[handed:], hand_over=True)
            else:
                self._record_rows(native.rows[:rows])
        if done > k:
            self.steps = done
            self.time = self.step_end = grid.start + done * grid.h if done < grid.n_steps else grid.stop
        if why == LIVE and (done % self.every == 0 or done == grid.n_steps):
            self._record(self.time)  # the point C handed back at: its row once the sources are sampled
        if live is not None and live.pacer.failure is not None:
            raise live.pacer.failure
        if why in (RAN, ROWS_FULL, BEHIND, LIVE):
            self._check_bus(self.time)  # the rows held the recorded variables, this the connected ones
            return done
        # step `done` stopped inside: the state the Python loop would have there
        t = self.time = grid.start + done * grid.h
        if native.step_start is not None:
            self._step_start = native.step_start[1:].copy()
        self.step_end = grid.start + (done + 1) * grid.h if done + 1 < grid.n_steps else grid.stop
        unit, action, index, function = native.stopped_at()
        plan = native.plan
        if why == CLOCK_INSIDE:  # a Clock ticks inside the unit's step: Python takes the step from there
            self._step_in_python(native.actions, grid, done, index, self.hold_events())
            return done + 1
        if why == STEP_RETURNED:  # an FMI 3.0 fmi3DoStep with an event, an early return or a termination
            _, _, m = native.actions[index]
            op = native.stopped_op()
            held = self.hold_events()
            unit.finish_step(t, m * grid.h if done + m < grid.last else grid.stop - t, op.step_status, op.flags,
                             op.last_time)
            self._step_in_python(native.actions, grid, done, index + 1, held)
            return done + 1
        if why in (STEP_EVENT, STATE_EVENT):
            held = self.hold_events()
            if why == STEP_EVENT:
                unit.finish_step_event(plan.time)
            else:
                try:
                    native.locate(unit)
                except RungeKuttaError as exc:
                    raise FmuFailure(f"{unit.name}: {exc}") from None
                except fmpy.fmi1.FMICallException as exc:
                    raise unit.failure(exc) from None
                _, _, m = native.actions[index]
                unit.finish_state_event(t, m * grid.h if done + m < grid.last else grid.stop - t)
            self._step_in_python(native.actions, grid, done, index + 1, held)
            return done + 1
        if why == TERMINATED:
            raise Terminated(unit.name, plan.time)
        if why == UNSETTLED:
            from .fmi3_units import unsettled  # here: a run of FMI 2.0 units never loads the FMI 3.0 ones

            raise FmuFailure(unsettled(unit.name, plan.time))
        if why == RK_FAILED:
            raise FmuFailure(f"{unit.name}: {step_failure(plan.rk_time, plan.status)}")
        exc = fmpy.fmi1.FMICallException(function=function, status=plan.status)
        if function == "fmi2DoStep":  # fmi2Discard may mean the FMU ended the run
            unit.step_failed(exc, t)
        raise unit.failure(exc)

    # --- recording ----------------------------------------------------------------------------
    def _record(self, t: float) -> None:
        self.writer.write(t, self.sampler.sample())
        self.recorded_until = t
        self._check_bus(t)

    def _check_bus(self, t: float) -> None:
        """Stop the run when a Real on the bus (recorded or connected, as of ``t``) is NaN or
        infinite, unless allowed."""
        if self.check_finite:
            bus = self.buses["Real"]
            # x * 0 is NaN for NaN and inf, else 0: one dot product, cheaper than isfinite(bus).all()
            if not math.isfinite(np.dot(bus, self._zeros)):
                self._not_finite(t, [self._real_names[i] for i in np.flatnonzero(~np.isfinite(bus))],
                                 bus[~np.isfinite(bus)])

    def _record_rows(self, rows: np.ndarray, hand_over: bool = False) -> None:
        """Rows ``time, values...`` recorded at once (a writer without ``write_rows`` gets them one by one);
        ``hand_over``: the rows are the writer's (a :class:`BackgroundRows` takes them without a copy)."""
        bad = None
        # every value of the block finite (the other columns hold integers): its sum is, but for
        # an overflow, which the row by row look below then clears (a paced run's C loop hands
        # its block back between two points: the look row by row took 0.1-0.3 ms there)
        if self.check_finite and len(self._real_columns) and not math.isfinite(np.add.reduce(rows, axis=None)):
            finite = np.isfinite(rows[:, 1 + self._real_columns]).all(axis=1)
            if not finite.all():
                bad = int(np.argmin(finite))
                rows = rows[:bad + 1]  # rows up to the first with a NaN, that one included
        if hand_over:
            self.writer.take_rows(rows)
        else:
            write_rows_to(self.writer, rows)
        self.recorded_until = float(rows[-1, 0])
        if bad is not None:
            self._check_row(float(rows[-1, 0]), rows[-1, 1:])

    def _check_row(self, t: float, row: np.ndarray) -> None:
        """Stop the run when a Real of the recorded ``row`` is NaN or infinite (unless allowed)."""
        if not self.check_finite or not len(self._real_columns):
            return
        values = np.asarray(row[self._real_columns], dtype=float)
        bad = ~np.isfinite(values)
        if bad.any():
            recorded = self.system.recorded
            self._not_finite(t, [recorded[i].ref for i in self._real_columns[bad]], values[bad])

    def _not_finite(self, t: float, names: Sequence[str], values: np.ndarray) -> None:
        """Raise the :class:`SimulationError` for the variables ``names`` that are NaN/inf at ``t``,
        naming first the one of the unit earliest in the stepping order: in a Gauss-Seidel step a
        NaN spreads to the units after its source, in a Jacobi step to none yet."""
        rank = {unit.name: i for i, unit in enumerate(self.ordered_units())}
        order = sorted(range(len(names)), key=lambda i: rank.get(names[i].split(".", 1)[0], len(rank)))
        first = order[0]
        value = values[first]
        what = "NaN" if np.isnan(value) else f"{'-' if value < 0 else ''}infinite"
        more = len(names) - 1
        others = f" (and {more} other variable{'s' * (more > 1)})" if more else ""
        flush = getattr(self.writer, "flush", None)
        if flush is not None:
            flush()
        raise SimulationError(f"{names[first]} is {what} at t = {t:.9g} s{others}; the rows up to there are in "
                              f"{self._kept_after_failure()} (to record it and go on: --allow-nan, or allow_nan: "
                              "true under master:)")

    def record_step(self, t: float) -> None:
        """Record the row at the end of a step that reached ``t``, and show progress (and stop
        here if a stop signal came)."""
        self._record(t)
        self.progress.update(t)
        if self.stop_signals.received:
            raise KeyboardInterrupt

    def _mark_step_start(self, t: float) -> None:
        """A step begins at ``t``: keep the recorded values its event rows show of the units
        other than the event's (only when some unit can have events and others are recorded)."""
        if self._others:
            self._step_start = self.sampler.sample().copy()

    def _on_event(self, unit: Unit, t: float, after: bool) -> None:
        # an event within round-off of the step's start or end (a unit's own t + h, or an FMU's
        # accumulated event time, can be an ulp off the grid's start + k h) is recorded there
        for grid_time in (self.time, self.step_end):
            if abs(t - grid_time) <= instant_margin(t):
                t = grid_time
        if after and t == self.step_end:
            # an event at the end of the step: the step's own row shows the values after it
            self.events += self._deferred is None
            if self._deferred is not None:
                self._deferred.append((t, None, True))
            return
        unit.fetch()
        row = self.sampler.sample().copy()
        others = self._others.get(unit.name)
        if others is not None and self._step_start is not None and t != self.step_end:
            # in a step the others have no values at t but those of its start (in a Gauss-Seidel
            # step the units stepped earlier already hold the step's end on the bus: later than t)
            row[others] = self._step_start[others]
        if self._deferred is not None:
            self._deferred.append((t, row, after))
            return
        self.events += after
        self._write_row(t, row)

    def _write_row(self, t: float, row: np.ndarray) -> None:
        self.writer.write(t, row)
        self.recorded_until = t
        self._check_row(t, row)

    def defer_events(self) -> None:
        """Hold event rows back until :meth:`commit_events` (a trial step may be rolled back)."""
        self._deferred = []

    def commit_events(self) -> None:
        """Write the held event rows, in time order (a unit's rows stay in their order)."""
        for t, row, after in sorted(self._deferred or (), key=lambda held: held[0]):
            self.events += after
            if row is not None:
                self._write_row(t, row)
        self._deferred = None

    def drop_events(self) -> None:
        """Forget the held event rows (their step was rolled back); keep deferring."""
        if self._deferred is not None:
            self._deferred = []

    def hold_events(self) -> Tuple[bool, int]:
        """Hold event rows back from here (a loop's step may be redone); a mark for
        :meth:`rewind_events` and :meth:`release_events`."""
        started = self._deferred is None
        if started:
            self.defer_events()
        return started, len(self._deferred)

    def rewind_events(self, mark: Tuple[bool, int]) -> None:
        """Forget the event rows held since ``mark``."""
        del self._deferred[mark[1]:]

    def release_events(self, mark: Tuple[bool, int]) -> None:
        """Stop holding if ``mark`` started it: write the rows held."""
        if mark[0]:
            self.commit_events()

    def loop_statistics(self) -> LoopStatistics:
        """Solves and evaluations of every algebraic loop so far (initialization included)."""
        total = LoopStatistics()
        for block in self.loops:
            total.add(block.statistics)
        if self.initial_loops is not None:
            total.add(self.initial_loops.statistics)
        return total

    # --- rollback helpers (used by the adaptive loop) -----------------------------------------
    def save(self) -> Tuple[list, Dict[str, np.ndarray]]:
        """Snapshot of every unit and of the buses."""
        return [u.save_state() for u in self.units], {k: b.copy() for k, b in self.buses.items()}

    def restore(self, snapshot: Tuple[list, Dict[str, np.ndarray]]) -> None:
        """Return every unit and the buses to ``snapshot`` (which stays valid)."""
        states, buses = snapshot
        for unit, state in zip(self.units, states):
            unit.restore_state(state)
        for kind, values in buses.items():
            self.buses[kind][:] = values

    def release(self, snapshot: Tuple[list, Dict[str, np.ndarray]]) -> None:
        """Free the FMU states of ``snapshot``."""
        for unit, state in zip(self.units, snapshot[0]):
            unit.free_state(state)
