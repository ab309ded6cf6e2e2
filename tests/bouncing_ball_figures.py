"""Figures of the talk's bouncing ball: bounce times, apex heights, energy per bounce, simulated
with the reference hybrid integrator (scipy), and the closed form of the energy each bounce gains
when a1 = 0. Kept apart from the models (:mod:`.bouncing_ball`) so that the FMUs, which carry
what their models import, carry neither this nor scipy.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np
from scipy.optimize import brentq

from hybrid_sim import HybridResult, simulate
from deltafmi.physics.contact_problems.bouncing_ball import ModelicaBouncingBall

__all__ = ["bounce_figures", "energy_gain_per_bounce", "free_flight_apexes"]


def energy_gain_per_bounce(g: float = 9.81, m: float = 1.0, a0: float = 100.0,
                           a2: float = 1e6) -> tuple[float, float]:
    """Closed form for a1 = 0: ``(q*, m (g q* - a0 q*^2/2 - a2 q*^4/4))`` with
    ``a0 q* + a2 q*^3 = g``. Below the floor the push is conservative (the loop integral of
    ``m g - m a0 q - m a2 q^3`` vanishes); above it, lambda does this work until it turns negative."""

    q_star = brentq(lambda q: a0 * q + a2 * q ** 3 - g, 0.0, g / a0 + 1.0, xtol=1e-16, rtol=1e-15)
    return q_star, m * (g * q_star - 0.5 * a0 * q_star ** 2 - 0.25 * a2 * q_star ** 4)


@dataclass
class BounceFigures:
    """Figures of one bouncing-ball run."""

    impact_times: list          #: times the contact law switches on (contact -> 1)
    apex_times: list            #: apex of each free flight after the first impact
    apex_heights: list
    apex_energies: list         #: m g h at each apex (the initial drop height first)
    energy_per_bounce: list     #: apex energy minus the previous one (> 0: energy created)
    transitions: list = field(default_factory=list)   #: (t, from, to) for every contact change
    result: Optional[HybridResult] = field(default=None, repr=False)


def free_flight_apexes(result: HybridResult, g: float,
                      in_flight: Callable[[int], bool]) -> list[tuple[float, float]]:
    """Apex (time, height) of every free-flight segment that starts rising, from the exact
    parabola through the segment's first state (``in_flight(mode)`` tells free flight)."""
    apexes = []
    flying = False
    for k in range(len(result.t)):
        now = in_flight(int(result.modes[k][0]))
        if now and not flying:
            t0, (q0, v0) = result.t[k], result.x[k][:2]
            if v0 > 0.0:
                apexes.append((float(t0 + v0 / g), float(q0 + v0 * v0 / (2.0 * g))))
        flying = now
    return apexes


def bounce_figures(a1: float = 20.0, t_end: float = 3.0, *, g: float = 9.81, m: float = 1.0,
                   a0: float = 100.0, a2: float = 1e6, q0: float = 1.0,
                   rtol: float = 1e-10, atol: float = 1e-12) -> BounceFigures:
    """Simulate the Modelica ball and report bounce times, apex heights and energy per bounce.

    With ``a1 = 0`` every entry of ``energy_per_bounce`` equals :func:`energy_gain_per_bounce`:
    the talk's "does not conserve energy" slide, in joules.
    """
    ball = ModelicaBouncingBall(g=g, m=m, a0=a0, a1=a1, a2=a2)
    result = simulate(ball, (0.0, t_end), np.array([q0, 0.0]), rtol=rtol, atol=atol)
    transitions = [(ev.t, ev.modes_before[0], ev.modes_after[0]) for ev in result.events
                   if ev.modes_before != ev.modes_after]
    impacts = [t for t, _, to in transitions if to == 1]
    apexes = [a for a in free_flight_apexes(result, g, lambda c: c != 1) if a[0] > impacts[0]] if impacts else []
    energies = [m * g * q0] + [m * g * h for _, h in apexes]
    return BounceFigures(
        impact_times=impacts,
        apex_times=[a[0] for a in apexes],
        apex_heights=[a[1] for a in apexes],
        apex_energies=energies,
        energy_per_bounce=list(np.diff(energies)),
        transitions=transitions,
        result=result,
    )
