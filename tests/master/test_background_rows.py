"""Result rows written on a thread of their own (deltafmi/master/results/background.py)."""
from __future__ import annotations

import numpy as np
import pytest

from deltafmi.errors import ResultWriteError
from deltafmi.master.results.background import BackgroundRows
from deltafmi.master.results.csv_file import CsvWriter


def _blocks(seed: int = 3) -> list:
    rng = np.random.default_rng(seed)
    return [np.column_stack([np.arange(k, k + n) * 1e-3, rng.normal(size=(n, 3))])
            for k, n in ((0, 700), (700, 1), (701, 300))]


def test_blocks_single_rows_and_flushes_reach_the_file_in_order(tmp_path):
    """Blocks handed to the thread, a row written directly between them, a flush: the file is
    byte for byte the one the writer makes alone."""
    def write(writer) -> int:
        first, single, last = _blocks()
        writer.write_rows(first)
        writer.write(float(single[0, 0]), single[0, 1:])
        writer.flush()
        writer.write_rows(last)
        in_file = writer.rows_written  # the rows in the file so far (the last block is queued)
        writer.close()
        return in_file

    assert write(CsvWriter(tmp_path / "alone.csv", ["a", "b", "c"])) == 701
    background = BackgroundRows(CsvWriter(tmp_path / "thread.csv", ["a", "b", "c"]))
    assert write(background) == 701
    assert background.rows_written == 1001
    assert (tmp_path / "thread.csv").read_bytes() == (tmp_path / "alone.csv").read_bytes()


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
