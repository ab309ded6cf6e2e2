"""Where the test suite's time goes: per test, its worker, wall time and CPU time (its own and its
finished child processes'), and a summary by module and by worker.

    TIMELINE_DIR=/tmp/t PYTHONPATH=tools python -m pytest -p suite_timeline     # records
    python tools/suite_timeline.py /tmp/t                                       # summarizes

As a pytest plugin it appends one line per test to ``$TIMELINE_DIR/<worker>.tsv``: node id, start
and end (epoch seconds), CPU seconds of the worker and of the children it waited for. CPU seconds
hardly change with the machine's load, wall seconds do: on a busy machine compare CPU.
"""
from __future__ import annotations

import os
import resource
import sys
import time
from collections import defaultdict
from pathlib import Path

import pytest


def _cpu() -> tuple[float, float]:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, children.ru_utime + children.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Time one test (setup, call and teardown)."""
    folder = os.environ.get("TIMELINE_DIR")
    start, (own, children) = time.time(), _cpu()
    yield
    end, (own_after, children_after) = time.time(), _cpu()
    if folder:
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        with open(Path(folder) / f"{worker}.tsv", "a") as out:
            out.write(f"{item.nodeid}\t{start:.3f}\t{end:.3f}\t{own_after - own:.2f}\t{children_after - children:.2f}\n")


def summary(folder: Path, top: int = 30) -> str:
    """The slowest modules by CPU seconds, and each worker's span, busy and CPU seconds."""
    modules: dict = defaultdict(lambda: [0.0, 0.0, 0])
    lines = ["worker  span s  busy s  cpu s  tests"]
    for path in sorted(folder.glob("*.tsv")):
        rows = [line.split("\t") for line in path.read_text().splitlines() if line]
        starts, ends = [float(r[1]) for r in rows], [float(r[2]) for r in rows]
        cpu = sum(float(r[3]) + float(r[4]) for r in rows)
        busy = sum(e - s for s, e in zip(starts, ends))
        lines.append(f"{path.stem:6}  {max(ends) - min(starts):6.0f}  {busy:6.0f}  {cpu:5.0f}  {len(rows):5}")
        for r in rows:
            module = modules[r[0].split("::")[0]]
            module[0] += float(r[3]) + float(r[4])
            module[1] += float(r[2]) - float(r[1])
            module[2] += 1
    lines += ["", "  cpu s  wall s  tests  module"]
    for name, (cpu, wall, count) in sorted(modules.items(), key=lambda kv: -kv[1][0])[:top]:
        lines.append(f"{cpu:7.1f}  {wall:6.1f}  {count:5}  {name}")
    return "\n".join(lines)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    print(summary(Path(sys.argv[1])))
