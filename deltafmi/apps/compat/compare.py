"""Does a result match its reference? The check an import result's ``passed`` rests on.

Per reference signal, as the Cross-Check tools compare (fmpy's ``validate_signal``): the
reference is resampled on a uniform grid of ``GRID`` points over its time span (linearly; held
between rows when every value is a whole number: integers, Booleans, enumerations); a band around
it is the running minimum and maximum over a window of ``WINDOW`` grid points (so that an event a
little earlier or later is no failure), widened by ``tolerance`` times the signal's range (at
least ``MAGNITUDE_FLOOR`` times its largest magnitude, and ``RANGE_FLOOR``). The result passes
when it reaches the stop time, has every reference column, and at no time stamp of the reference
(inside its span) the result, interpolated between its rows, leaves the band. The Cross-Check
tools accept up to 10 % of the samples outside a band of 10 % of the range; deltafmi asks none
outside a band of ``tolerance`` (default 1 %).
"""
from __future__ import annotations

from typing import List, Optional

import numpy as np

from .files import Table

__all__ = ["DEFAULT_TOLERANCE", "mismatches"]

#: default band half-width, relative to each signal's range
DEFAULT_TOLERANCE = 1e-2
#: smallest range a band is computed from: a signal that is zero up to round-off (1e-15) is
#: compared as if it spanned this much ...
RANGE_FLOOR = 1e-6
#: ... and one that barely moves (a conserved energy) as if it spanned this part of its magnitude
MAGNITUDE_FLOOR = 1e-3
GRID = 1000
#: band window in grid points (0.5 % of the span each side)
WINDOW = 11


def mismatches(result: Table, reference: Table, stop: Optional[float] = None,
               tolerance: float = DEFAULT_TOLERANCE) -> List[str]:
    """What keeps ``result`` from matching ``reference``, one line per problem; empty: it matches."""
    problems = []
    span = reference.time[-1] - reference.time[0]
    if stop is not None and (len(result.time) == 0 or result.time[-1] < stop - 1e-9 * max(abs(stop), span, 1.0)):
        end = result.time[-1] if len(result.time) else float("nan")
        problems.append(f"the result ends at t = {end:.9g} s, before the stop time {stop:.9g} s")
    for name, ref in reference.columns.items():
        if name not in result.columns:
            problems.append(f"{name}: not in the result")
            continue
        ref = ref.reshape(len(reference.time), -1)
        res = np.asarray(result.columns[name], dtype=float).reshape(len(result.time), -1)
        if res.shape[1] != ref.shape[1]:
            problems.append(f"{name}: {res.shape[1]} elements in the result, {ref.shape[1]} in the reference")
            continue
        for i in range(ref.shape[1]):
            label = name if ref.shape[1] == 1 else f"{name}[{i + 1}]"
            outside = _outside(result.time, res[:, i], reference.time, ref[:, i], tolerance)
            if outside:
                t, value, low, high = outside
                problems.append(f"{label}: {value:.9g} at t = {t:.9g} s is outside the band "
                                f"[{low:.9g}, {high:.9g}] around the reference")
    return problems


def _outside(t: np.ndarray, y: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray,
             tolerance: float) -> Optional[tuple]:
    """The first reference time stamp at which ``y`` (interpolated between its rows) is outside
    the band around ``y_ref``: (time, value, low, high). Only where the reference has samples:
    between them it says nothing of what the signal does (a bounce's lowest point, say)."""
    t_ref = _strictly_increasing(t_ref)
    grid = np.linspace(t_ref[0], t_ref[-1], GRID)
    if np.all(y_ref == np.round(y_ref)):  # integer, Boolean, enumeration: held between rows
        sampled = y_ref[np.clip(np.searchsorted(t_ref, grid, side="right") - 1, 0, len(y_ref) - 1)]
    else:
        sampled = np.interp(grid, t_ref, y_ref)
    low, high = sampled.copy(), sampled.copy()
    # the reference's own samples keep their extremes (a short peak between grid points)
    nearest = np.clip(np.searchsorted(grid, t_ref), 0, GRID - 1)
    np.minimum.at(low, nearest, y_ref)
    np.maximum.at(high, nearest, y_ref)
    low, high = _running(np.minimum, low), _running(np.maximum, high)
    lowest, highest = float(np.min(y_ref)), float(np.max(y_ref))
    width = tolerance * max(highest - lowest, MAGNITUDE_FLOOR * max(abs(lowest), abs(highest)), RANGE_FLOOR)
    y = np.interp(t_ref, _strictly_increasing(t), y)
    t = t_ref
    inside_span = (t > grid[0]) & (t < grid[-1])
    low_t, high_t = np.interp(t, grid, low) - width, np.interp(t, grid, high) + width
    bad = inside_span & ((y < low_t) | (y > high_t) | ~np.isfinite(y))
    if not np.any(bad):
        return None
    k = int(np.argmax(bad))
    return float(t[k]), float(y[k]), float(low_t[k]), float(high_t[k])


def _running(reduce: np.ufunc, values: np.ndarray) -> np.ndarray:
    """``reduce`` (minimum or maximum) over a centred window of ``WINDOW`` points."""
    half = WINDOW // 2
    padded = np.pad(values, half, mode="edge")
    out = padded[:len(values)].copy()
    for shift in range(1, WINDOW):
        out = reduce(out, padded[shift:shift + len(values)])
    return out


def _strictly_increasing(t: np.ndarray) -> np.ndarray:
    """The time with repeated stamps (an event's two rows) nudged apart, for interpolation."""
    t = np.array(t, dtype=float)
    for k in range(1, len(t)):
        if t[k] <= t[k - 1]:
            t[k] = np.nextafter(t[k - 1], np.inf) if t[k - 1] != 0 else 1e-300
    return t
