"""Dormand-Prince 5(4) in plain Python for tiny ODEs with sign-change events.

The collision law's calibration integrates one two-state ODE to 1e-12 a few dozen times; this
keeps that on the standard library (an FMU's host may have numpy and nothing else). Events are
located by re-stepping from the last accepted point to the crossing (secant steps on the step
length, Illinois-safeguarded), so a located point is as accurate as an accepted step.
"""
from __future__ import annotations

from typing import Callable, NamedTuple, Sequence

__all__ = ["find_root", "integrate"]

State = tuple[float, ...]
Rhs = Callable[[float, State], State]
Event = Callable[[float, State], float]

# Dormand & Prince (1980), RK5(4)7M: nodes, stage weights, 5th-order weights (= last stage row,
# first same as last), and the 5th minus 4th order weights for the error estimate
_C = (0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0)
_A = ((),
      (1 / 5,),
      (3 / 40, 9 / 40),
      (44 / 45, -56 / 15, 32 / 9),
      (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
      (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656))
_B = (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84)
_E = (35 / 384 - 5179 / 57600, 0.0, 500 / 1113 - 7571 / 16695, 125 / 192 - 393 / 640,
      -2187 / 6784 + 92097 / 339200, 11 / 84 - 187 / 2100, -1 / 40)


class Crossing(NamedTuple):
    """Where an event function went from positive to <= 0."""

    t: float
    y: State


class Solution(NamedTuple):
    """The first crossing of the terminal event (None: none before ``t_end``) and the first
    crossing of each other event (None where it did not cross)."""

    terminal: Crossing | None
    others: list[Crossing | None]


def _step(f: Rhs, t: float, y: State, h: float, k1: State) -> tuple[State, State, State]:
    """One step of length ``h`` from ``(t, y)`` with ``k1 = f(t, y)``: (y_new, f(t + h, y_new),
    local error estimate)."""
    ks = [k1]
    for i in range(1, 6):
        a = _A[i]
        yi = tuple(y[j] + h * sum(a[m] * ks[m][j] for m in range(i)) for j in range(len(y)))
        ks.append(f(t + _C[i] * h, yi))
    y_new = tuple(y[j] + h * sum(_B[m] * ks[m][j] for m in range(6)) for j in range(len(y)))
    k7 = f(t + h, y_new)
    ks.append(k7)
    err = tuple(h * sum(_E[m] * ks[m][j] for m in range(7)) for j in range(len(y)))
    return y_new, k7, err


def _error_norm(y: State, y_new: State, err: State, rtol: float, atol: float) -> float:
    total = 0.0
    for j in range(len(y)):
        scale = atol + rtol * max(abs(y[j]), abs(y_new[j]))
        total += (err[j] / scale) ** 2
    return (total / len(y)) ** 0.5


def _locate(f: Rhs, event: Event, t: float, y: State, k1: State, h: float, g0: float, g1: float,
            ttol: float) -> Crossing:
    """The crossing of ``event`` inside the step (t, t + h], g0 > 0 >= g1 at its ends."""
    lo, hi, g_lo, g_hi = 0.0, h, g0, g1
    side = 0
    best = (h, _step(f, t, y, h, k1)[0])
    for _ in range(200):
        if hi - lo <= ttol:
            break
        theta = hi - g_hi * (hi - lo) / (g_hi - g_lo)  # secant (regula falsi)
        if not lo < theta < hi:
            theta = 0.5 * (lo + hi)
        y_theta = _step(f, t, y, theta, k1)[0]
        g = event(t + theta, y_theta)
        if g > 0.0:
            lo, g_lo = theta, g
            if side == -1:
                g_hi *= 0.5  # Illinois: do not let one end stay put
            side = -1
        else:
            hi, g_hi = theta, g
            best = (theta, y_theta)
            if side == 1:
                g_lo *= 0.5
            side = 1
    return Crossing(t + best[0], best[1])


def integrate(f: Rhs, y0: Sequence[float], t_end: float, terminal: Event, others: Sequence[Event] = (),
              rtol: float = 1e-12, atol: float = 1e-14, h0: float = 1e-4) -> Solution:
    """Integrate ``y' = f(t, y)`` from ``t = 0`` until ``terminal`` goes from > 0 to <= 0.

    Each of ``others`` reports its first such crossing. A crossing is located to ~1e-15 in t.
    """
    t, y = 0.0, tuple(float(v) for v in y0)
    k1 = f(t, y)
    h = h0
    g_term = terminal(t, y)
    g_others = [g(t, y) for g in others]
    found: list[Crossing | None] = [None] * len(others)
    while t < t_end:
        h = min(h, t_end - t)
        y_new, k7, err = _step(f, t, y, h, k1)
        norm = _error_norm(y, y_new, err, rtol, atol)
        if norm > 1.0:
            h *= max(0.2, 0.9 * norm ** -0.2)
            continue
        t_new = t + h
        for i, g in enumerate(others):
            g_new = g(t_new, y_new)
            if found[i] is None and g_others[i] > 0.0 >= g_new:
                found[i] = _locate(f, g, t, y, k1, h, g_others[i], g_new, 1e-15 * max(1.0, t_new))
            g_others[i] = g_new
        g_new = terminal(t_new, y_new)
        if g_term > 0.0 >= g_new:
            return Solution(_locate(f, terminal, t, y, k1, h, g_term, g_new, 1e-15 * max(1.0, t_new)), found)
        g_term = g_new
        t, y, k1 = t_new, y_new, k7
        h *= min(5.0, 0.9 * norm ** -0.2) if norm > 0.0 else 5.0
    return Solution(None, found)


def find_root(f: Callable[[float], float], lo: float, hi: float, xtol: float = 1e-14,
              rtol: float = 1e-13) -> float:
    """A root of ``f`` in ``[lo, hi]`` where ``f`` changes sign (Illinois regula falsi)."""
    f_lo, f_hi = f(lo), f(hi)
    if f_lo == 0.0:
        return lo
    if f_hi == 0.0:
        return hi
    if (f_lo > 0.0) == (f_hi > 0.0):
        raise ValueError(f"no sign change of the function between {lo} and {hi}")
    side = 0
    x = lo
    for _ in range(500):
        x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        if not lo < x < hi:
            x = 0.5 * (lo + hi)
        fx = f(x)
        if fx == 0.0:
            return x
        if (fx > 0.0) == (f_lo > 0.0):
            lo, f_lo = x, fx
            if side == -1:
                f_hi *= 0.5
            side = -1
        else:
            hi, f_hi = x, fx
            if side == 1:
                f_lo *= 0.5
            side = 1
        if hi - lo <= xtol + rtol * abs(x):
            break
    return x
