"""Metrics: one number per run from its recorded signals (no code from YAML, only these).

The signal of a metric is one recorded variable or array (``plant.z``), or the difference of two
of the same size (``plant.z - trajectory.r``). A one-element signal stays signed unless a ``norm``
is given (then its absolute value); a vector is reduced at every sample to its norm: Euclidean
(default), ``inf`` (largest magnitude) or ``1``. Over the samples in the window (both ends
included; default the whole run):

``max`` / ``min`` / ``final``
    of the recorded samples.
``mean`` / ``rms``
    time averages, trapezoidal rule over the samples (the two rows of an event have the same
    time stamp and add nothing): ``integral(s dt) / T``, ``sqrt(integral(s^2 dt) / T)``.
``at``
    the value at ``time``: the last row at that time (the value after an event there), else
    linear interpolation between the rows around it; NaN outside the run.
``settling_time``
    how long after the window start the signal enters ``|s - target| <= band`` for good
    (``target`` defaults to the final value); the entry is interpolated linearly between the
    last sample outside the band and the next one; 0 when it never leaves it, NaN when it ends
    outside it.
``first_crossing``
    the time (absolute) at which the signal first crosses ``level`` in ``direction`` (rising,
    falling, either), interpolated linearly; NaN when it never does.
``alternation``
    the amplitude of a step-to-step oscillation: per recorded element, over consecutive rows, the
    binomial high-pass ``a_i = (s_i-2 - 4 s_i-1 + 6 s_i - 4 s_i+1 + s_i+2) / 16`` (a signal
    alternating +-A about a smooth one gives ``|a| = A``; a smooth one ``h^4 |s^(4)| / 16`` for a
    row spacing ``h``: a 30 Hz swing of 10 N sampled at 1 kHz reads 8e-4 N), reduced per row by the
    norm before the signal's own reduction (a vector flipping sign keeps its amplitude), then its
    RMS over the rows in the window: a sustained oscillation reads its amplitude, a transient of a
    few rows in a long window little. Rows sharing a time stamp (an event) count once, the last.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Optional, Sequence, Tuple

import numpy as np

from .spec import MetricSpec, Window

__all__ = ["Metric", "alternation", "first_crossing", "reduce", "settling_time", "statistic", "value_at"]


@dataclass(frozen=True)
class Metric:
    """A metric with its signal resolved to recorded scalar columns (``plant.z[1]``, ...)."""

    spec: MetricSpec
    left: Tuple[str, ...]
    right: Tuple[str, ...] = ()
    unit: str = ""

    @property
    def name(self) -> str:
        """The metric's name (its result column)."""
        return self.spec.name

    def signal(self, columns: Mapping[str, np.ndarray]) -> np.ndarray:
        """The metric's signal at every recorded row (computed once per set of ``columns`` that
        keeps ``signals``, a dict: metrics of the same signal and norm share it)."""
        kept = getattr(columns, "signals", None)
        key = (self.left, self.right, self.spec.norm)
        if kept is not None and key in kept:
            return kept[key]
        if len(self.left) < 8:  # column by column (see reduce): the same numbers, far fewer loops
            # the recorded columns themselves where ``columns`` can give them (no copies: element
            # by element arithmetic gives the same numbers on them)
            column = getattr(columns, "view", None) or (lambda name: np.asarray(columns[name], dtype=float))
            elements = [column(name) for name in self.left]
            if self.right:
                elements = [e - column(name) for e, name in zip(elements, self.right)]
            signal = np.ascontiguousarray(_reduced(elements, self.spec.norm))
        else:
            signal = reduce(self._values(columns), self.spec.norm)
        if kept is not None:
            kept[key] = signal
        return signal

    def _values(self, columns: Mapping[str, np.ndarray]) -> np.ndarray:
        """Rows x elements of the signal before its norm."""
        values = _block(columns, self.left)
        if self.right:
            values = values - _block(columns, self.right)
        return values

    def value(self, columns: Mapping[str, np.ndarray]) -> float:
        """The metric of one run; ``columns`` holds ``time`` and the recorded variables."""
        time = np.asarray(columns["time"], dtype=float)
        if self.spec.statistic == "alternation":
            return alternation(time, self._values(columns), self.spec.norm, self.spec.window)
        window = getattr(columns, "window", None)  # the window's rows found by bisection
        rows = window(self.spec.window.start, self.spec.window.stop) if window is not None else None
        return statistic(self.spec, time, self.signal(columns), rows)


def _block(columns: Mapping[str, np.ndarray], names: Tuple[str, ...]) -> np.ndarray:
    """The named columns as rows x columns, floats (in one gather where ``columns`` offers
    ``block``: the same numbers as stacking them one by one)."""
    block = getattr(columns, "block", None)
    if block is not None:
        return block(names)
    return np.column_stack([np.asarray(columns[c], dtype=float) for c in names])


def reduce(values: np.ndarray, norm: str | None) -> np.ndarray:
    """Rows x elements -> one value per row: the element itself (one element, no norm), else the norm."""
    if values.shape[1] < 8:
        return _reduced([values[:, j] for j in range(values.shape[1])], norm)
    if norm == "inf":
        return np.max(np.abs(values), axis=1)
    if norm == "1":
        return np.sum(np.abs(values), axis=1)
    return np.sqrt(np.sum(values * values, axis=1))


def _reduced(elements: Sequence[np.ndarray], norm: str | None) -> np.ndarray:
    """:func:`reduce` of fewer than 8 elements given as columns: numpy sums a row of fewer than 8
    elements one after the other, and column after column is the same sum in a few long loops."""
    if len(elements) == 1 and norm is None:
        return elements[0]
    if norm == "inf":
        largest = np.abs(elements[0])
        for element in elements[1:]:
            np.maximum(largest, np.abs(element), out=largest)
        return largest
    if norm == "1":
        total = np.abs(elements[0])
        for element in elements[1:]:
            total += np.abs(element)
        return total
    total = elements[0] * elements[0]
    for element in elements[1:]:
        total += element * element
    return np.sqrt(total, out=total)


def statistic(spec: MetricSpec, time: np.ndarray, signal: np.ndarray, rows: Optional[slice] = None) -> float:
    """``spec.statistic`` of ``signal`` sampled at ``time`` (see the module docstring); ``rows``:
    the rows in ``spec.window`` when the caller knows them."""
    if spec.statistic == "at":
        return value_at(time, signal, _given(spec.time))
    time, signal = windowed(time, signal, spec.window) if rows is None else (time[rows], signal[rows])
    if len(time) == 0:
        return math.nan
    kind = spec.statistic
    if kind == "max":
        return float(np.max(signal))
    if kind == "min":
        return float(np.min(signal))
    if kind == "final":
        return float(signal[-1])
    if kind in ("mean", "rms"):
        span = time[-1] - time[0]
        if span <= 0:
            return float(signal[-1] if kind == "mean" else abs(signal[-1]))
        if kind == "mean":
            return float(np.trapezoid(signal, time) / span)
        return float(math.sqrt(np.trapezoid(signal * signal, time) / span))
    if kind == "settling_time":
        start = spec.window.start if spec.window.start is not None else time[0]
        target = spec.target if spec.target is not None else signal[-1]
        return settling_time(time, signal, target, _given(spec.band)) - start
    if kind == "first_crossing":
        return first_crossing(time, signal, _given(spec.level), spec.direction)
    raise ValueError(f"unknown statistic '{kind}'")


def alternation(time: np.ndarray, values: np.ndarray, norm: str | None, window: Window) -> float:
    """The RMS amplitude of the step-to-step alternation of ``values`` (rows x elements) over the
    rows in ``window`` (module docstring); NaN with fewer than five rows."""
    last = np.ones(len(time), dtype=bool)
    last[:-1] = time[1:] != time[:-1]
    time, values = time[last], values[last]
    if len(time) < 5:
        return math.nan
    high = (values[:-4] - 4.0 * values[1:-3] + 6.0 * values[2:-2] - 4.0 * values[3:-1] + values[4:]) / 16.0
    if values.shape[1] == 1 and norm is None:
        amplitude = np.abs(high[:, 0])
    else:
        amplitude = reduce(high, "2" if norm is None else norm)
    _, amplitude = windowed(time[2:-2], amplitude, window)
    if len(amplitude) == 0:
        return math.nan
    return float(math.sqrt(np.mean(amplitude * amplitude)))


def _given(value: float | None) -> float:
    """An option the study checks made sure of."""
    if value is None:
        raise ValueError("a statistic is missing its option")
    return value


def windowed(time: np.ndarray, signal: np.ndarray, window: Window) -> Tuple[np.ndarray, np.ndarray]:
    """The rows with ``window.start <= t <= window.stop``."""
    keep = np.ones(len(time), dtype=bool)
    if window.start is not None:
        keep &= time >= window.start
    if window.stop is not None:
        keep &= time <= window.stop
    return time[keep], signal[keep]


def value_at(time: np.ndarray, signal: np.ndarray, t: float) -> float:
    """The last row at ``t``, else linear interpolation; NaN outside the recorded span."""
    if len(time) == 0 or t < time[0] or t > time[-1]:
        return math.nan
    i = int(np.searchsorted(time, t, side="right")) - 1
    if time[i] == t or i + 1 >= len(time):
        return float(signal[i])
    fraction = (t - time[i]) / (time[i + 1] - time[i])
    return float(signal[i] + fraction * (signal[i + 1] - signal[i]))


def settling_time(time: np.ndarray, signal: np.ndarray, target: float, band: float) -> float:
    """The time from which ``|signal - target| <= band`` holds to the end (interpolated entry);
    ``time[0]`` when it always holds, NaN when it does not hold at the end."""
    excess = np.abs(signal - target) - band
    outside = np.nonzero(excess > 0)[0]
    if len(outside) == 0:
        return float(time[0])
    i = int(outside[-1])
    if i + 1 >= len(time):
        return math.nan
    return _interpolated_zero(time, excess, i)


def first_crossing(time: np.ndarray, signal: np.ndarray, level: float, direction: str = "either") -> float:
    """The first time ``signal`` crosses ``level`` (rising: from below to at-or-above; falling:
    from above to at-or-below), interpolated linearly; NaN when it never does."""
    g = signal - level
    rising = (g[:-1] < 0) & (g[1:] >= 0)
    falling = (g[:-1] > 0) & (g[1:] <= 0)
    hits = rising if direction == "rising" else falling if direction == "falling" else rising | falling
    found = np.nonzero(hits)[0]
    if len(found) == 0:
        return math.nan
    return _interpolated_zero(time, g, int(found[0]))


def _interpolated_zero(time: np.ndarray, g: np.ndarray, i: int) -> float:
    """Where the straight line through (time[i], g[i]) and (time[i+1], g[i+1]) is zero."""
    dt, dg = time[i + 1] - time[i], g[i + 1] - g[i]
    if dt == 0 or dg == 0:
        return float(time[i + 1])
    return float(time[i] + dt * (-g[i] / dg))
