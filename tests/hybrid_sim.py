"""Reference hybrid simulation driver with FMI Model-Exchange event semantics (for tests).

Any object with ``n_states``, ``n_indicators``, ``modes``, ``initialize(t, x)``,
``derivatives(t, x)``, ``event_indicators(t, x)``, ``update(t, x) -> (x_new or None, changed)``,
``energy(x)`` and ``contact_forces(x, t)`` can be simulated: :class:`~.contact.ContactSystem` and
the Modelica bouncing ball both are.

Integration uses a scipy ODE solver (DOP853 by default, any ``scipy.integrate.OdeSolver``)
stepped by hand. After every accepted step the indicators are compared with their domains at the
step start (z > 0 versus z <= 0, the FMI 2.0 rule); the earliest domain change is located on the
step's dense output by a bracketing (Illinois) search, the state is taken on the far side of the
crossing, ``update`` runs, and the solver restarts there. solve_ivp's own event search is not used
because it reports an indicator that merely leaves exactly 0 (touching bodies at rest) as an event
at the restart instant, forever.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

__all__ = ["HybridResult", "simulate"]


@dataclass
class EventRecord:
    """One event: time, which indicator fired (-1: initial), modes before and after."""

    t: float
    indicator: int
    modes_before: tuple
    modes_after: tuple


@dataclass
class HybridResult:
    """Samples at every accepted step and at both sides of every event."""

    t: np.ndarray
    x: np.ndarray                 #: (n_samples, n_states)
    modes: np.ndarray             #: (n_samples, n_modes)
    energy: np.ndarray
    forces: np.ndarray            #: (n_samples, n_forces)
    events: list = field(default_factory=list)
    n_rhs: int = 0

    def at(self, t: float) -> np.ndarray:
        """State at the last sample at or before ``t``."""
        return self.x[np.searchsorted(self.t, t, side="right") - 1]


def _domain(z: np.ndarray) -> np.ndarray:
    return z > 0.0


def _locate(g: Callable[[float], float], a: float, b: float, side_a: bool, tol: float) -> float:
    """Smallest found ``t`` in (a, b] where ``g`` has left the domain ``side_a`` (Illinois)."""
    ga, gb = g(a), g(b)
    last = 0
    while b - a > tol:
        # regula falsi with the Illinois halving; bisection when the values give no slope
        denom = gb - ga
        m = b - gb * (b - a) / denom if denom != 0.0 and np.isfinite(denom) else 0.5 * (a + b)
        if not a < m < b:
            m = 0.5 * (a + b)
        gm = g(m)
        if (gm > 0.0) == side_a:
            a, ga = m, gm
            if last == -1:
                gb *= 0.5
            last = -1
        else:
            b, gb = m, gm
            if last == 1:
                ga *= 0.5
            last = 1
    return b


def simulate(system: Any, t_span: tuple[float, float], x0: np.ndarray, *, method: str = "DOP853",
             rtol: float = 1e-9, atol: float = 1e-12, max_step: float = np.inf,
             initialize: bool = True, max_events: int = 100000) -> HybridResult:
    """Simulate ``system`` from ``x0`` over ``t_span`` with events and discrete updates."""
    t, t_end = float(t_span[0]), float(t_span[1])
    x = np.array(x0, dtype=float)
    from scipy import integrate  # here: FMUs import this module's types, never scipy

    solver_cls = getattr(integrate, method) if isinstance(method, str) else method
    n_rhs = 0

    def rhs(tt: float, xx: np.ndarray) -> np.ndarray:
        nonlocal n_rhs
        n_rhs += 1
        return system.derivatives(tt, xx)

    ts, xs, ms, es, fs, events = [], [], [], [], [], []

    def record(tt: float, xx: np.ndarray) -> None:
        ts.append(tt)
        xs.append(xx.copy())
        ms.append(np.array(system.modes, dtype=int).copy())
        es.append(system.energy(xx))
        fs.append(np.array(system.contact_forces(xx, tt), dtype=float))

    def apply_update(tt: float, xx: np.ndarray, indicator: int) -> np.ndarray:
        before = tuple(int(m) for m in system.modes)
        new_x, _ = system.update(tt, xx)
        if new_x is not None:
            xx = np.array(new_x, dtype=float)
        events.append(EventRecord(tt, indicator, before, tuple(int(m) for m in system.modes)))
        return xx

    if initialize:
        before = tuple(int(m) for m in system.modes)
        system.initialize(t, x)
        events.append(EventRecord(t, -1, before, tuple(int(m) for m in system.modes)))
    record(t, x)
    while t < t_end:
        solver = solver_cls(rhs, t, x, t_end, rtol=rtol, atol=atol, max_step=max_step)
        side = _domain(system.event_indicators(t, x))
        fired = False
        while solver.status == "running":
            t_old = solver.t
            with np.errstate(over="ignore", invalid="ignore"):  # rejected trial stages may overflow
                solver.step()
            if solver.status == "failed":
                raise RuntimeError(f"integration failed at t={solver.t}: {solver.message}")
            z = system.event_indicators(solver.t, solver.y)
            changed = np.flatnonzero(_domain(z) != side)
            if changed.size == 0:
                record(solver.t, solver.y)
                continue
            dense = solver.dense_output()
            tol = 1e-13 * max(1.0, abs(solver.t))
            best_t, best_j = solver.t, int(changed[0])
            for j in changed:
                tj = _locate(lambda tt, j=j: system.event_indicators(tt, dense(tt))[j],
                             t_old, solver.t, bool(side[j]), tol)
                if tj < best_t:
                    best_t, best_j = tj, int(j)
            x_event = dense(best_t) if best_t < solver.t else solver.y.copy()
            record(best_t, x_event)
            t, x = best_t, apply_update(best_t, x_event, best_j)
            record(t, x)
            fired = True
            if len(events) > max_events:
                raise RuntimeError(f"more than {max_events} events before t={t} (chattering?)")
            break
        if not fired:
            t, x = solver.t, solver.y.copy()
    return HybridResult(np.array(ts), np.array(xs), np.array(ms), np.array(es), np.array(fs),
                        events, n_rhs)
