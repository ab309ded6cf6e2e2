"""Result files: rows streamed to CSV while the run goes on, and read back for plots and tests.

The file starts with a ``time`` column followed by one column per recorded ``comp.var``. An event
shows as two rows with the same time stamp (values just before and just after). Real values are
written as ``repr`` writes them (they read back bit for bit; blocks of numeric rows are
formatted in C by ``native/csv_rows.c``, Ryu's shortest digits, ten times faster than ``repr``),
Integer, Boolean and Enumeration values as integers, String values quoted by the :mod:`csv` module's rules (``QUOTE_NONNUMERIC``: every
string in double quotes, a quote inside doubled). Rows are buffered and written out whenever
the buffer fills up or half a second has passed, to a temporary file beside the result file
that :meth:`CsvWriter.close` moves into place (:mod:`.safe_file`): a failing or interrupted run
keeps (almost) everything up to its end, and an earlier result of the same name is replaced
only by a whole file. The file never ends in a partial row, also when the disk fills up.
"""
from __future__ import annotations

import ctypes
import csv
import io
import os
import time as _time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from deltafmi.errors import ResultWriteError
from deltafmi.files import written_through
from deltafmi.toolchain import plain_c_library

from .safe_file import ResultFile

__all__ = ["CsvRowsThread", "CsvWriter", "RowSampler", "columns", "read_csv"]

_FLUSH_SECONDS = 0.5
_INTEGERS = ("Integer", "Boolean")
_format_rows: Optional[Any] = None
_tables: List[np.ndarray] = []  # Ryu's tables, alive as long as the library uses them


_library: Optional[Any] = None


class _SinkReport(ctypes.Structure):  # csv_rows.c's SinkReport
    _fields_ = [("size", ctypes.c_longlong), ("rows", ctypes.c_long), ("last_time", ctypes.c_double),
                ("error", ctypes.c_int)]


def _csv_library() -> Any:
    """``native/csv_rows.c`` loaded, its tables set and its functions typed."""
    global _format_rows, _library
    if _library is None:
        library = ctypes.CDLL(str(plain_c_library(Path(__file__).parent / "native" / "csv_rows.c")))
        _tables[:] = _ryu_tables()
        library.deltafmi_csv_tables(ctypes.c_void_p(_tables[0].ctypes.data), ctypes.c_void_p(_tables[1].ctypes.data))
        function = library.deltafmi_csv_rows
        function.argtypes = [ctypes.c_void_p, ctypes.c_long, ctypes.c_long, ctypes.c_void_p, ctypes.c_char_p]
        function.restype = ctypes.c_size_t
        library.deltafmi_csv_sink_open.argtypes = [ctypes.c_int, ctypes.c_long, ctypes.c_void_p, ctypes.c_long]
        library.deltafmi_csv_sink_open.restype = ctypes.c_void_p
        library.deltafmi_csv_sink_put.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_long]
        library.deltafmi_csv_sink_put.restype = ctypes.c_long
        library.deltafmi_csv_sink_taken.argtypes = [ctypes.c_void_p]
        library.deltafmi_csv_sink_taken.restype = ctypes.c_long
        library.deltafmi_csv_sink_wait.argtypes = [ctypes.c_void_p, ctypes.POINTER(_SinkReport)]
        library.deltafmi_csv_sink_wait.restype = None
        library.deltafmi_csv_sink_failed.argtypes = [ctypes.c_void_p]
        library.deltafmi_csv_sink_failed.restype = ctypes.c_int
        library.deltafmi_csv_sink_close.argtypes = [ctypes.c_void_p]
        library.deltafmi_csv_sink_close.restype = None
        _format_rows, _library = function, library
    return _library


def _rows_formatter() -> Any:
    """The C function writing rows of doubles as CSV text (``native/csv_rows.c``), its tables set."""
    _csv_library()
    return _format_rows


def _ryu_tables() -> List[np.ndarray]:
    """Ryu's 125-bit powers of five, exact (Python integers), as (low, high) 64-bit pairs:
    ``2^(bits(5^i) - 1 + 125) // 5^i + 1`` for i < 342 and ``5^i`` scaled to 125 bits for i < 326."""
    def pairs(values: List[int]) -> np.ndarray:
        return np.array([[v & (2 ** 64 - 1), v >> 64] for v in values], dtype=np.uint64)
    inverse = [(1 << (5 ** i).bit_length() - 1 + 125) // 5 ** i + 1 for i in range(342)]
    powers = []
    for i in range(326):
        shift = (5 ** i).bit_length() - 125
        powers.append(5 ** i >> shift if shift >= 0 else 5 ** i << -shift)
    return [pairs(inverse), pairs(powers)]


def units_file(path: str | Path) -> Path:
    """The file beside a CSV result that holds its units (a CSV has no place for them):
    ``r.csv`` -> ``r.csv.units.json``, ``{"time": "s", "plant.z[3]": "m", ...}``; beside the file
    a symbolic link points to (where a run given the link writes the rows)."""
    path = written_through(Path(path))
    return path.with_name(path.name + ".units.json")


def read_units(path: str | Path) -> Dict[str, str]:
    """The units of the CSV result ``path`` from its :func:`units_file` ({} when there is none,
    or it cannot be read: the numbers stand without them)."""
    import json

    try:
        units = json.loads(units_file(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return {str(k): str(v) for k, v in units.items()} if isinstance(units, dict) else {}


class CsvWriter:
    """Appends rows ``time, values...`` to a CSV file.

    ``kinds`` gives each column's FMI type (``Real``, ``Integer``, ``Boolean``, ``String``;
    default all Real). Without String columns rows go through a float block and one format
    string; with them, each row is kept as a list and written by :func:`csv.writer`.

    The file only ever holds whole rows: rows go out with ``os.write`` in blocks, and when a
    write fails (a full disk, a quota, a file size limit) the file is cut back to the end of the
    last complete row and :class:`~deltafmi.errors.ResultWriteError` says how many rows it holds
    and up to which time. After that the writer takes no more rows.

    The rows go to a temporary file beside ``path``, moved into place by :meth:`close`; after
    :meth:`fail` (the run failed) to ``path``'s failed name instead (:mod:`.safe_file`).
    ``units`` (one per column after ``time``) go to :func:`units_file` beside it when it closes.
    """

    def __init__(self, path: str | Path, names: Sequence[str], chunk: int = 512,
                 kinds: Optional[Sequence[str]] = None, units: Optional[Sequence[str]] = None) -> None:
        kinds = list(kinds) if kinds is not None else ["Real"] * len(names)
        if len(kinds) != len(names):
            raise ValueError(f"{len(names)} column names but {len(kinds)} column types")
        self.path = Path(path)
        self.file = ResultFile(self.path)
        self._units = dict(zip(["time", *names], ["s", *units])) if units is not None and any(units) else None
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fd: Optional[int] = os.open(self.file.temporary, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        self._size = 0  # bytes of whole rows (and the header) in the file
        self._failed: Optional[ResultWriteError] = None
        self._chunk = chunk
        self._text = "String" in kinds
        if self._text:
            self._rows: list = []
            self._csv_buffer = io.StringIO()
            self._csv = csv.writer(self._csv_buffer, quoting=csv.QUOTE_NONNUMERIC, lineterminator="\n")
        else:
            self._block = np.empty((chunk, len(names) + 1))
            self._integer = (ctypes.c_int * (len(names) + 1))(0, *[kind in _INTEGERS for kind in kinds])
            self._text_out = ctypes.create_string_buffer(chunk * (len(names) + 1) * 33 + 32)  # csv_rows.c's room
            self._format_rows = _rows_formatter()
        self._n = 0
        self._last_flush = _time.monotonic()
        self.rows_written = 0
        self._last_time: Optional[float] = None  # of the last row in the file
        header = io.StringIO()
        csv.writer(header, lineterminator="\n").writerow(["time", *names])
        data = header.getvalue().encode("utf-8")
        self._emit(data, np.array([len(data)]), [])

    def write(self, time: float, values: np.ndarray) -> None:
        """Queue one row; it reaches the file at the next flush."""
        if self._failed is not None:
            raise self._failed
        if self._text:
            self._rows.append([time, *values])
        else:
            row = self._block[self._n]
            row[0] = time
            row[1:] = values
        self._n += 1
        if self._n == self._chunk or (self._n & 63 == 0 and
                                      _time.monotonic() - self._last_flush > _FLUSH_SECONDS):
            self.flush()

    def write_rows(self, rows: np.ndarray) -> None:
        """Queue rows ``time, values...`` (a 2-D float array) at once."""
        if self._text:
            for row in rows:
                self.write(float(row[0]), row[1:])
            return
        if self._failed is not None:
            raise self._failed
        done, chunk = 0, self._chunk
        direct = (isinstance(rows, np.ndarray) and rows.dtype == np.float64 and rows.flags.c_contiguous
                  and rows.shape[1:] == self._block.shape[1:])
        while done < len(rows):
            if direct and self._n == 0 and len(rows) - done >= chunk:
                # a whole block with none queued before it: formatted where it is, not copied first
                self._write_block(rows[done:done + chunk])
                done += chunk
                continue
            take = min(len(rows) - done, chunk - self._n)
            self._block[self._n:self._n + take] = rows[done:done + take]
            self._n += take
            done += take
            if self._n == chunk or _time.monotonic() - self._last_flush > _FLUSH_SECONDS:
                self.flush()

    def flush(self) -> None:
        """Write the queued rows (whole rows only; see the class). After a failed write it does
        nothing: the error was raised once, where the rows were written."""
        if self._failed is not None:
            return
        if self._n:
            n, self._n = self._n, 0
            if self._text:
                pieces = []
                for row in self._rows:
                    self._csv.writerow(row)
                    pieces.append(self._csv_buffer.getvalue().encode("utf-8"))
                    self._csv_buffer.seek(0)
                    self._csv_buffer.truncate()
                data = b"".join(pieces)
                ends = np.cumsum([len(piece) for piece in pieces])
                times = [row[0] for row in self._rows]
                self._rows = []
                self._emit(data, ends, times, n)
            else:
                self._write_block(self._block[:n])
        self._last_flush = _time.monotonic()

    def _write_block(self, block: np.ndarray) -> None:
        """Numeric rows (a C-contiguous float block of at most ``chunk`` rows) as text to the file."""
        size = self._format_rows(block.ctypes.data, len(block), block.shape[1], self._integer, self._text_out)
        data = memoryview(self._text_out)[:size]  # written before the buffer is used again
        # ends None: one row a line, found from the text if a write fails
        self._emit(data, None, block[:, 0], len(block))
        self._last_flush = _time.monotonic()

    def _emit(self, data: Any, ends: Optional[np.ndarray], times: Sequence[float], n_rows: int = 0) -> None:
        """Write ``data`` (bytes-like), rows ending at byte offsets ``ends`` (None: ``n_rows`` rows
        of one line each; the header when ``times`` is empty); on a failed write cut the file
        back to its last whole row and raise ResultWriteError."""
        written = 0
        try:
            while written < len(data):
                written += os.write(self._fd, data[written:])
        except OSError as exc:
            if ends is None:
                ends = np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == 10) + 1
            whole = int(np.searchsorted(ends, written, side="right"))  # rows entirely written
            keep = int(ends[whole - 1]) if whole else 0
            try:
                os.ftruncate(self._fd, self._size + keep)  # frees space: cannot fail for lack of it
            except OSError:
                pass
            if len(times):
                self.rows_written += whole
                if whole:
                    self._last_time = float(times[whole - 1])
            raise self._refuse(exc) from None
        self._size += written
        if len(times):
            self.rows_written += len(ends) if ends is not None else n_rows
            self._last_time = float(times[-1])

    def _refuse(self, error: OSError) -> ResultWriteError:
        """A write failed (the file holds whole rows only): the error this writer raises from now on."""
        self._failed = ResultWriteError(self.fail(), self.rows_written, self._last_time, error)
        return self._failed

    def rows_thread(self) -> Optional["CsvRowsThread"]:
        """A thread of C formatting and writing blocks of rows to this file (None: not for this
        writer, whose String columns Python writes, or no thread could be made)."""
        if self._text or self._failed is not None or self._fd is None:
            return None
        return CsvRowsThread.open(self)

    def fail(self) -> Path:
        """The run failed: :meth:`close` keeps the rows under the failed name (returned)."""
        return self.file.fail()

    def close(self) -> None:
        """Flush, close and move the file into place (idempotent). Raises
        :class:`~deltafmi.errors.ResultWriteError` when the last rows do not fit; the file is
        closed and kept (under the failed name) either way."""
        if self._fd is None:
            return
        try:
            self.flush()
        finally:
            os.close(self._fd)
            self._fd = None
            final = self.file.finish()
            if final is not None and self._units is not None:
                self._write_units(final)

    def _write_units(self, final: Path) -> None:
        """The units beside the file (written whole, then renamed: never half a file)."""
        import json

        target = units_file(final)
        temporary = target.with_name(f".{target.name}.{os.getpid()}.tmp")
        try:
            temporary.write_text(json.dumps(self._units, indent=0, ensure_ascii=False) + "\n", encoding="utf-8")
            os.replace(temporary, target)
        except OSError:  # the rows are what matters; a plot then shows no units
            temporary.unlink(missing_ok=True)


class CsvRowsThread:
    """Blocks of rows formatted and written to a :class:`CsvWriter`'s file by a thread in C
    (``native/csv_rows.c``'s sink), the same text the writer writes: no Python between a block and
    its text. A block stays untouched by the caller until the thread has taken it (:meth:`taken`);
    :meth:`wait` brings the writer's counts up to date, and returns the writer's error when a write
    failed (the file then ends at its last whole row, as the writer leaves it)."""

    def __init__(self, writer: CsvWriter, handle: int, library: Any) -> None:
        self._writer, self._handle, self._library = writer, handle, library
        self.width = len(writer._integer)  #: the columns of a row, time first
        self._report = _SinkReport()
        self._counted = _SinkReport(0, 0, float("nan"), 0)  # what the writer was told already

    @classmethod
    def open(cls, writer: CsvWriter) -> Optional["CsvRowsThread"]:
        """The thread for ``writer`` (None when none could be made)."""
        library = _csv_library()
        handle = library.deltafmi_csv_sink_open(writer._fd, len(writer._integer),
                                                ctypes.cast(writer._integer, ctypes.c_void_p), writer._chunk)
        return cls(writer, handle, library) if handle else None

    def put(self, rows: np.ndarray) -> int:
        """Queue ``rows`` (C-contiguous floats, the writer's width): they reach the file after the
        rows the writer queued before. Returns the number of blocks queued so far."""
        self._writer.flush()
        return self._library.deltafmi_csv_sink_put(self._handle, rows.ctypes.data, len(rows))

    def taken(self) -> int:
        """The blocks the thread is done with (their memory is the caller's again)."""
        return self._library.deltafmi_csv_sink_taken(self._handle)

    def failed(self) -> bool:
        """Whether a write failed (:meth:`wait` tells the writer)."""
        return bool(self._library.deltafmi_csv_sink_failed(self._handle))

    def direct(self) -> Tuple[int, int]:
        """(the address of ``deltafmi_csv_sink_put``, the sink) for C to queue blocks itself
        (after the rows the writer holds: :meth:`take_writer_rows` first)."""
        return ctypes.cast(self._library.deltafmi_csv_sink_put, ctypes.c_void_p).value, self._handle

    def take_writer_rows(self) -> Optional[np.ndarray]:
        """The rows the writer holds of its own, not yet written (a copy, its queue emptied), to
        queue here: None when it holds none."""
        writer = self._writer
        if not writer._n:
            return None
        rows, writer._n = writer._block[:writer._n].copy(), 0
        return rows

    def wait(self) -> Optional[ResultWriteError]:
        """Wait until every block queued is written; the writer's error if a write failed."""
        report, counted, writer = self._report, self._counted, self._writer
        self._library.deltafmi_csv_sink_wait(self._handle, ctypes.byref(report))
        writer._size += report.size - counted.size
        if report.rows != counted.rows:
            writer.rows_written += report.rows - counted.rows
            writer._last_time = report.last_time
        ctypes.memmove(ctypes.byref(counted), ctypes.byref(report), ctypes.sizeof(report))
        if report.error and writer._failed is None:
            return writer._refuse(OSError(report.error, os.strerror(report.error)))
        return None

    def close(self) -> None:
        """Write what is queued and end the thread (once; :meth:`wait` first for the counts)."""
        if self._handle:
            self._library.deltafmi_csv_sink_close(self._handle)
            self._handle = None


class RowSampler:
    """Gathers the recorded variables from the master's buses into one row (float, or an
    object array when a String variable is recorded)."""

    def __init__(self, parts: Sequence[Tuple[np.ndarray, Sequence[int], Sequence[int]]], width: int) -> None:
        """``parts``: (bus, bus indices, row columns) per FMI type."""
        self._parts = [(bus, np.asarray(index, np.intp), np.asarray(columns, np.intp))
                       for bus, index, columns in parts if len(index)]
        text = any(bus.dtype == object for bus, _, _ in self._parts)
        self.row = np.zeros(width, dtype=object if text else float)

    def sample(self) -> np.ndarray:
        """The current values of every recorded variable."""
        row = self.row
        for bus, index, columns in self._parts:
            row[columns] = bus[index]
        return row


def read_csv(path: str | Path) -> Tuple[List[str], np.ndarray]:
    """Column names and data (rows x columns, time first) of a result file.

    The data are floats; a file with String columns comes back as an object array whose
    String columns hold ``str`` (see :func:`columns` for typed columns).
    """
    with open(path, newline="") as file:
        names = next(csv.reader(file))
        body = file.read()
    if not body.strip():  # a run that ended before its first row: a header alone
        return names, np.empty((0, len(names)))
    if '"' not in body:
        return names, np.loadtxt(io.StringIO(body), delimiter=",", ndmin=2)
    rows = list(csv.reader(io.StringIO(body), quoting=csv.QUOTE_NONNUMERIC))
    data = np.empty((len(rows), len(names)), dtype=object)
    for i, row in enumerate(rows):
        data[i, :] = row
    return names, data


def columns(path: str | Path) -> Dict[str, np.ndarray]:
    """A result file as ``{name: column}`` (``time`` included): float arrays, and object
    arrays of ``str`` for String columns."""
    names, data = read_csv(path)
    result = {}
    for i, name in enumerate(names):
        column = data[:, i]
        if column.dtype == object and not any(isinstance(value, str) for value in column):
            column = column.astype(float)
        result[name] = column
    return result
