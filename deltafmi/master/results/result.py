"""A run's results in memory: :class:`Result` (what :func:`deltafmi.simulate` returns), the
writer that collects it while the master runs, and :func:`read_result` for result files.

A :class:`Result` holds the ``time`` column and one column per recorded variable, with units
where they are known (from the FMUs' modelDescription; a ``.parquet`` or ``.mat`` file carries
them, a ``.csv`` file does not). Columns keep their FMI type: Real as float, Integer and
Enumeration as int64, Boolean as bool, String as str objects.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence

import numpy as np

from deltafmi.errors import BadInput, did_you_mean

from ..scenario.modelinfo import split_element
from .writers import KeptRows, typed_column, write_rows_to, writer_for

__all__ = ["Result", "ResultRecorder", "plot_result", "read_result", "result_figure"]


class Result:
    """Time series of one run: ``r.time``, ``r["plant.z[3]"]``, ``r.units["plant.z[3]"]``.

    ``r[name]`` is a NumPy array: one variable's column, or for an array variable's name
    without index (``r["plant.z"]``) a rows x elements array of ``plant.z[1]``, ``plant.z[2]``, ...
    in index order. ``r.names`` lists the recorded variables (``time`` not included),
    ``r.units`` maps each of them and ``time`` to its unit (``""``: the FMU declares none; a
    result read from a CSV without its ``.units.json`` file has an empty ``units``), ``r.summary`` is the run's
    :class:`~deltafmi.master.results.progress.Summary` (None for a result read from a file).
    An event shows as two rows with the same time (values just before and just after it).
    """

    def __init__(self, columns: Mapping[str, np.ndarray], units: Optional[Mapping[str, str]] = None,
                 summary: Any = None, kinds: Optional[Mapping[str, str]] = None) -> None:
        """``columns``: ``time`` first or anywhere, then every variable (equal lengths)."""
        if "time" not in columns:
            raise ValueError("a result needs a 'time' column")
        self._columns: Dict[str, np.ndarray] = {"time": np.asarray(columns["time"], dtype=float)}
        for name, values in columns.items():
            if name != "time":
                self._columns[name] = np.asarray(values)
        self.units: Dict[str, str] = dict(units or {})
        self.kinds: Dict[str, str] = dict(kinds or {})
        self.summary = summary

    # --- access -------------------------------------------------------------------------------
    @property
    def time(self) -> np.ndarray:
        """Time of every row [s]."""
        return self._columns["time"]

    @property
    def names(self) -> List[str]:
        """The recorded variables, in recording order (``time`` not included)."""
        return [name for name in self._columns if name != "time"]

    def __getitem__(self, name: str) -> np.ndarray:
        column = self._columns.get(name)
        if column is not None:
            return column
        elements = self.elements(name)
        if elements:
            return np.column_stack([self._columns[e] for e in elements])
        raise KeyError(f"no variable '{name}' in the result{did_you_mean(name, self._columns)}")

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and (name in self._columns or bool(self.elements(name)))

    def __iter__(self) -> Iterator[str]:
        return iter(self._columns)

    def __len__(self) -> int:
        """The number of rows."""
        return len(self.time)

    def __repr__(self) -> str:
        span = f", t = {self.time[0]:g} .. {self.time[-1]:g} s" if len(self) else ""
        return f"<Result: {len(self)} rows x {len(self.names)} variables{span}>"

    def elements(self, name: str) -> List[str]:
        """The recorded elements of the array ``name``: ``plant.z`` -> ``plant.z[1]``,
        ``plant.z[2]``, ... in index order (``[]`` when none is recorded)."""
        found = []
        for column in self._columns:
            element = split_element(column)
            if element and element[0] == name:
                found.append((element[1], column))
        return [column for _, column in sorted(found)]

    def match(self, pattern: str) -> List[str]:
        """Recorded names matching ``pattern`` (``*`` and ``?`` globs, ``[i:j]`` index ranges:
        the patterns of a scenario's ``outputs``), in recording order."""
        from ..scenario.resolve import pattern_regex

        regex = pattern_regex(pattern)
        return [name for name in self.names if regex.match(name)]

    def unit(self, name: str) -> str:
        """The unit of ``name`` (or of the elements of an array name); ``""`` when unknown."""
        if name in self.units:
            return self.units[name]
        elements = self.elements(name)
        return self.units.get(elements[0], "") if elements else ""

    # --- conversions --------------------------------------------------------------------------
    def to_pandas(self) -> Any:
        """A ``pandas.DataFrame`` indexed by ``time`` (an event repeats its time), one column per
        variable; ``df.attrs["units"]`` maps names to units. Needs pandas (``pip install pandas``)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Result.to_pandas() needs pandas, which is not installed: "
                              "pip install pandas") from None
        frame = pd.DataFrame({name: self._columns[name] for name in self.names},
                             index=pd.Index(self.time, name="time"))
        frame.attrs["units"] = dict(self.units)
        return frame

    def plot(self, signals: Sequence[str], output: str | Path, **options: Any) -> Path:
        """Draw ``signals`` into ``output`` as :func:`plot_result` does (``deltafmi plot``): names,
        patterns, differences ``"plant.z - trajectory.r"``, units."""
        return plot_result(self, signals, output, **options)

    def save(self, path: str | Path) -> Path:
        """Write the result as ``.csv``, ``.parquet`` (units in field metadata) or ``.mat``, by
        the extension (:class:`~deltafmi.errors.BadInput` for another); returns the path."""
        path = Path(path)
        writer_class = writer_for(path)
        names = self.names
        kinds = [self.kinds.get(name, _kind_of(self._columns[name])) for name in names]
        # Booleans as 0/1, as a run records them (the master's buses hold FMI's fmi2Boolean)
        columns = [self._columns[n].astype(np.int64) if kind == "Boolean" else self._columns[n]
                   for n, kind in zip(names, kinds)]
        writer = writer_class(path, names, kinds=kinds, units=[self.units.get(n, "") for n in names])
        try:
            if "String" in kinds:
                for i, t in enumerate(self.time):
                    writer.write(float(t), np.array([column[i] for column in columns], dtype=object))
            elif len(self):
                writer.write_rows(np.column_stack([self.time, *[column.astype(float) for column in columns]]))
        finally:
            writer.close()
        return path


def _kind_of(column: np.ndarray) -> str:
    if column.dtype == bool:
        return "Boolean"
    if np.issubdtype(column.dtype, np.integer):
        return "Integer"
    if column.dtype == object or np.issubdtype(column.dtype, np.str_):
        return "String"
    return "Real"


class ResultRecorder:
    """A result writer for the master (``writer_class``) that keeps every row in memory and
    passes each row on to a file writer too when given one; :meth:`result` builds the
    :class:`Result`. ``after_rows()`` is called after rows are written (between steps, outside
    every FMU call)."""

    def __init__(self, names: Sequence[str], kinds: Sequence[str], units: Sequence[str],
                 file_writer: Any = None, chunk: int = 4096,
                 after_rows: Optional[Callable[[], None]] = None) -> None:
        self.names, self.kinds, self.units = list(names), list(kinds), list(units)
        self.file_writer = file_writer
        self.after_rows = after_rows
        self._rows = KeptRows(len(self.names) + 1, self.kinds, chunk)

    @property
    def rows_written(self) -> int:
        """Rows kept so far."""
        return self._rows.rows_written

    def write(self, time: float, values: np.ndarray) -> None:
        """Keep one row (and pass it on)."""
        self._rows.write(time, values)
        if self.file_writer is not None:
            self.file_writer.write(time, values)
        if self.after_rows is not None:
            self.after_rows()

    def write_rows(self, rows: np.ndarray) -> None:
        """Keep rows ``time, values...`` (a 2-D array), and pass them on."""
        self._rows.write_rows(rows)
        if self.file_writer is not None:
            write_rows_to(self.file_writer, rows)
        if self.after_rows is not None:
            self.after_rows()

    def flush(self) -> None:
        """Flush the file writer (the rows in memory need none)."""
        self._rows.flush()
        if self.file_writer is not None:
            self.file_writer.flush()

    def fail(self) -> Optional[Path]:
        """The run failed: the file writer keeps its rows under the failed name (returned; None
        without a file writer, or one that cannot)."""
        fail = getattr(self.file_writer, "fail", None)
        return fail() if fail is not None else None

    def close(self) -> None:
        """Close the file writer (idempotent)."""
        self._rows.flush()
        if self.file_writer is not None:
            self.file_writer.close()

    def result(self, summary: Any = None) -> Result:
        """Every row kept so far as a :class:`Result`."""
        data = self._rows.data()
        columns = {"time": data[:, 0].astype(float)}
        for i, (name, kind) in enumerate(zip(self.names, self.kinds), start=1):
            columns[name] = typed_column(data[:, i], kind)
            if kind == "String":
                columns[name] = columns[name].astype(object)
        units = {"time": "s", **dict(zip(self.names, self.units))}
        return Result(columns, units, summary, dict(zip(self.names, self.kinds)))


def read_result(path: str | Path) -> Result:
    """A result file written by ``deltafmi run -o`` (or :meth:`Result.save`) as a :class:`Result`:
    ``.csv`` (its units from the ``.units.json`` file beside it, when there is one), ``.parquet``
    and ``.mat`` (with units). Raises
    :class:`~deltafmi.errors.BadInput` naming the file when it cannot be read."""
    path = Path(path)
    suffix = path.suffix.lower()
    if not path.is_file():
        raise BadInput(f"result file '{path}' not found")
    if path.stat().st_size == 0:
        raise BadInput(f"cannot read '{path}' as a result file: it is empty (0 bytes)")
    try:
        if suffix == ".parquet":
            return _read_parquet(path)
        if suffix == ".mat":
            return _read_mat(path)
        from .csv_file import columns, read_units
        return Result(columns(path), read_units(path) or None)
    except BadInput:
        raise
    except UnicodeDecodeError as exc:
        raise BadInput(f"cannot read '{path}' as a result file: not text (byte {exc.start} is not UTF-8)") from None
    except (ValueError, OSError, KeyError, StopIteration) as exc:
        raise BadInput(f"cannot read '{path}' as a result file: {exc or type(exc).__name__}") from None
    except Exception as exc:  # pyarrow's and scipy's own errors for files that are not theirs
        raise BadInput(f"cannot read '{path}' as a result file: {exc}") from None


def _read_parquet(path: Path) -> Result:
    import pyarrow.parquet as pq

    table = pq.read_table(str(path))
    columns, units = {}, {}
    for field in table.schema:
        column = table.column(field.name).to_numpy()
        columns[field.name] = column.astype(object) if column.dtype == object else column
        metadata = field.metadata or {}
        units[field.name] = metadata.get(b"unit", b"").decode()
    return Result(columns, units)


def _read_mat(path: Path) -> Result:
    from scipy.io import loadmat

    content = loadmat(str(path))
    names = [str(np.ravel(n)[0]) if np.size(n) else "" for n in np.ravel(content["names"])]
    variables = [str(np.ravel(v)[0]) for v in np.ravel(content["variables"])]
    units = [str(np.ravel(u)[0]) if np.size(u) else "" for u in np.ravel(content["units"])]
    columns: Dict[str, np.ndarray] = {"time": np.ravel(content["time"]).astype(float)}
    for name, variable in zip(names, variables):
        column = content[variable]
        if column.dtype == object:
            columns[name] = np.array([str(np.ravel(v)[0]) if np.size(v) else "" for v in np.ravel(column)], dtype=object)
        else:
            columns[name] = np.ravel(column)
    return Result(columns, {"time": "s", **dict(zip(names, units))})


def plot_result(result: str | Path | Result, signals: Sequence[str], output: str | Path,
                separate: bool = False, title: str = "", compare: str | Path | Result | None = None) -> Path:
    """Plot ``signals`` of ``result`` (a result file or a :class:`Result`) over time into
    ``output`` (.png, .pdf, .svg, ...: matplotlib's formats); one axis per unit, differences on
    axes of their own (``separate``: one axis per curve). ``compare``: plot ``result - compare``
    for each signal. Raises :class:`~deltafmi.master.results.plot.UnknownSignal` for a signal that
    is not there, :class:`~deltafmi.errors.BadInput` for a figure format matplotlib cannot write or
    a file that is no result or has no rows."""
    from .plot import checked_figure_file, save_figure

    output = checked_figure_file(output)
    return save_figure(result_figure(result, signals, separate, title, compare), output)


def result_figure(result: str | Path | Result, signals: Sequence[str], separate: bool = False, title: str = "",
                  compare: str | Path | Result | None = None) -> Any:
    """The matplotlib ``Figure`` :func:`plot_result` saves (made without pyplot: it leaves the
    caller's backend and figures alone)."""
    from .plot import figure_of

    first = _rows_of(result)
    other = None if compare is None else _rows_of(compare)
    return figure_of(first, signals, separate, title, other,
                     (_name(result, "result"), _name(compare, "compared"), _name(compare, "the compared result")))


def _rows_of(result: str | Path | Result) -> Result:
    """``result``, read when a file; BadInput when it has no rows (nothing to draw)."""
    loaded = result if isinstance(result, Result) else read_result(result)
    if not len(loaded):
        raise BadInput(f"{'the result' if isinstance(result, Result) else result} has no rows")
    return loaded


def _name(result: str | Path | Result | None, default: str) -> str:
    return default if result is None or isinstance(result, Result) else Path(result).name
