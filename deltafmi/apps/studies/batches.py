"""Which cases go into the next Dask task, and what happens to the cases of a task whose worker died.

One task per case costs a round trip through the scheduler per case, during which the worker
waits: 3 to 6 ms on a 2-core machine, 2-3 % of a flagship case. A task therefore carries a
*batch* of cases, sized from the cases' measured wall time so that it holds about
:data:`TASK_SECONDS` of work. Batches stay small enough that the end of the study does not wait
on one long task (at most the remaining cases over twice the workers), and the first tasks carry
one case each, until results tell how long a case takes.

When the workers stream each case's result to the client as it finishes (a study without time
series), a batch loses nothing when the study stops, and batches grow up to
:data:`STREAMED_BATCH` cases of about :data:`STREAMED_SECONDS`; with one worker the end needs no
balancing and no case needs timing first: a batch takes all the cases left, up to
:data:`STREAMED_BATCH` (a task stops between two cases when the study is stopped).

A worker holds one task at a time (``worker-saturation`` 1.0), so a worker that dies takes down
exactly one task. Its cases then run again one per task, which is the retry: a case that kills
the worker running it alone is recorded as failed (see :mod:`deltafmi.apps.studies.driver`). With
results streamed, only the first case of the task that had not finished runs again alone (the one
that ran when the worker died); the rest go back to the cases waiting.
"""
from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass
from typing import Deque, Iterable, List

from .cases import Case

__all__ = ["Batch", "Batcher", "MAX_BATCH", "STREAMED_BATCH", "STREAMED_SECONDS", "TASK_SECONDS"]

#: seconds of cases one task aims to carry: Dask's few milliseconds per task become ~1 % of it
TASK_SECONDS = 1.0
#: cases one task carries at most (what an interrupted study may have to run again, per worker)
MAX_BATCH = 16
#: the same with each case's result streamed to the client as it finishes
STREAMED_SECONDS = 5.0
STREAMED_BATCH = 256
#: cases' wall times the size is taken from (the latest)
RECENT = 32


@dataclass
class Batch:
    """The cases of one task; ``alone`` for a case run again after its worker died."""

    cases: List[Case]
    alone: bool = False


class Batcher:
    """Hands out the cases still to run as batches, the cases to run again first."""

    def __init__(self, cases: Iterable[Case], workers: int, streamed: bool = False) -> None:
        """``streamed``: the workers send each case's result as it finishes (see the module)."""
        self.workers = max(1, workers)
        self.streamed = streamed
        self._waiting: Deque[Case] = deque(cases)
        self._again: Deque[Case] = deque()
        self._walls: Deque[float] = deque(maxlen=RECENT)

    def __bool__(self) -> bool:
        return bool(self._waiting or self._again)

    def observe(self, wall_time: float) -> None:
        """One case finished in ``wall_time`` seconds (on its worker)."""
        self._walls.append(wall_time)

    def size(self) -> int:
        """Cases for the next batch of new cases."""
        alone = self.streamed and self.workers == 1  # nothing to balance, nothing lost when stopped
        if not self._walls:
            return min(len(self._waiting), STREAMED_BATCH) if alone else 1
        per_case = max(statistics.median(self._walls), 1e-4)
        seconds, most = (STREAMED_SECONDS, STREAMED_BATCH) if self.streamed else (TASK_SECONDS, MAX_BATCH)
        wanted = max(1, round(seconds / per_case))
        share = len(self._waiting) if alone else len(self._waiting) // (2 * self.workers)
        return max(1, min(wanted, most, share))

    def next(self) -> Batch:
        """The next batch (call only while the batcher is not empty)."""
        if self._again:
            return Batch([self._again.popleft()], alone=True)
        return Batch([self._waiting.popleft() for _ in range(self.size())])

    def run_again(self, batch: Batch) -> None:
        """The worker running ``batch`` died: each of its cases (those without a result yet) runs
        again, alone; streamed, only the first, and the others wait their turn as before."""
        if self.streamed and batch.cases:
            self._again.append(batch.cases[0])
            self._waiting.extendleft(reversed(batch.cases[1:]))
        else:
            self._again.extend(batch.cases)
