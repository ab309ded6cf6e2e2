"""Closed-form solution of fmu_src/oscillator.py: damped oscillator, wall impacts, force step."""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

P = dict(m=1.0, k=39.47841760435743, c=0.2, wall=-0.5, e=0.8, t_step=2.5, F_step=5.0)


def _free(x0: float, v0: float, force: float, tau: np.ndarray | float, p=P):
    """x, v after tau seconds of free damped motion with constant force."""
    w0 = math.sqrt(p["k"] / p["m"])
    zeta = p["c"] / (2 * math.sqrt(p["k"] * p["m"]))
    wd = w0 * math.sqrt(1 - zeta ** 2)
    xe = force / p["k"]
    y0 = x0 - xe
    a, b = y0, (v0 + zeta * w0 * y0) / wd
    decay = np.exp(-zeta * w0 * tau)
    cos, sin = np.cos(wd * tau), np.sin(wd * tau)
    x = xe + decay * (a * cos + b * sin)
    v = decay * ((-zeta * w0) * (a * cos + b * sin) + (-a * wd * sin + b * wd * cos))
    return x, v


def solution(times: np.ndarray, x0: float = 1.0, v0: float = 0.0, p=P):
    """x(t), v(t) and the impact times, on the given (sorted) times."""
    times = np.asarray(times, dtype=float)
    xs, vs = np.empty_like(times), np.empty_like(times)
    t, x, v, impacts = 0.0, x0, v0, []
    stop = times[-1]
    while True:
        force = p["F_step"] if t >= p["t_step"] else 0.0
        horizon = min(stop, p["t_step"]) if t < p["t_step"] else stop
        # next wall crossing (downwards) in (t, horizon]: scan finely, then refine
        grid = np.linspace(t, horizon, max(2, int((horizon - t) / 1e-4) + 2))
        gap = _free(x, v, force, grid - t, p)[0] - p["wall"]
        hits = np.nonzero((gap[1:] <= 0) & (gap[:-1] > 0))[0]
        t_end = horizon
        if len(hits):
            i = hits[0]
            t_end = brentq(lambda s: _free(x, v, force, s - t, p)[0] - p["wall"], grid[i], grid[i + 1], xtol=1e-15)
        mask = (times >= t) & (times <= t_end)
        xs[mask], vs[mask] = _free(x, v, force, times[mask] - t, p)
        x, v = _free(x, v, force, t_end - t, p)
        t = t_end
        if len(hits):
            v = -p["e"] * v
            impacts.append(t)
        elif t >= stop:
            return xs, vs, impacts
