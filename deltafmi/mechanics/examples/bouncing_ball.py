"""The talk's Modelica bouncing ball, as written, and a variant on the contact framework.

:class:`ModelicaBouncingBall` reproduces ``model myBouncingBall`` statement by statement::

    b1 := h <= 0;  b2 := lambda < 0.0;  b3 := h > 0.0;  b4 := h <= 0 and hDot < 0;
    if edge(b1) and contact == 0 then contact := 1; end if;
    if contact == 1 and edge(b2) then contact := 2; end if;
    if contact == 2 and edge(b3) then contact := 0; end if;
    if contact == 2 and edge(b4) then contact := 1; end if;
    if contact == 1 or linFlag then 0 = hDotDot + a1*hDot + a0*h + a2*h^3; else lambda = 0;
    f = if linFlag then lambda else contact*lambda;  der(q) = v;  m*der(v) = -m*g + f;  h = q;

Index reduction of the contact equation with ``hDotDot = der(v) = -g + lambda/m`` gives
``lambda = m (g - a1 v - a0 q - a2 q^3)``. (The talk's slide writes ``(a0 q + a2 q^3 + g) m``:
that is this expression for a1 = 0 with the spring terms' sign flipped; the equations as written
give the sign used here, which pushes the ball out of the floor.)

Modelica semantics kept: the algorithm runs at events only (its relations are the zero-crossing
functions h, hDot, lambda), ``edge(b) = b and not pre(b)``, the ifs run in sequence on the updated
``contact``, and the event iteration repeats the algorithm with ``pre`` updated until ``contact``
stops changing. A relation is read on its indicator's FMI domain (z > 0 / z <= 0), which is how a
crossing located by the solver is made to count. Booleans start false.

With a1 = 0 the contact law does not conserve energy: lambda keeps pushing after the ball has
risen through h = 0, until ``a0 q* + a2 q*^3 = g``; each bounce gains exactly
``m (g q* - a0 q*^2/2 - a2 q*^4/4)`` (:func:`energy_gain_per_bounce`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from ..contact.collision_law import CollisionLaw
from ..contact.system import ContactSystem, LagrangianModel
from ..contact.hybrid_sim import HybridResult, simulate


class ModelicaBouncingBall:
    """``myBouncingBall`` from the talk: states ``[q, v]``, discrete ``contact`` in {0, 1, 2}."""

    n_states = 2
    n_indicators = 3

    def __init__(self, g: float = 9.81, m: float = 1.0, a0: float = 100.0, a1: float = 20.0,
                 a2: float = 1e6, lin_flag: bool = False) -> None:
        self.g, self.m, self.a0, self.a1, self.a2 = float(g), float(m), float(a0), float(a1), float(a2)
        self.lin_flag = bool(lin_flag)
        self.contact = 0
        self.pre_b = [False, False, False, False]

    @property
    def modes(self) -> np.ndarray:
        """``[contact]`` (the driver records it like contact modes)."""
        return np.array([self.contact])

    def _constrained(self, contact: int) -> bool:
        return contact == 1 or self.lin_flag

    def lam(self, x: np.ndarray, contact: Optional[int] = None) -> float:
        """Multiplier: from the contact equation when it is active, else 0."""
        contact = self.contact if contact is None else contact
        if not self._constrained(contact):
            return 0.0
        q, v = float(x[0]), float(x[1])
        return self.m * (self.g - self.a1 * v - self.a0 * q - self.a2 * q ** 3)

    def force(self, x: np.ndarray) -> float:
        """``f = if linFlag then lambda else contact*lambda``."""
        lam = self.lam(x)
        return lam if self.lin_flag else self.contact * lam

    def derivatives(self, t: float, x: np.ndarray) -> np.ndarray:
        """``der(q) = v``, ``m der(v) = -m g + f``."""
        return np.array([x[1], -self.g + self.force(x) / self.m])

    def event_indicators(self, t: float, x: np.ndarray) -> np.ndarray:
        """Zero-crossing functions of the relations: h, hDot, and lambda (1 while lambda = 0)."""
        lam_z = self.lam(x) if self._constrained(self.contact) else 1.0
        return np.array([x[0], x[1], lam_z])

    def relations(self, x: np.ndarray, contact: int) -> list[bool]:
        """``[b1, b2, b3, b4]`` for ``contact``, each read on its indicator's FMI domain."""
        h, h_dot = float(x[0]), float(x[1])
        b2 = self._constrained(contact) and self.lam(x, contact) <= 0.0
        return [h <= 0.0, b2, h > 0.0, h <= 0.0 and h_dot <= 0.0]

    def _algorithm(self, b: list[bool], contact: int) -> int:
        edge = [bi and not pi for bi, pi in zip(b, self.pre_b)]
        if edge[0] and contact == 0:
            contact = 1
        if contact == 1 and edge[1]:
            contact = 2
        if contact == 2 and edge[2]:
            contact = 0
        if contact == 2 and edge[3]:
            contact = 1
        return contact

    def update(self, t: float, x: np.ndarray) -> tuple[None, bool]:
        """Event iteration: algorithm, pre := value, repeat until ``contact`` is stable."""
        changed = False
        for _ in range(10):
            b = self.relations(x, self.contact)
            new_contact = self._algorithm(b, self.contact)
            self.pre_b = b
            if new_contact == self.contact:
                break
            self.contact = new_contact
            changed = True
        return None, changed

    def initialize(self, t: float, x: np.ndarray) -> None:
        """Start values: contact = 0, Booleans false; then the initial event iteration."""
        self.contact = 0
        self.pre_b = [False, False, False, False]
        self.update(t, x)

    def energy(self, x: np.ndarray) -> float:
        """Mechanical energy ``m v^2 / 2 + m g q``."""
        return 0.5 * self.m * float(x[1]) ** 2 + self.m * self.g * float(x[0])

    def contact_forces(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``[f]``, the force the floor applies."""
        return np.array([self.force(x)])


def energy_gain_per_bounce(g: float = 9.81, m: float = 1.0, a0: float = 100.0,
                           a2: float = 1e6) -> tuple[float, float]:
    """Closed form for a1 = 0: ``(q*, m (g q* - a0 q*^2/2 - a2 q*^4/4))`` with
    ``a0 q* + a2 q*^3 = g``. Below the floor the push is conservative (the loop integral of
    ``m g - m a0 q - m a2 q^3`` vanishes); above it, lambda does this work until it turns negative."""
    from scipy.optimize import brentq  # here: the FMU path does not need scipy

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


class BallModel(LagrangianModel):
    """Point mass above the floor: ``q`` height, gap ``h = q``."""

    n_q = 1
    n_c = 1

    def __init__(self, m: float = 1.0, g: float = 9.81) -> None:
        self.m, self.g = float(m), float(g)
        self.force = 0.0  #: extra vertical force, e.g. an FMU input

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """``[[m]]``."""
        return np.array([[self.m]])

    def applied_forces(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Weight plus the extra force."""
        return np.array([-self.m * self.g + self.force])

    def potential_energy(self, q: np.ndarray) -> float:
        """``m g q``."""
        return self.m * self.g * float(q[0])

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """``h = q``."""
        return np.array([q[0]])

    def gap_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``[[1]]``."""
        return np.array([[1.0]])

    def gap_jacobian_dot_v(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Zero."""
        return np.zeros(1)


def make_bouncing_ball(e: float = 0.8, duration: float = 1e-4, *, m: float = 1.0, g: float = 9.81,
                       q0: float = 1.0, exponent: float = 3.0, capture_speed: float = 0.05,
                       alpha0: float = 100.0, alpha1: float = 20.0) -> tuple[ContactSystem, np.ndarray]:
    """The ball on the framework with restitution ``e``; the first impact (speed sqrt(2 g q0))
    lasts exactly ``duration``. Returns the system and ``x0 = [q0, 0]``."""
    law = CollisionLaw(restitution=e, duration=duration, reference_speed=math.sqrt(2.0 * g * q0),
                       exponent=exponent)
    system = ContactSystem(BallModel(m, g), law, alpha0=alpha0, alpha1=alpha1,
                           capture_speed=capture_speed)
    return system, np.array([q0, 0.0])
