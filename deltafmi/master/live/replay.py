"""``--replay``: a live source's values taken back from the results file of the run that received
them, so the run repeats bit for bit without the device, the network or the wall clock.

The row of a communication point ``t`` holds what the source had delivered by ``t`` (see
:mod:`.units`); several rows may share a time (an event's before and after rows): the last
one holds the value the next step used. A replay may stop earlier than the run it repeats (a
run ended by Ctrl-C at the time it says), not later.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from deltafmi.errors import BadInput

from ..scenario.spec import grid_steps

__all__ = ["ReplaySource", "Grid"]


class ReplaySource:
    """A live source whose values are the columns ``<name>.<signal>`` of a recorded result."""

    def __init__(self, name: str, signals: Sequence[str], result, path: Path, grid: "Grid") -> None:
        """``result``: the :class:`~deltafmi.master.results.result.Result` read from ``path``;
        ``grid``: the replaying run's communication points."""
        self.name = name
        self.signals: Tuple[str, ...] = tuple(signals)
        self.path = path
        self.grid = grid
        missing = [f"{name}.{s}" for s in self.signals if f"{name}.{s}" not in result.names]
        if missing:
            raise BadInput(f"--replay {path}: no column {', '.join(missing)}: the file was not recorded "
                           f"from a run with the live source '{name}'")
        columns = np.column_stack([np.asarray(result[f"{name}.{s}"], dtype=float) for s in self.signals])
        self._rows = {key: columns[i] for key, i in grid.rows(result.time).items()}
        end = grid.key(grid.stop)
        if end not in self._rows:  # a last point off the grid: what had arrived by the point before
            self._rows[end] = self._rows[grid.key(grid.points[-2])]
        self.replayed = 0

    def open(self, warn: Callable[[str], None]) -> None:
        pass

    def poll(self, t: float) -> Optional[Dict[str, float]]:
        row = self._rows.get(self.grid.key(t))
        if row is None:  # check ran before: only a run that changed its own grid gets here
            raise BadInput(f"--replay {self.path}: no row at t = {t!r}")
        self.replayed += 1
        return dict(zip(self.signals, row.tolist()))

    def counters(self) -> Dict[str, int]:
        return {"replayed": self.replayed}

    def close(self) -> None:
        pass


class Grid:
    """The communication points of a fixed-step run, and which row of a recorded result stands
    for each: points are matched by their index k on ``start + k * step`` (two runs may add up
    the same point an ulp apart: a run stopped at 0.009 s wrote its last row at 9 * 0.001 =
    0.009000000000000001 s), a point off the grid (a last point at a stop between two points)
    by its time."""

    def __init__(self, start: float, stop: float, step: float) -> None:
        self.start, self.stop, self.step = start, stop, step
        n = grid_steps(start, stop, step)
        self.points = [start + k * step for k in range(n)] + [stop]

    def key(self, t: float) -> Tuple[str, float]:
        k = round((t - self.start) / self.step)
        if abs(t - (self.start + k * self.step)) <= 1e-9 * self.step:
            return ("k", float(k))
        return ("t", t)

    def rows(self, times: np.ndarray) -> Dict[Tuple[str, float], int]:
        """Key -> the last row of ``times`` at that point (an event's after-row)."""
        return {self.key(float(t)): i for i, t in enumerate(times)}

    def check(self, result, path: Path) -> None:
        """:class:`BadInput` unless ``result`` has a row at every point (the run it recorded had
        the same start and step, and went at least as far); a last point between two of the
        grid's takes the values of the point before (nothing steps after it)."""
        keys = self.rows(result.time)
        needed = self.points if self.key(self.stop)[0] == "k" else self.points[:-1]
        absent = [t for t in needed if self.key(t) not in keys]
        if absent:
            times = result.time
            recorded = f"{times[0]:g} .. {times[-1]:g} s" if len(times) else "no rows"
            raise BadInput(f"--replay {path}: no row at t = {absent[0]:.9g} s (it records {recorded}); replay "
                           "with the start and step of the run it recorded, and a stop it reached")
