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
``m (g q* - a0 q*^2/2 - a2 q*^4/4)`` (tests/bouncing_ball_figures.py: ``energy_gain_per_bounce``).
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from ..contact.collision_law import CollisionLaw
from ..contact.system import ContactSystem, LagrangianModel
from .ball_kernels import (ModelicaBall, modelica_derivatives, modelica_energy, modelica_force, modelica_indicators,
                           modelica_lam)

__all__ = ["BallModel", "ModelicaBouncingBall", "make_bouncing_ball"]


def _floats(x) -> list[float]:
    return [float(v) for v in x[:2]]


class ModelicaBouncingBall:
    """``myBouncingBall`` from the talk: states ``[q, v]``, discrete ``contact`` in {0, 1, 2}."""

    n_states = 2
    n_indicators = 3

    def __init__(self, g: float = 9.81, m: float = 1.0, a0: float = 100.0, a1: float = 20.0,
                 a2: float = 1e6, lin_flag: bool = False) -> None:
        self.g, self.m, self.a0, self.a1, self.a2 = float(g), float(m), float(a0), float(a1), float(a2)
        self.lin_flag = bool(lin_flag)
        #: the parameters as the kernels (.ball_kernels, compiled into its FMU) take them
        self.params = ModelicaBall(self.g, self.m, self.a0, self.a1, self.a2, self.lin_flag)
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
        return modelica_lam(self.params, contact, _floats(x))

    def force(self, x: np.ndarray) -> float:
        """``f = if linFlag then lambda else contact*lambda``."""
        return modelica_force(self.params, self.contact, _floats(x))

    def derivatives(self, t: float, x: np.ndarray) -> np.ndarray:
        """``der(q) = v``, ``m der(v) = -m g + f``."""
        return np.array(modelica_derivatives(self.params, self.contact, _floats(x)))

    def event_indicators(self, t: float, x: np.ndarray) -> np.ndarray:
        """Zero-crossing functions of the relations: h, hDot, and lambda (1 while lambda = 0)."""
        return np.array(modelica_indicators(self.params, self.contact, _floats(x)))

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
        return modelica_energy(self.params, _floats(x))

    def contact_forces(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``[f]``, the force the floor applies."""
        return np.array([self.force(x)])


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
