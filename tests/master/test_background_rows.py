"""Result rows written on a thread of their own (deltafmi/master/results/background.py)."""
from __future__ import annotations

import numpy as np
import pytest

from deltafmi.errors import ResultWriteError
from deltafmi.master.results.background import BackgroundRows
from deltafmi.master.results.csv_file import CsvWriter
from deltafmi.master.results.safe_file import failed_name


def _blocks(seed: int = 3) -> list:
    rng = np.random.default_rng(seed)
    return [np.column_stack([np.arange(k, k + n) * 1e-3, rng.normal(size=(n, 3))])
            for k, n in ((0, 700), (700, 1), (701, 300))]


class _PythonThreadCsv(CsvWriter):
    """The CSV writer without its thread of C: BackgroundRows writes its blocks from Python."""

    def rows_thread(self):
        return None


@pytest.mark.parametrize("csv_class, in_file", [(CsvWriter, 1001), (_PythonThreadCsv, 701)])
def test_blocks_single_rows_and_flushes_reach_the_file_in_order(tmp_path, csv_class, in_file):
    """Blocks handed to the thread (of C for the CSV writer, else of Python), a row written
    directly between them, a flush: the file is byte for byte the one the writer makes alone.
    The thread of C writes a block whole (the rows in the file then count it); the writer from
    Python keeps the last rows of a block for its next flush, as it does alone."""
    def write(writer) -> int:
        first, single, last = _blocks()
        writer.write_rows(first)
        writer.write(float(single[0, 0]), single[0, 1:])
        writer.flush()
        writer.write_rows(last)
        in_file = writer.rows_written  # the rows in the file so far
        writer.close()
        return in_file

    assert write(CsvWriter(tmp_path / "alone.csv", ["a", "b", "c"])) == 701
    background = BackgroundRows(csv_class(tmp_path / "thread.csv", ["a", "b", "c"]))
    assert (background._c is not None) == (csv_class is CsvWriter)
    assert write(background) == in_file
    assert background.rows_written == 1001
    assert (tmp_path / "thread.csv").read_bytes() == (tmp_path / "alone.csv").read_bytes()


def test_the_c_thread_writes_what_the_writer_writes_for_every_kind_of_value(tmp_path):
    """Blocks with integer columns, repeated values, signs, tiny and huge numbers, NaN and
    infinities through the thread of C: the text is the writer's own, bit for bit, and reads
    back to the same doubles."""
    rng = np.random.default_rng(7)
    n = 1500
    values = np.column_stack([np.arange(n) * 1e-3, rng.normal(size=n) * 10.0 ** rng.integers(-30, 30, n),
                              np.repeat(rng.normal(size=n // 100), 100), rng.integers(-5, 5, n).astype(float),
                              np.where(rng.random(n) < 0.01, np.nan, rng.normal(size=n)),
                              np.where(rng.random(n) < 0.01, -np.inf, 0.5)])
    names, kinds = ["x", "held", "status", "maybe_nan", "inf"], ["Real", "Real", "Integer", "Real", "Real"]
    alone = CsvWriter(tmp_path / "alone.csv", names, kinds=kinds)
    alone.write_rows(values)
    alone.close()
    background = BackgroundRows(CsvWriter(tmp_path / "thread.csv", names, kinds=kinds))
    for block in np.array_split(values, [1, 2, 300, 301, 1200]):
        background.take_rows(np.ascontiguousarray(block))
    background.close()
    text = (tmp_path / "thread.csv").read_bytes()
    assert text == (tmp_path / "alone.csv").read_bytes()
    back = np.loadtxt(tmp_path / "thread.csv", delimiter=",", skiprows=1)
    assert np.array_equal(back[:, [0, 1, 2, 4, 5]], values[:, [0, 1, 2, 4, 5]], equal_nan=True)
    assert np.array_equal(back[:, 3], values[:, 3])


@pytest.fixture
def file_size_limit():
    """Set a file size limit (writes beyond it fail with EFBIG, SIGXFSZ ignored); given back after."""
    import resource
    import signal

    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    def limit(size: int) -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, hard))

    try:
        yield limit
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, handler)


def test_the_c_thread_meets_a_full_file_as_the_writer_does(tmp_path, file_size_limit):
    """A write cut short by a file size limit: the thread of C leaves the file at its last whole
    row, counts the rows and their last time, and the error is raised once, where the writer is
    used next, saying what the writer alone says."""
    import errno

    first, _, last = _blocks()
    blocks = [first, last]

    def run(writer, name: str):
        error = None
        try:
            for block in blocks:
                writer.write_rows(block)
            writer.flush()
        except ResultWriteError as exc:
            error = exc
        rows = writer.rows_written
        if error is not None:
            writer.fail()
        writer.close()
        return error, rows, failed_name(tmp_path / name).read_bytes()

    file_size_limit(30000)
    alone = run(CsvWriter(tmp_path / "alone.csv", ["a", "b", "c"]), "alone.csv")
    background = BackgroundRows(CsvWriter(tmp_path / "thread.csv", ["a", "b", "c"]))
    assert background._c is not None
    thread = run(background, "thread.csv")
    for error, rows, text in (alone, thread):
        assert isinstance(error, ResultWriteError) and error.error.errno == errno.EFBIG
        assert text.endswith(b"\n") and len(text) <= 30000 and text.count(b"\n") == rows + 1  # the header
        assert error.rows == rows and error.time == pytest.approx((rows - 1) * 1e-3, abs=0.0)
    assert thread[2] == alone[2] and str(thread[0]).replace("thread.failed", "alone.failed") == str(alone[0])
    with pytest.raises(ResultWriteError):  # more rows: the writer says again that it is full
        background.write_rows(last)


class _FullDisk:
    """A caller's writer that takes 500 rows, then fails as CsvWriter does on a full disk."""

    def __init__(self) -> None:
        self.rows_written = 0
        self.closed = False

    def write_rows(self, rows: np.ndarray) -> None:
        if self.rows_written + len(rows) > 500:
            raise ResultWriteError(None, self.rows_written, None, OSError(28, "No space left on device"))
        self.rows_written += len(rows)

    def write(self, time: float, values: np.ndarray) -> None:
        self.write_rows(np.array([[time, *values]]))

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self.closed = True


def test_an_error_of_the_thread_is_raised_once_where_the_writer_is_used_next():
    writer = _FullDisk()
    background = BackgroundRows(writer)
    first, _, last = _blocks()
    background.write_rows(first[:400])
    background.write_rows(first[400:])  # does not fit: the thread meets the error
    with pytest.raises(ResultWriteError):
        background.drain()
    background.drain()  # raised once
    assert writer.rows_written == 400
    with pytest.raises(ResultWriteError):  # more rows: the writer says again that it is full
        background.write_rows(last)
    background.close()
    assert writer.closed and writer.rows_written == 400
