"""Adaptive communication step with rollback (every FMU must support fmi2Get/SetFMUstate).

Each macro step is tried, its coupling error estimated, and either accepted or rolled back and
retried with a smaller step. Two estimates:

* ``double-step``: one step of H against two of H/2 from the same snapshot; the difference of all
  fetched Real values is the (Richardson) error of the zero-order-hold coupling, O(H^2) per step.
* ``io-gap``: after one step, how far every coupling signal (each Real input, as its source
  gives it) moved over the step: the gap a held input leaves, O(H) per step; cheaper (no second
  pass).

The error is scaled as ``|e| / (abs_tolerance + tolerance * |value|)``; a step is accepted when its
maximum is <= 1. Events found during a trial are recorded only if the trial is kept.

The loop drives anything that offers :class:`SteppedSystem` (the master does); it imports nothing
of the master.
"""
from __future__ import annotations

from typing import Any, Dict, List, Protocol, Sequence

import numpy as np

from ..scenario.spec import Adaptive
from deltafmi.master.stepping.algebraic_loops import Stepper
from .unit_base import Unit, instant_margin

__all__ = ["run_adaptive"]

_SAFETY, _SHRINK, _GROW = 0.9, 0.2, 2.0


class SteppedSystem(Protocol):
    """What the adaptive loop needs of a master: its span, units and buses, one communication
    step of everything, snapshots, held-back event rows, and the row at the end of a step."""

    start: float
    stop: float
    step: float
    #: where the run is, the end of the step under way, accepted and rejected steps
    time: float
    step_end: float
    steps: int
    rejected: int
    units: List[Unit]
    buses: Dict[str, np.ndarray]

    def stepping_blocks(self) -> List[Stepper]: ...

    def step_all(self, blocks: Sequence[Stepper], t: float, step: float) -> None: ...

    def save(self) -> Any: ...

    def restore(self, snapshot: Any) -> None: ...

    def release(self, snapshot: Any) -> None: ...

    def defer_events(self) -> None: ...

    def commit_events(self) -> None: ...

    def drop_events(self) -> None: ...

    def record_step(self, t: float) -> None: ...

    def warn(self, message: str) -> None: ...


def run_adaptive(master: SteppedSystem, settings: Adaptive) -> None:
    """Step ``master`` from its start to its stop time with an adaptive communication step."""
    h = master.step
    h_min = settings.min_step or h / 1000.0
    h_max = settings.max_step or 100.0 * h
    blocks = master.stepping_blocks()
    for unit in master.units:
        unit.no_prior_state = 0  # we will set earlier states again
    double = settings.error_estimate == "double-step"
    order = 2.0 if double else 1.0
    t, stop = master.start, master.stop
    warned = False
    while t < stop - instant_margin(stop):
        step = min(h, stop - t)
        master.step_end = t + step
        snapshot = master.save()
        master.defer_events()
        try:
            if double:
                error = _double_step_error(master, blocks, t, step, snapshot, settings)
            else:
                before = master.buses["Real"].copy()
                master.step_all(blocks, t, step)
                error = _io_gap_error(master.units, before, settings)
            factor = _SAFETY * error ** (-1.0 / order) if error > 0 else _GROW
            if error <= 1.0 or step <= h_min * (1 + 1e-9):
                if error > 1.0 and not warned:
                    master.warn(f"adaptive step: error estimate {error:.3g} above tolerance at the minimum "
                                f"step {h_min:g} s (t = {t:.9g} s); accepting")
                    warned = True
                t = t + step if step < stop - t else stop
                master.time = t
                master.steps += 1
                master.commit_events()
                master.record_step(t)
            else:
                master.restore(snapshot)
                master.drop_events()
                master.rejected += 1
            h = min(h_max, max(h_min, step * min(_GROW, max(_SHRINK, factor))))
        finally:
            master.release(snapshot)


def _double_step_error(master: SteppedSystem, blocks: List[Stepper], t: float, step: float, snapshot: Any,
                       settings: Adaptive) -> float:
    master.step_all(blocks, t, step)
    coarse = master.buses["Real"].copy()
    master.restore(snapshot)
    master.drop_events()
    half = 0.5 * step
    master.step_all(blocks, t, half)
    master.step_all(blocks, t + half, half)
    fine = master.buses["Real"]
    scale = settings.abs_tolerance + settings.tolerance * np.maximum(np.abs(fine), np.abs(coarse))
    return float(np.max(np.abs(fine - coarse) / scale)) if len(fine) else 0.0


def _io_gap_error(units: List[Unit], before: np.ndarray, settings: Adaptive) -> float:
    error = 0.0
    for unit in units:
        for inputs in unit.inputs:
            if inputs.values.dtype != np.float64:
                continue
            start, end = before[inputs.index], inputs.bus[inputs.index]
            if inputs.factor is not None:
                start, end = start * inputs.factor, end * inputs.factor
            scale = settings.abs_tolerance + settings.tolerance * np.abs(end + inputs.offset)
            error = max(error, float(np.max(np.abs(end - start) / scale)))
    return error
