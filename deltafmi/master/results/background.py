"""A result writer whose blocks of rows are formatted and written on a thread of their own.

The master's C loop hands its recorded rows over in blocks; turning them into CSV text and
writing it costs about as much as a third of a flagship step. :class:`BackgroundRows` takes a
block (a copy) and returns at once; one thread formats and writes the blocks in order while the
C loop, which releases the GIL, computes the next ones. Every other use of the writer (a single
row, a flush, close, fail, ``rows_written``, ...) first waits until the blocks handed over are
written, so rows reach the file in the order they were recorded, and an error the thread met
(:class:`~deltafmi.errors.ResultWriteError`: the disk filled) is raised there, once, as the
writer would have raised it.

A writer that offers a thread of C for its blocks (``rows_thread()``: the CSV writer's,
:class:`~.csv_file.CsvRowsThread`) gets them that way, with no Python on the thread (no lock
shared with the stepping thread, no queue); the blocks written are handed back for the C loop to
fill again (:meth:`BackgroundRows.spare`).
"""
from __future__ import annotations

import queue
import threading
from typing import Any, List, Optional, Tuple

import numpy as np

from .writers import write_rows_to

__all__ = ["BackgroundRows"]


class BackgroundRows:
    """``writer`` with :meth:`write_rows` on a thread (see the module docstring)."""

    def __init__(self, writer: Any) -> None:
        self._writer = writer
        self._blocks: Optional["queue.Queue[Optional[np.ndarray]]"] = None  # the Python thread's (made with it)
        self._error: Optional[Any] = None  # what writing a block raised (_Spent once raised here)
        self._thread: Optional[threading.Thread] = None
        rows_thread = getattr(writer, "rows_thread", None)
        self._c = rows_thread() if rows_thread is not None else None  # the writer's thread of C
        self._queued: List[Tuple[int, np.ndarray]] = []  # (its last block's number, an array) until taken
        self._spare: List[np.ndarray] = []  # blocks written: memory to fill again

    def write_rows(self, rows: np.ndarray) -> None:
        """Queue rows ``time, values...`` (copied); raises what an earlier block met."""
        self.take_rows(np.array(rows, copy=True))

    def take_rows(self, rows: np.ndarray) -> None:
        """Queue rows ``time, values...`` handed over: not copied, the caller writes them no more
        (the master's C loop then fills a block of its own); raises what an earlier block met."""
        self._raise()
        if isinstance(self._error, _Spent):  # the writer refuses rows now: let it say so
            write_rows_to(self._writer, rows)
            return
        if self._c is not None:
            if self._c.failed():  # the thread met an error: raised now, as the Python thread's is
                self._wait_c()
                self._raise()
            rows = np.ascontiguousarray(rows, dtype=np.float64)
            if rows.ndim == 2 and rows.shape[1] == self._c.width:
                self.handed(rows, self._c.put(rows))
                return
            self.drain()  # rows the writer takes otherwise (or refuses): after those handed over
            write_rows_to(self._writer, rows)
            return
        if self._thread is None:
            self._blocks = queue.Queue()
            self._thread = threading.Thread(target=self._work, name="deltafmi-result-rows", daemon=True)
            self._thread.start()
        self._blocks.put(rows)

    def _work(self) -> None:
        while True:
            rows = self._blocks.get()
            try:
                if rows is None:
                    return
                if self._error is None:  # after a failure the rest is not written
                    write_rows_to(self._writer, rows)
            except BaseException as exc:  # noqa: BLE001 - handed to the master's thread
                self._error = exc
            finally:
                self._blocks.task_done()

    def c_sink(self) -> Optional[Tuple[int, int]]:
        """Where C code queues blocks to this writer's thread of C itself, as
        :meth:`.NativeLoop.hand_rows_to` takes it (None: the writer has none, or has failed); the
        rows queued or handed over before are written first. Call it again before every run of
        C code that hands rows over (rows written in between, e.g. an event's, are queued first)."""
        if self._c is None or self._error is not None:
            return None
        held = self._c.take_writer_rows()
        if held is not None:  # the rows written one by one (the first, an event's) go first
            self.handed(held, self._c.put(held))
        return self._c.direct()

    def handed(self, rows: np.ndarray, queued: int) -> None:
        """``rows`` were queued to the thread of C (the ``queued``-th block or before): their memory
        is left alone until it has taken them."""
        base = rows.base if rows.base is not None else rows
        if self._queued and self._queued[-1][1] is base:
            self._queued[-1] = (queued, base)
        else:
            self._queued.append((queued, base))

    def spare(self, like: np.ndarray) -> np.ndarray:
        """An array shaped as ``like`` to fill with rows: a block handed over before, which the
        C thread has written (its pages in memory already), else a new one."""
        if self._c is not None and self._queued:
            taken = self._c.taken()
            while self._queued and self._queued[0][0] <= taken:
                base = self._queued.pop(0)[1]
                if base.shape == like.shape and base.flags.c_contiguous and base.dtype == like.dtype:
                    self._spare.append(base)
        for i, block in enumerate(self._spare):
            if block.shape == like.shape:
                return self._spare.pop(i)
        return np.empty_like(like)

    def _wait_c(self) -> None:
        """Wait for the C thread; what it met becomes this writer's error (raised once)."""
        error = self._c.wait()
        self._queued.clear()
        if error is not None and self._error is None:
            self._error = error

    def drain(self) -> None:
        """Wait until every block handed over is written; raise what writing one met."""
        if self._c is not None:
            self._wait_c()
        if self._thread is not None:
            self._blocks.join()
        self._raise()

    def _raise(self) -> None:
        error = self._error
        if error is not None and not isinstance(error, _Spent):
            self._error = _Spent(error)  # later blocks are dropped, as the writer refuses them
            raise error

    def stop(self) -> None:
        """Write what is queued and end the thread (idempotent); raises what writing met."""
        if self._c is not None:
            self._wait_c()
            self._c.close()
            self._c = None
            self._spare.clear()
        if self._thread is not None:
            self._blocks.put(None)
            self._thread.join()
            self._thread = None
        self._raise()

    def write(self, time: float, values: np.ndarray) -> None:
        self.drain()
        self._writer.write(time, values)

    def flush(self) -> None:
        self.drain()
        self._writer.flush()

    def close(self) -> None:
        try:
            self.stop()
        finally:
            self._writer.close()

    def fail(self) -> Any:
        try:
            self.stop()
        except BaseException:  # noqa: BLE001 - failing already: the rows that fit are kept
            pass
        return self._writer.fail()

    @property
    def rows_written(self) -> int:
        if self._c is not None:
            self._wait_c()
        if self._thread is not None:
            self._blocks.join()
        return self._writer.rows_written

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        self.drain()
        return getattr(self._writer, name)


class _Spent:
    """An error already raised: the blocks after it are dropped, nothing is raised again."""

    def __init__(self, error: BaseException) -> None:
        self.error = error
