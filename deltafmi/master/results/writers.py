"""Result writers chosen by the result file's extension: ``.csv``, ``.parquet`` and ``.mat``.

Every writer takes ``(path, names, kinds=..., units=...)`` and offers ``write(time, values)``,
``write_rows(rows)``, ``flush()``, ``close()`` and ``rows_written``, like
:class:`~deltafmi.master.results.csv_file.CsvWriter`.

- ``.csv``: streamed text (see :mod:`.csv_file`); its units in ``r.csv.units.json`` beside it.
- ``.parquet``: one column per variable, ``time`` first; each field's metadata holds its unit
  under the key ``unit`` (``s`` for time, ``""`` where the modelDescription declares none).
  Rows go out as row groups while the run goes on (whenever 8192 rows are queued or half a
  second has passed); the file's footer is written by :meth:`ParquetWriter.close`, which the
  master calls after a failure, Ctrl-C or SIGTERM too. A process killed outright (SIGKILL,
  power loss) leaves a file without a footer, which Parquet readers refuse. A full disk does
  not: a reserve of disk space kept next to the file (:class:`_ReservedSink`) takes the row
  group being written and the footer, and the file ends there, readable.
- ``.mat``: MATLAB 5 file (:func:`scipy.io.savemat`), held in memory and written by
  :meth:`MatWriter.close` (at the end, and after a failure or interruption). See
  :func:`matlab_names` for how FMI names become MATLAB names. When it does not fit on the disk
  the partial file is removed.

A write that fails for lack of space raises :class:`~deltafmi.errors.ResultWriteError` (one line:
the file, the rows it holds and their last time); the writer then takes no more rows.

Every writer writes a temporary file beside the result file and moves it into place when it
closes (:mod:`.safe_file`): an earlier result of the same name is replaced only by a readable
file. After ``fail()`` (the run failed) the rows go to the failed name (``r.failed.parquet``).
"""
from __future__ import annotations

import errno
import os
import re
import time as _time
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence

import numpy as np

from deltafmi.errors import BadInput, ResultWriteError

from .csv_file import CsvWriter
from .safe_file import ResultFile

__all__ = ["KeptRows", "MatWriter", "ParquetWriter", "matlab_names", "typed_column", "write_rows_to", "writer_for"]

_FLUSH_SECONDS = 0.5
#: MATLAB's namelengthmax
_MATLAB_NAME_LENGTH = 63
#: the .mat file's own variables, which no recorded variable may take
_MAT_RESERVED = ("time", "names", "variables", "units")
_NO_SPACE = (errno.ENOSPC, errno.EDQUOT)


def _csv(path: Path, names: Sequence[str], kinds: Optional[Sequence[str]] = None,
         units: Optional[Sequence[str]] = None) -> CsvWriter:
    return CsvWriter(path, names, kinds=kinds, units=units)


def writer_for(path: str | Path) -> Callable[..., Any]:
    """The writer class for a result file, by its extension (case-insensitive).

    Raises :class:`BadInput` naming the file and the supported extensions for any other.
    """
    suffix = Path(path).suffix.lower()
    writers: Dict[str, Callable[..., Any]] = {".csv": _csv, ".parquet": ParquetWriter, ".mat": MatWriter}
    if suffix not in writers:
        raise BadInput(f"result file '{path}': unknown format '{suffix or '(no extension)'}'; "
                       f"use {', '.join(writers)}")
    return writers[suffix]


class RowQueue:
    """Rows queued in blocks: floats, or objects when a String variable is recorded."""

    def __init__(self, width: int, kinds: Sequence[str], chunk: int) -> None:
        self.text = "String" in kinds
        self.block = np.empty((chunk, width), dtype=object if self.text else float)
        self.n = 0

    def add(self, time: float, values: np.ndarray) -> bool:
        """Queue one row; True when the block is full."""
        self.block[self.n, 0] = time
        self.block[self.n, 1:] = values
        self.n += 1
        return self.n == len(self.block)

    def take(self) -> np.ndarray:
        """The queued rows (a copy), and an empty queue."""
        rows = self.block[:self.n].copy()
        self.n = 0
        return rows


class KeptRows:
    """Every row ``time, values...`` kept in memory, for a writer that needs them all at the end
    (the .mat file, the API's result). ``rows_written`` counts the rows moved out of the queue."""

    def __init__(self, width: int, kinds: Sequence[str], chunk: int) -> None:
        self._queue = RowQueue(width, kinds, chunk)
        self._blocks: List[np.ndarray] = []
        self.rows_written = 0

    def write(self, time: float, values: np.ndarray) -> None:
        """Keep one row."""
        if self._queue.add(time, values):
            self.flush()

    def write_rows(self, rows: np.ndarray) -> None:
        """Keep rows ``time, values...`` (a 2-D array)."""
        self.flush()
        self._blocks.append(np.array(rows, dtype=self._queue.block.dtype))
        self.rows_written += len(rows)

    def flush(self) -> None:
        """Move the queued rows to the kept blocks."""
        if self._queue.n:
            rows = self._queue.take()
            self._blocks.append(rows)
            self.rows_written += len(rows)

    def data(self) -> np.ndarray:
        """Every row kept, as one array (floats, or objects when a String variable is kept)."""
        self.flush()
        if self._blocks:
            return np.concatenate(self._blocks)
        return np.empty((0, self._queue.block.shape[1]), dtype=self._queue.block.dtype)


def write_rows_to(writer: Any, rows: np.ndarray) -> None:
    """Rows ``time, values...`` to ``writer``: at once when it takes them so, else row by row (a
    user's writer class may offer ``write`` only)."""
    write_rows = getattr(writer, "write_rows", None)
    if write_rows is not None:
        write_rows(rows)
    else:
        for row in rows:
            writer.write(float(row[0]), row[1:])


def typed_column(values: np.ndarray, kind: str) -> np.ndarray:
    """One column with its FMI type's NumPy type."""
    if kind == "String":
        return values.astype(str)
    if kind == "Boolean":
        return values.astype(float) != 0
    if kind in ("Integer", "Enumeration"):
        return values.astype(np.int64)
    return values.astype(float)


class _ReservedSink:
    """The binary file a Parquet writer writes to, with a reserve of disk space beside it (a
    hidden file of allocated blocks, removed at :meth:`close`): a write that finds the disk full
    frees the reserve and goes on, so the row group being written and the footer still fit;
    :attr:`full` then tells the writer to end the file."""

    def __init__(self, path: Path) -> None:
        self._fd: Optional[int] = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        self.reserve_path = path.with_name(f".{path.name}.reserve")
        self.reserved = 0
        self.position = 0
        #: the error of the write (or reservation) that found the disk full
        self.full: Optional[OSError] = None

    def reserve(self, size: int) -> None:
        """Keep ``size`` bytes in reserve; sets :attr:`full` when the disk has not that much."""
        if self.full is not None or size == self.reserved:
            return
        try:
            fd = os.open(self.reserve_path, os.O_WRONLY | os.O_CREAT, 0o600)
            try:
                if size < self.reserved:
                    os.ftruncate(fd, size)
                else:
                    os.posix_fallocate(fd, 0, size)
            finally:
                os.close(fd)
            self.reserved = size
        except OSError as exc:
            if exc.errno in _NO_SPACE:
                self.full = exc
            self.release()  # a file system that cannot allocate ahead runs without a reserve

    def release(self) -> None:
        """Give the reserve back to the file system."""
        try:
            os.unlink(self.reserve_path)
        except FileNotFoundError:
            pass
        self.reserved = 0

    def write(self, data: Any) -> int:
        view = memoryview(data).cast("B")
        written = 0
        while written < len(view):
            try:
                written += os.write(self._fd, view[written:])
            except OSError as exc:
                if exc.errno not in _NO_SPACE or not self.reserved:
                    raise
                self.full = self.full or exc
                self.release()
        self.position += written
        return written

    def tell(self) -> int:
        return self.position

    def flush(self) -> None:
        pass

    @property
    def closed(self) -> bool:
        return self._fd is None

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        self.release()


class ParquetWriter:
    """Streams rows to a Parquet file (pyarrow), one row group per flush; units in field metadata.

    A full disk ends the file after the row group being written (its footer goes in the space
    :class:`_ReservedSink` kept) and raises :class:`~deltafmi.errors.ResultWriteError`."""

    def __init__(self, path: str | Path, names: Sequence[str], kinds: Optional[Sequence[str]] = None,
                 units: Optional[Sequence[str]] = None, chunk: int = 8192) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._pa = pa
        self.path = Path(path)
        self.file = ResultFile(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._kinds = ["Real", *(kinds if kinds is not None else ["Real"] * len(names))]
        units = ["s", *(units if units is not None else [""] * len(names))]
        types = {"Real": pa.float64(), "Integer": pa.int64(), "Enumeration": pa.int64(),
                 "Boolean": pa.bool_(), "String": pa.string()}
        self._schema = pa.schema([pa.field(name, types[kind], metadata={"unit": unit})
                                  for name, kind, unit in zip(["time", *names], self._kinds, units)])
        self._sink = _ReservedSink(self.file.temporary)
        self._chunk = chunk
        # bytes a row takes in the file: plain size (8 bytes a value) until row groups tell
        self._row_bytes = 9.0 * len(self._kinds) + 16
        self._groups = 0
        self._sink.reserve(self._reserve_size())
        self._file: Any = pq.ParquetWriter(self._sink, self._schema)
        self._rows = RowQueue(len(names) + 1, self._kinds, chunk)
        self._last_flush = _time.monotonic()
        self._last_time: Optional[float] = None
        self._failed: Optional[ResultWriteError] = None
        self.rows_written = 0
        if self._sink.full is not None:
            try:
                self._end(self._sink.full)
            finally:
                self.file.finish()  # no writer to close: the file (its footer, no rows) goes now

    def _reserve_size(self) -> int:
        """Room for a full row group (twice the size rows took so far) and the footer (a few hundred
        bytes per column and row group)."""
        return int(2 * self._chunk * self._row_bytes) + 400 * len(self._kinds) * (self._groups + 2) + 65536

    def write(self, time: float, values: np.ndarray) -> None:
        """Queue one row; it reaches the file with the next row group."""
        if self._failed is not None:
            raise self._failed
        if self._rows.add(time, values) or (self._rows.n & 63 == 0 and
                                            _time.monotonic() - self._last_flush > _FLUSH_SECONDS):
            self.flush()

    def write_rows(self, rows: np.ndarray) -> None:
        """Queue rows ``time, values...`` (a 2-D array) at once."""
        if self._failed is not None:
            raise self._failed
        queue, done = self._rows, 0
        while done < len(rows):
            take = min(len(rows) - done, len(queue.block) - queue.n)
            queue.block[queue.n:queue.n + take] = rows[done:done + take]
            queue.n += take
            done += take
            if queue.n == len(queue.block) or _time.monotonic() - self._last_flush > _FLUSH_SECONDS:
                self.flush()

    def flush(self) -> None:
        """Write the queued rows as one row group (nothing after a failed write)."""
        if self._rows.n and self._file is not None and self._failed is None:
            rows = self._rows.take()
            arrays = [self._pa.array(typed_column(rows[:, i], kind), type=field.type)
                      for i, (kind, field) in enumerate(zip(self._kinds, self._schema))]
            before = self._sink.position
            try:
                self._file.write_table(self._pa.Table.from_arrays(arrays, schema=self._schema))
            except OSError as exc:  # no reserve left to fall back on: the file cannot be finished
                self._abandon(exc, self.rows_written + len(rows))
            self.rows_written += len(rows)
            self._last_time = float(rows[-1, 0])
            measured = (self._sink.position - before) / len(rows)
            self._row_bytes = measured if self._groups == 0 else max(self._row_bytes, measured)
            self._groups += 1
            self._sink.reserve(self._reserve_size())
            if self._sink.full is not None:
                self._end(self._sink.full)
        self._last_flush = _time.monotonic()

    def _end(self, error: OSError) -> None:
        """The disk is full: write the footer now (in the reserve's space) and refuse more rows."""
        try:
            self._file.close()
        except OSError as exc:
            self._abandon(exc, self.rows_written)
        self._file = None
        self._sink.close()
        self._failed = ResultWriteError(self.fail(), self.rows_written, self._last_time, error)
        raise self._failed

    def _abandon(self, error: OSError, lost: int) -> None:
        """A write failed with no reserve to fall back on: remove the unreadable file (``lost`` rows)."""
        self._file = None
        self._sink.close()
        self.file.fail()
        self.file.discard()
        self._failed = ResultWriteError(self.path, lost, self._last_time, error, whole_file=True)
        raise self._failed from None

    def fail(self) -> Path:
        """The run failed: :meth:`close` keeps the rows under the failed name (returned)."""
        return self.file.fail()

    def close(self) -> None:
        """Write the last rows and the footer, and move the file into place (idempotent)."""
        try:
            if self._file is not None:
                try:
                    self.flush()
                    if self._file is not None:
                        self._file.close()
                        self._file = None
                finally:
                    self._sink.close()
        finally:
            if self._file is None:  # a file with its footer (a failed close leaves an unreadable one)
                self.file.finish()
            else:
                self._file = None
                self.file.discard()


def matlab_names(names: Sequence[str]) -> List[str]:
    """MATLAB variable names for FMI names, in order, all distinct.

    Every run of characters other than letters, digits and ``_`` becomes one ``_``, and a
    trailing ``_`` is dropped: ``plant.z[3]`` -> ``plant_z_3``, ``der(osc.x)`` -> ``der_osc_x``.
    A name that does not start with a letter gets ``x`` before it; names are cut to 63
    characters; a name already taken (by an earlier variable or by ``time``, ``names``,
    ``variables``, ``units``) gets ``_2``, ``_3``, ... .
    """
    taken = set(_MAT_RESERVED)
    result = []
    for name in names:
        base = re.sub(r"[^A-Za-z0-9_]+", "_", name).rstrip("_") or "x"
        if not base[0].isalpha() or not base[0].isascii():
            base = "x" + base
        base = base[:_MATLAB_NAME_LENGTH]
        candidate, n = base, 1
        while candidate in taken:
            n += 1
            candidate = f"{base[:_MATLAB_NAME_LENGTH - len(str(n)) - 1]}_{n}"
        taken.add(candidate)
        result.append(candidate)
    return result


class MatWriter:
    """Keeps rows in memory and writes a MATLAB 5 .mat file when closed.

    The file holds ``time`` (a column), one column per recorded variable under its
    :func:`matlab_names` name, and three cell arrays (rows), one entry per variable in
    recording order: ``names`` (the FMI names), ``variables`` (their MATLAB names) and
    ``units``. In MATLAB: ``r = load('r.mat'); plot(r.time, r.(r.variables{strcmp(r.names,
    'plant.z[3]')}))``. String variables are cell arrays, the others doubles.
    """

    def __init__(self, path: str | Path, names: Sequence[str], kinds: Optional[Sequence[str]] = None,
                 units: Optional[Sequence[str]] = None, chunk: int = 8192) -> None:
        self.path = Path(path)
        self.file = ResultFile(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._names = list(names)
        self._kinds = list(kinds) if kinds is not None else ["Real"] * len(names)
        self._units = list(units) if units is not None else [""] * len(names)
        self._rows = KeptRows(len(names) + 1, self._kinds, chunk)
        self._closed = False

    @property
    def rows_written(self) -> int:
        """Rows kept so far (written to the file by :meth:`close`)."""
        return self._rows.rows_written

    def write(self, time: float, values: np.ndarray) -> None:
        """Keep one row."""
        self._rows.write(time, values)

    def write_rows(self, rows: np.ndarray) -> None:
        """Keep rows ``time, values...`` (a 2-D array)."""
        self._rows.write_rows(rows)

    def flush(self) -> None:
        """Move the queued rows to the kept ones (the file is written by :meth:`close`)."""
        self._rows.flush()

    def fail(self) -> Path:
        """The run failed: :meth:`close` writes the rows under the failed name (returned)."""
        return self.file.fail()

    def close(self) -> None:
        """Write the .mat file with every row kept, and move it into place (idempotent)."""
        if self._closed:
            return
        from scipy.io import savemat

        data = self._rows.data()
        variables = matlab_names(self._names)
        content: Dict[str, Any] = {"time": data[:, 0].astype(float)}
        for i, (name, kind) in enumerate(zip(variables, self._kinds), start=1):
            column = data[:, i]
            content[name] = column.astype(str).astype(object) if kind == "String" else column.astype(float)
        for key, values in (("names", self._names), ("variables", variables), ("units", self._units)):
            content[key] = np.array(values, dtype=object).reshape(1, -1)
        self._closed = True
        try:
            savemat(str(self.file.temporary), content, oned_as="column")
        except OSError as exc:
            self.file.discard()  # a partial .mat file is unreadable
            time = float(data[-1, 0]) if len(data) else None
            raise ResultWriteError(self.path, len(data), time, exc, whole_file=True) from None
        self.file.finish()
