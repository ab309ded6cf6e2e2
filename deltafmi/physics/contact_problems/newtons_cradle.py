"""Newton's cradle: N balls in a row, as a free chain or as pendulums, on the contact framework.

Ball 1 (the striker, leftmost) moves towards +x. Contact i is between balls i and i+1 with gap
``|c_{i+1} - c_i| - r_i - r_{i+1}``. Models are allocated for ``n_max`` balls; balls beyond ``n``
are frozen (FMI 2.0 needs fixed state and indicator counts).
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from ..contact.collision_law import CollisionLaw
from ..contact.system import ContactSystem, LagrangianModel
from ..contact.law_kernels import law_constants
from .contact_kernels import KernelContactSystem
from .cradle_kernels import N_BALLS, CradleParams, cradle_evaluate

__all__ = ["ChainModel", "make_cradle", "momentum"]


class ChainModel(LagrangianModel):
    """Balls on a line (no gravity along it): ``q = x`` centres, ``M = diag(m)``."""

    def __init__(self, masses: np.ndarray, radii: np.ndarray) -> None:
        self.masses = np.asarray(masses, float)
        self.radii = np.asarray(radii, float)
        self.n_q = len(self.masses)
        self.n_c = self.n_q - 1
        self._M = np.diag(self.masses)
        self._H = np.zeros((self.n_c, self.n_q))
        for i in range(self.n_c):
            self._H[i, i], self._H[i, i + 1] = -1.0, 1.0

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Constant diagonal mass matrix."""
        return self._M

    def applied_forces(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """No force along the chain."""
        return np.zeros(self.n_q)

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """Surface distances between neighbours."""
        return q[1:] - q[:-1] - self.radii[1:] - self.radii[:-1]

    def gap_jacobian(self, q: np.ndarray) -> np.ndarray:
        """Constant: ``h_i = x_{i+1} - x_i - ...``."""
        return self._H

    def gap_jacobian_dot_v(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Zero: the Jacobian is constant."""
        return np.zeros(self.n_c)

    def ball_velocities(self, x: np.ndarray) -> np.ndarray:
        """Horizontal ball velocities from the state."""
        return np.asarray(x[self.n_q:], float)


class PendulumModel(LagrangianModel):
    """Point-mass pendulums of length ``length`` hanging from pivots on the x axis, swinging in
    the x-z plane: ``q = theta`` (0 hanging, positive towards +x), ``M = diag(m L^2)``."""

    def __init__(self, masses: np.ndarray, radii: np.ndarray, length: float, pivots: np.ndarray,
                 g: float = 9.81) -> None:
        self.masses = np.asarray(masses, float)
        self.radii = np.asarray(radii, float)
        self.length, self.g = float(length), float(g)
        self.pivots = np.asarray(pivots, float)
        self.n_q = len(self.masses)
        self.n_c = self.n_q - 1
        self._M = np.diag(self.masses * self.length ** 2)

    def centres(self, q: np.ndarray) -> np.ndarray:
        """Ball centres, shape (n, 2): (x, z)."""
        L = self.length
        return np.column_stack([self.pivots + L * np.sin(q), -L * np.cos(q)])

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Constant ``diag(m L^2)``."""
        return self._M

    def applied_forces(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Gravity torque ``-m g L sin(theta)``."""
        return -self.masses * self.g * self.length * np.sin(q)

    def potential_energy(self, q: np.ndarray) -> float:
        """``sum m g L (1 - cos theta)``."""
        return float(np.sum(self.masses * self.g * self.length * (1.0 - np.cos(q))))

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """Centre distance minus the two radii."""
        c = self.centres(q)
        return np.linalg.norm(c[1:] - c[:-1], axis=1) - self.radii[1:] - self.radii[:-1]

    def _geometry(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c = self.centres(q)
        d = c[1:] - c[:-1]
        dist = np.linalg.norm(d, axis=1)
        J = self.length * np.column_stack([np.cos(q), np.sin(q)])  # d centre / d theta
        return d / dist[:, None], dist, J

    def gap_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``H_i = n_i . (J_{i+1} e_{i+1} - J_i e_i)`` with n the unit centre-to-centre vector."""
        n, _, J = self._geometry(q)
        H = np.zeros((self.n_c, self.n_q))
        idx = np.arange(self.n_c)
        H[idx, idx] = -np.sum(n * J[:-1], axis=1)
        H[idx, idx + 1] = np.sum(n * J[1:], axis=1)
        return H

    def gap_jacobian_dot_v(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Curvature of ``|d|``: ``(|w|^2 - (n.w)^2)/|d| + n.(c''_{i+1} - c''_i)|_{theta''=0}``."""
        n, dist, J = self._geometry(q)
        vel = J * v[:, None]
        w = vel[1:] - vel[:-1]
        centripetal = self.length * np.column_stack([-np.sin(q), np.cos(q)]) * (v ** 2)[:, None]
        dc = centripetal[1:] - centripetal[:-1]
        nw = np.sum(n * w, axis=1)
        return (np.sum(w * w, axis=1) - nw ** 2) / dist + np.sum(n * dc, axis=1)

    def ball_velocities(self, x: np.ndarray) -> np.ndarray:
        """Horizontal ball velocities ``L cos(theta) theta'``."""
        q, v = x[:self.n_q], x[self.n_q:]
        return self.length * np.cos(q) * v


def momentum(model: LagrangianModel, x: np.ndarray, n: Optional[int] = None) -> float:
    """Horizontal linear momentum of the first ``n`` balls."""
    vel = model.ball_velocities(x)
    n = model.n_q if n is None else n
    return float(np.sum(model.masses[:n] * vel[:n]))


def make_cradle(n: int = 3, *, pendulum: bool = False, mass: float = 1.0, radius: float = 0.02,
                length: float = 0.3, gap: float = 0.0, striker_speed: float = 1.0,
                striker_angle: float = 0.0, law: Optional[CollisionLaw] = None,
                n_max: Optional[int] = None, g: float = 9.81,
                capture_speed: float = 0.0, kernels: bool = False) -> tuple[ContactSystem, np.ndarray]:
    """A cradle of ``n`` equal balls and its initial state.

    Balls hang (or lie) in a row with surface gaps ``gap``. The striker, ball 1, starts in its
    row position moving at ``striker_speed`` towards +x, or (pendulum only, ``striker_angle`` > 0)
    is released at rest from that angle. ``n_max`` balls are allocated; the extra ones are frozen.
    ``capture_speed`` defaults to 0: a cradle has no resting loads, so CONTACT is never entered.
    ``kernels``: evaluate with :mod:`.cradle_kernels` (what its FMU compiles; needs ``n_max`` = 7),
    whose parameter record is then ``system.params``.
    """
    n_max = n if n_max is None else n_max
    if not 2 <= n <= n_max:
        raise ValueError(f"need 2 <= n <= n_max, got n={n}, n_max={n_max}")
    law = law if law is not None else CollisionLaw()
    masses = np.full(n_max, float(mass))
    radii = np.full(n_max, float(radius))
    spacing = 2.0 * radius + gap
    if pendulum:
        model: LagrangianModel = PendulumModel(masses, radii, length, spacing * np.arange(n_max), g)
    else:
        model = ChainModel(masses, radii)
    active = np.arange(n_max) < n
    options = dict(capture_speed=capture_speed, active_dofs=active, active_constraints=active[1:])
    if kernels:
        if n_max != N_BALLS:
            raise ValueError(f"the cradle's kernels are for n_max = {N_BALLS} balls, got {n_max}")
        system: ContactSystem = KernelContactSystem(model, law, cradle_evaluate, None, **options)
        system.params = CradleParams(n, bool(pendulum), float(mass), float(radius), float(length), float(g),
                                     tuple(float(p) for p in spacing * np.arange(n_max)), law_constants(law),
                                     system.alpha0, system.alpha1)
    else:
        system = ContactSystem(model, law, **options)
    x0 = np.zeros(2 * n_max)
    if pendulum:
        if striker_angle > 0.0:
            x0[0] = -striker_angle
        else:
            x0[n_max] = striker_speed / length
    else:
        x0[:n_max] = spacing * np.arange(n_max)
        x0[n_max] = striker_speed
    return system, x0
