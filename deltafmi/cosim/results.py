"""Result files: rows streamed to CSV while the run goes on, and read back for plots and tests.

The file starts with a ``time`` column followed by one column per recorded ``comp.var``. An event
shows as two rows with the same time stamp (values just before and just after). Rows are buffered
in a small numpy block and written out whenever it fills up or half a second has passed, so a
failing or killed run keeps (almost) everything up to the failure.
"""
from __future__ import annotations

import time as _time
from pathlib import Path
from typing import Dict, List, Sequence, Tuple

import numpy as np

_FLUSH_SECONDS = 0.5


class CsvWriter:
    """Appends rows ``time, values...`` to a CSV file."""

    def __init__(self, path: str | Path, names: Sequence[str], chunk: int = 512) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "w", newline="")
        self._file.write(",".join(["time", *names]) + "\n")
        self._file.flush()
        self._rows = np.empty((chunk, len(names) + 1))
        self._n = 0
        self._last_flush = _time.monotonic()
        self.rows_written = 0

    def write(self, time: float, values: np.ndarray) -> None:
        """Queue one row; it reaches the file at the next flush."""
        row = self._rows[self._n]
        row[0] = time
        row[1:] = values
        self._n += 1
        if self._n == len(self._rows) or (self._n & 63 == 0 and
                                           _time.monotonic() - self._last_flush > _FLUSH_SECONDS):
            self.flush()

    def flush(self) -> None:
        """Write the queued rows and flush the file."""
        if self._n:
            text = "\n".join(",".join(map(repr, row)) for row in self._rows[: self._n].tolist())
            self._file.write(text + "\n")
            self.rows_written += self._n
            self._n = 0
        self._file.flush()
        self._last_flush = _time.monotonic()

    def close(self) -> None:
        """Flush and close (idempotent)."""
        if not self._file.closed:
            self.flush()
            self._file.close()


class RowSampler:
    """Gathers the recorded variables from the master's buses into one float row."""

    def __init__(self, parts: Sequence[Tuple[np.ndarray, Sequence[int], Sequence[int]]], width: int) -> None:
        """``parts``: (bus, bus indices, row columns) per FMI type."""
        self.row = np.zeros(width)
        self._parts = [(bus, np.asarray(index, np.intp), np.asarray(columns, np.intp))
                       for bus, index, columns in parts if len(index)]

    def sample(self) -> np.ndarray:
        """The current values of every recorded variable."""
        row = self.row
        for bus, index, columns in self._parts:
            row[columns] = bus[index]
        return row


def read_csv(path: str | Path) -> Tuple[List[str], np.ndarray]:
    """Column names and data (rows x columns, time first) of a result file."""
    with open(path) as file:
        names = file.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return names, data


def columns(path: str | Path) -> Dict[str, np.ndarray]:
    """A result file as ``{name: column}`` (``time`` included)."""
    names, data = read_csv(path)
    return {name: data[:, i] for i, name in enumerate(names)}
