"""Run one case of a study in this process: the worker side of a sweep.

:class:`CaseTemplate` resolves the study's scenario once (against the FMU files by hash) and
turns each case's values into a :class:`~deltafmi.master.scenario.resolve.System` by swapping start
values, without checking the scenario again. :func:`run_case` runs it through the ordinary
master with FMUs lent by a :class:`~deltafmi.apps.studies.pool.FmuPool` and the rows kept in memory
(:class:`MemoryRecorder`, the same rows the CSV of ``deltafmi run`` gets), computes the metrics
and returns a :class:`CaseResult`. A failure of the case is a result, never an exception.
"""
from __future__ import annotations

import dataclasses
import math
import time as _time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from deltafmi.errors import BadInput, ScenarioError, SimulationError
from deltafmi.master.stepping.master import Master
from deltafmi.master.scenario.resolve import resolve_system
from deltafmi.master.scenario.system import ResolvedComponent, System

from .plan import StudyPlan, with_parameters
from .pool import FmuPool
from .spec import Target

__all__ = ["CaseResult", "CaseTemplate", "FAILED", "MemoryRecorder", "OK", "run_case"]

OK, FAILED = "ok", "failed"


class MemoryRecorder:
    """The master's result writer, keeping the rows in memory (same calls as the CSV writer): one
    array of rows, ``chunk`` at first, whose capacity doubles as it fills (no concatenation at the end)."""

    def __init__(self, path: Path, names: Sequence[str], kinds: Optional[Sequence[str]] = None,
                 chunk: int = 1024, memory: Optional[np.ndarray] = None) -> None:
        """``memory``: an array of rows to fill (an earlier case's, done with: its pages in memory
        already), taken when it has room for ``chunk`` rows of this width and type."""
        self.path = path
        self.names = list(names)
        self.kinds = list(kinds) if kinds is not None else ["Real"] * len(names)
        dtype = np.dtype(object if "String" in self.kinds else float)
        if memory is not None and memory.dtype == dtype and memory.shape[1] == len(self.names) + 1 \
                and len(memory) >= chunk:
            self._rows = memory
        else:
            self._rows = np.empty((chunk, len(self.names) + 1), dtype=dtype)
        self.rows_written = 0

    def _room(self, n: int) -> np.ndarray:
        """The next ``n`` free rows, the array grown (doubled) if needed."""
        end = self.rows_written + n
        if end > len(self._rows):
            grown = np.empty((max(end, 2 * len(self._rows)), self._rows.shape[1]), dtype=self._rows.dtype)
            grown[: self.rows_written] = self._rows[: self.rows_written]
            self._rows = grown
        room = self._rows[self.rows_written:end]
        self.rows_written = end
        return room

    def write(self, time: float, values: np.ndarray) -> None:
        """Keep one row."""
        row = self._room(1)[0]
        row[0] = time
        row[1:] = values

    def write_rows(self, rows: np.ndarray) -> None:
        """Keep a block of rows ``time, values...`` (how the master's C loop hands them over)."""
        self._room(len(rows))[:] = rows

    def flush(self) -> None:
        """Nothing to flush."""

    def close(self) -> None:
        """Nothing to close."""

    def release(self) -> np.ndarray:
        """The rows array, no longer this recorder's (nothing written or read after)."""
        rows, self._rows, self.rows_written = self._rows, self._rows[:0], 0
        return rows

    def columns(self) -> "RecordedColumns":
        """The rows by column: ``time``, then every recorded variable."""
        return RecordedColumns(self._rows[: self.rows_written], self.names, self.kinds)


class RecordedColumns(Mapping[str, np.ndarray]):
    """Recorded rows by column name; a column is copied out at its first use (a study's metrics
    read a few of the many recorded variables): float arrays, ``str`` objects for Strings."""

    def __init__(self, rows: np.ndarray, names: Sequence[str], kinds: Sequence[str]) -> None:
        self._rows = rows
        self._index = {"time": 0, **{name: i + 1 for i, name in enumerate(names)}}
        self._strings = {name for name, kind in zip(names, kinds) if kind == "String"}
        self._copied: Dict[str, np.ndarray] = {}
        self._ordered: Optional[bool] = None  # the times never decrease (see window)
        #: metric signals computed from these rows, shared by the metrics of one signal (see metrics.py)
        self.signals: Dict[Any, np.ndarray] = {}

    def block(self, names: Sequence[str]) -> np.ndarray:
        """Several numeric columns as one rows x columns float array (one gather from the rows)."""
        if self._rows.dtype != object:
            gathered = self._rows[:, [self._index[name] for name in names]]  # column-major
            # numpy reduces a row of fewer than 8 elements one element after the other whatever
            # the layout, and a longer one pairwise in C order: C order there, as stacking gives
            return gathered if len(names) < 8 else np.ascontiguousarray(gathered)
        return np.column_stack([self[name] for name in names])

    def view(self, name: str) -> np.ndarray:
        """A numeric column as a view of the rows (no copy; strided: do not write to it)."""
        if self._rows.dtype == object:
            return self[name]
        return self._rows[:, self._index[name]]

    def window(self, start: Optional[float], stop: Optional[float]) -> Optional[slice]:
        """The rows with ``start <= time <= stop`` (None: no bound) as a slice, when the times
        never decrease (a master's rows: an event's two rows share their time), else None."""
        if self._ordered is None:
            time = self["time"]
            self._ordered = bool(np.all(time[1:] >= time[:-1]))
        if not self._ordered:
            return None
        time = self["time"]
        first = 0 if start is None else int(np.searchsorted(time, start, side="left"))
        end = len(time) if stop is None else int(np.searchsorted(time, stop, side="right"))
        return slice(first, max(first, end))

    def __getitem__(self, name: str) -> np.ndarray:
        column = self._copied.get(name)
        if column is None:
            column = self._rows[:, self._index[name]]
            column = self._copied[name] = column.copy() if name in self._strings else column.astype(float)
        return column

    def __iter__(self) -> Iterator[str]:
        return iter(self._index)

    def __len__(self) -> int:
        return len(self._index)


@dataclass
class CaseResult:
    """What a case returns to the client."""

    case: int
    values: Dict[str, Any]
    metrics: Dict[str, float]
    status: str
    error: str = ""
    wall_time: float = 0.0
    #: seconds before the first step: lending or loading, reset or instantiation, initialization
    setup_time: float = 0.0
    #: seconds of the stepping loop (the simulation itself)
    sim_time: float = 0.0
    #: the recorded signals (``time`` first), when the study keeps time series
    timeseries: Optional[Dict[str, np.ndarray]] = field(default=None, repr=False)
    #: where it ran (a Dask worker address, or "local")
    worker: str = ""


class CaseTemplate:
    """The study's scenario resolved once; :meth:`system` makes any case's system from it."""

    def __init__(self, plan: StudyPlan, fmu_files: Mapping[str, Path]) -> None:
        self.plan = plan
        #: the most rows a case of it recorded so far (room made for as many in the next)
        self.rows = 0
        #: the master's wiring of the cases, kept for the next case on the same pooled FMUs
        self.wirings: Dict[Any, Any] = {}
        #: rows arrays of cases done (their values copied out), for later cases to fill
        self.spare_rows: List[np.ndarray] = []
        by_component = dict(plan.fmus)
        components = tuple(dataclasses.replace(c, fmu=str(fmu_files[by_component[c.name]]), source=None)
                           for c in plan.scenario.components)
        scenario = dataclasses.replace(plan.scenario, components=components)
        probe = [(Target(name, None), value) for name, value in plan.probe]
        self.base = resolve_system(with_parameters(scenario, probe))
        # the probe's start values come last in each component, in target order: one slot each
        self.slots: Dict[str, Tuple[int, int]] = {}
        index = {c.name: i for i, c in enumerate(self.base.components)}
        seen: Dict[str, int] = {}
        for target, _ in probe:
            component = self.base.components[index[target.component]]
            mine = sum(1 for t, _ in probe if t.component == target.component)
            position = len(component.start_values) - mine + seen.get(target.component, 0)
            seen[target.component] = seen.get(target.component, 0) + 1
            self.slots[target.name] = (index[target.component], position)

    def system(self, values: Mapping[str, Any]) -> Tuple[System, Optional[float]]:
        """The system of a case and its stop time (None: the scenario's)."""
        components: List[ResolvedComponent] = list(self.base.components)
        copied = set()
        experiment = self.base.scenario.experiment
        stop = None
        for name, value in values.items():
            if name == "experiment.stop":
                stop = float(value)
                continue
            if name == "experiment.step":
                experiment = dataclasses.replace(experiment, step=float(value))
                continue
            i, position = self.slots[name]
            if i not in copied:
                components[i] = dataclasses.replace(components[i], start_values=list(components[i].start_values))
                copied.add(i)
            port = components[i].start_values[position][0]
            components[i].start_values[position] = (port, _converted(components[i], port.name, value))
        scenario = self.base.scenario
        if experiment is not scenario.experiment:
            scenario = dataclasses.replace(scenario, experiment=experiment)
        return dataclasses.replace(self.base, components=components, scenario=scenario), stop


def _converted(component: ResolvedComponent, name: str, value: Any) -> Any:
    """An Enumeration item name as its value (the scenario checker does the same)."""
    if isinstance(value, str):
        enumeration = component.info.enumeration(name)
        if enumeration is not None:
            return enumeration[1][value]
    return value


def run_case(template: CaseTemplate, pool: FmuPool, case: int, values: Mapping[str, Any],
             keep_timeseries: bool = False, worker: str = "local") -> CaseResult:
    """Run one case with FMUs from ``pool``; metrics are NaN when it failed."""
    wall = _time.perf_counter()
    lent: List[Any] = []
    recorders: List[MemoryRecorder] = []

    def lend(component: ResolvedComponent) -> Any:
        lent.append(pool.lend(component))
        return lent[-1]

    def recorder(path: Path, names: Sequence[str], kinds: Optional[Sequence[str]] = None) -> MemoryRecorder:
        # room for as many rows as the longest case so far: no growing (and copying) while it runs
        try:
            memory = template.spare_rows.pop()
        except IndexError:  # none (the first case, or another thread's case has it)
            memory = None
        recorders.append(MemoryRecorder(path, names, kinds, chunk=max(1024, template.rows), memory=memory))
        return recorders[-1]

    status, error, setup, stepping = OK, "", 0.0, 0.0
    metrics = {m.name: math.nan for m in template.plan.metrics}
    try:
        system, stop = template.system(values)
        summary = Master(system, result=Path(f"case-{case}"), stop=stop, fmus=lend, writer_class=recorder,
                         wirings=template.wirings).run()
        setup, stepping = summary.setup_time, summary.wall_time - summary.setup_time
    except (SimulationError, BadInput, ScenarioError) as exc:
        # the rows up to the failure are in memory, not in the file the master names
        status, error = FAILED, exc.format_message().replace(f" (results up to the failure in case-{case})", "")
        pool.discard(lent)
    except Exception as exc:  # noqa: BLE001 - anything else is this case's failure, not the study's
        status, error = FAILED, f"{type(exc).__name__}: {exc} ({_where(exc)})"
        pool.discard(lent)
    columns = recorders[0].columns() if recorders else None
    if recorders:
        template.rows = max(template.rows, recorders[0].rows_written)
    if status == OK and columns is not None:
        for metric in template.plan.metrics:
            try:
                metrics[metric.name] = metric.value(columns)
            except Exception as exc:  # noqa: BLE001
                status, error = FAILED, f"metric '{metric.name}': {type(exc).__name__}: {exc}"
    timeseries = dict(columns) if keep_timeseries and columns is not None else None  # copies
    if recorders and len(template.spare_rows) < 2:  # nothing of the case points into its rows now
        template.spare_rows.append(recorders[0].release())
    return CaseResult(case, dict(values), metrics, status, error, _time.perf_counter() - wall, setup, stepping,
                      timeseries, worker)


def _where(exc: BaseException) -> str:
    frames = traceback.extract_tb(exc.__traceback__)
    last = frames[-1] if frames else None
    return f"{Path(last.filename).name}:{last.lineno}" if last else "unknown place"
