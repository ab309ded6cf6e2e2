"""A point block on a flat surface, in the surface's frame: ``n_t`` tangential coordinates (1: a
line, 2: a plane) then the normal one.

Shared by the examples: the incline (gravity tilted by ``theta``) and the stick-slip oscillator
(a spring to a wall, the surface a belt). One contact: gap ``h`` = the normal coordinate, tangent
rows ``W = [I_{n_t} 0]``.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from .law import FrictionParams
from .system import FrictionModel

__all__ = ["PlanarBlock"]


class PlanarBlock(FrictionModel):
    """Mass ``m`` under a constant force ``(f_t..., f_n)`` plus a spring ``-k (x - x_0)`` along the
    first tangent, on the surface (normal coordinate 0) moving at ``surface_speed`` along it."""

    n_c = 1

    def __init__(self, mass: float, force: Sequence[float], friction: FrictionParams, *,
                 stiffness: float = 0.0, surface_speed: float = 0.0) -> None:
        self.mass, self.force = float(mass), np.asarray(force, float)
        self.n_q = self.force.size
        self.n_t = self.n_q - 1
        self.friction, self.stiffness = friction, float(stiffness)
        self._M = self.mass * np.eye(self.n_q)
        self._H = np.eye(self.n_q)[-1:]
        self._W = np.eye(self.n_q)[:-1]
        self._u = np.zeros(self.n_t)
        self._u[0] = surface_speed

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """``m I``."""
        return self._M

    def applied_forces(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The constant force and the spring on the first coordinate."""
        spring = np.zeros(self.n_q)
        spring[0] = -self.stiffness * q[0]
        return self.force + spring

    def potential_energy(self, q: np.ndarray) -> float:
        """``-f . q + k x^2 / 2``."""
        return float(-self.force @ q + 0.5 * self.stiffness * q[0] ** 2)

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """The normal coordinate."""
        return q[-1:].copy()

    def gap_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``[0 ... 0 1]``."""
        return self._H

    def tangent_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``[I 0]``."""
        return self._W

    def surface_velocity(self, t: float) -> np.ndarray:
        """The belt's velocity."""
        return self._u

    def gap_jacobian_dot_v(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Constant Jacobian: zero."""
        return np.zeros(1)

    def tangent_jacobian_dot_v(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Constant Jacobian: zero."""
        return np.zeros(self.n_t)
