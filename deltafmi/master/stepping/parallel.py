"""Units stepped at the same time (``master: {threads: N}``): which may, in what groups, on what threads.

A unit's fmi2DoStep may run on another thread than the master's when nothing of the step needs
Python: fmpy calls an FMU's functions through ctypes, which lets go of Python's lock (the GIL) for
the call, so that the steps of FMUs written in C run at once on several cores. A PythonFMU FMU, and a
deltafmi FMU that does not take its steps in C, runs its component's Python in every step: it
holds the GIL, gains nothing from another thread and steps on the master's thread, as do Model
Exchange units (the master integrates
them, in Python or in its C loop) and FMI 3.0 units (their steps may stop at events the master
handles). Such a unit is *pooled* when :func:`pooled` says so.

Which steps may run at once without changing a single bit of the results:

- **Jacobi**: every unit steps from the same snapshot of the bus (all set first, all stepped, all
  read afterwards), so the pooled units' steps are one group.
- **Gauss-Seidel**: a unit sees the fresh outputs of the units before it; consecutive pooled units
  none of which takes an input from another of them are one group: all of them set, stepped
  together, read, which is what one after the other would have set and read (their steps touch
  only their own FMU). Every other unit keeps its place and its set-step-read.

Each step has the arguments it has with one thread; only who runs it differs. The C loop steps a
group on its own POSIX threads (``native/fixed_step.c``); the Python loop on a
:class:`StepPool`. A failing step is reported as it would be one after the other (the first in
stepping order), except that the others of its group have taken the step too.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, List, Optional, Sequence, Tuple

if TYPE_CHECKING:
    from concurrent.futures import ThreadPoolExecutor

__all__ = ["StepPool", "group_actions", "pooled", "runs_python"]

#: files that say an FMU runs Python: deltafmi's boot code, PythonFMU's slave module
_PYTHON_MARKERS = ("resources/deltafmi_boot.py", "resources/slavemodule.txt")
#: what a deltafmi FMU that takes its Co-Simulation steps in C carries: its compiled kernels' description
#: and the runtime module that hands the step to C (``deltafmi.runtime.cs_native``)
_STEPS_IN_C = ("resources/native_kernels.json", "resources/python/deltafmi/runtime/cs_native.py")
PULL, STEP, FETCH = "pull", "do_step", "fetch"


def runs_python(unzip_dir: str | Path) -> bool:
    """Whether the FMU unpacked in ``unzip_dir`` runs Python in every fmi2DoStep (holding the GIL).

    A deltafmi FMU whose steps run in C (compiled kernels, CVODE called from C) runs Python only at
    its events: it takes the GIL then, and lets other threads step meanwhile."""
    folder = Path(unzip_dir)
    if not any((folder / marker).is_file() for marker in _PYTHON_MARKERS):
        return False
    if not all((folder / marker).is_file() for marker in _STEPS_IN_C):
        return True
    try:  # kernels the C layer calls; functions alone (NativeKernels(functions=...)) are Python's
        return not json.loads((folder / _STEPS_IN_C[0]).read_text()).get("kernels")
    except (OSError, ValueError):
        return True


def pooled(unit: Any) -> bool:
    """Whether ``unit`` (a unit or a loop block) may step on another thread than the master's:
    an FMI 2.0 Co-Simulation unit whose FMU runs no Python in its steps."""
    if getattr(unit, "interface", "") != "CS" or getattr(unit, "fmi3", True) or getattr(unit, "clocks", None):
        return False
    if not hasattr(unit, "_steps_without_python"):
        unit._steps_without_python = not runs_python(unit.fmu.unzipDirectory)
    return unit._steps_without_python


def group_actions(blocks: Sequence[Any], algorithm: str, links: Sequence[Any]
                  ) -> Tuple[List[Tuple[Any, str, int]], List[int]]:
    """The actions of one step, (unit, PULL | STEP | FETCH, step multiple) in order, and per
    action its group (> 0: a STEP stepped at once with the consecutive STEPs of its group; 0: on
    the master's thread), for ``blocks`` in stepping order (see the module docstring)."""
    inputs_from: Dict[str, set] = {}
    for link in links:
        inputs_from.setdefault(link.target.component, set()).add(link.source.component)
    actions: List[Tuple[Any, str, int]] = []
    groups: List[int] = []

    def add(units: Sequence[Any], group: int) -> None:
        ordered = [u for u in units if pooled(u)] + [u for u in units if not pooled(u)]
        for action in (PULL, STEP, FETCH):
            for unit in units if action != STEP else ordered:
                actions.append((unit, action, unit.step_multiple))
                groups.append(group if action == STEP and pooled(unit) else 0)

    if algorithm != "gauss-seidel":
        add(blocks, 1 if sum(map(pooled, blocks)) > 1 else 0)
        return actions, groups
    level: List[Any] = []
    count = 0

    def close() -> None:
        nonlocal count
        if len(level) > 1:
            count += 1
            add(level, count)
        elif level:
            add(level, 0)
        level.clear()

    for block in blocks:
        if not pooled(block):
            close()
            add([block], 0)
        else:
            if inputs_from.get(block.name, set()) & {u.name for u in level}:
                close()  # it takes an input from one of them: after their step
            level.append(block)
    close()
    return actions, groups


class StepPool:
    """Threads that take the steps of a group in the Python loop, the calling thread among them."""

    def __init__(self, threads: int) -> None:
        self.threads = threads
        self._executor: Optional[ThreadPoolExecutor] = None
        if threads > 1:  # imported here: a run on one thread does without
            from concurrent.futures import ThreadPoolExecutor
            self._executor = ThreadPoolExecutor(max_workers=threads - 1, thread_name_prefix="deltafmi-step")

    def step(self, units: Sequence[Any], t: float, steps: Sequence[float]) -> None:
        """``unit.do_step(t, step)`` for each unit and its step, at once; the first exception in
        ``units``' order is raised once all have returned."""
        if self._executor is None or len(units) < 2:
            for unit, h in zip(units, steps):
                unit.do_step(t, h)
            return
        futures = [self._executor.submit(unit.do_step, t, h) for unit, h in zip(units[1:], steps[1:])]
        errors: List[Optional[BaseException]] = [None] * len(units)
        try:
            units[0].do_step(t, steps[0])
        except BaseException as exc:  # noqa: BLE001 - raised below, in stepping order
            errors[0] = exc
        for i, future in enumerate(futures, 1):
            errors[i] = future.exception()
        first = next((e for e in errors if e is not None), None)
        if first is not None:
            raise first

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None
