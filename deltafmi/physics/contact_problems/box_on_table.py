"""A planar rigid box dropped on a frictionless table: 3 DOF (x, y, theta), its 4 corners as gaps.

``(x, y)`` is the centre of mass, ``theta`` the rotation (counter-clockwise). The centre of mass
may sit ``com_offset`` (body frame) away from the geometric centre, which makes the resting
contact forces unequal. The table is the line y = 0, gravity is -g along y.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from ..contact.collision_law import CollisionLaw
from ..contact.system import ContactSystem, LagrangianModel

__all__ = ["BoxModel", "make_box_drop"]


class BoxModel(LagrangianModel):
    """Rigid rectangle (mass, width, height, inertia about the centre of mass) over a table."""

    n_q = 3
    n_c = 4

    def __init__(self, mass: float = 1.0, width: float = 0.4, height: float = 0.2,
                 inertia: Optional[float] = None, com_offset: tuple[float, float] = (0.0, 0.0),
                 g: float = 9.81) -> None:
        self.mass, self.width, self.height, self.g = float(mass), float(width), float(height), float(g)
        # uniform plate about its centre, moved to the centre of mass (parallel axis)
        self.inertia = (float(inertia) if inertia is not None else
                        mass * (width ** 2 + height ** 2) / 12.0 + mass * float(np.dot(com_offset, com_offset)))
        sx, sy = 0.5 * width, 0.5 * height
        #: corners relative to the centre of mass, body frame: bottom-left, bottom-right, top-right, top-left
        self.corners = np.array([[-sx, -sy], [sx, -sy], [sx, sy], [-sx, sy]]) - np.asarray(com_offset, float)
        self._M = np.diag([self.mass, self.mass, self.inertia])
        self.force = np.zeros(3)  #: extra generalised force (Fx, Fy, torque), e.g. an FMU input

    def rotated_corners(self, theta: float) -> np.ndarray:
        """Corner offsets from the centre of mass in the world frame, shape (4, 2)."""
        c, s = np.cos(theta), np.sin(theta)
        return self.corners @ np.array([[c, s], [-s, c]])

    def corner_positions(self, q: np.ndarray) -> np.ndarray:
        """World positions of the 4 corners."""
        return q[:2] + self.rotated_corners(q[2])

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """``diag(m, m, I)``."""
        return self._M

    def applied_forces(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Gravity plus the extra force."""
        return np.array([0.0, -self.mass * self.g, 0.0]) + self.force

    def potential_energy(self, q: np.ndarray) -> float:
        """``m g y``."""
        return self.mass * self.g * float(q[1])

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """Corner heights above the table."""
        return q[1] + self.rotated_corners(q[2])[:, 1]

    def gap_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``[0, 1, d(corner_y)/d theta] = [0, 1, r_x]`` with r the rotated corner offset."""
        r = self.rotated_corners(q[2])
        return np.column_stack([np.zeros(4), np.ones(4), r[:, 0]])

    def gap_jacobian_dot_v(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Centripetal term ``-theta'^2 r_y``."""
        return -v[2] ** 2 * self.rotated_corners(q[2])[:, 1]

    def resting_forces(self) -> np.ndarray:
        """Static forces on the two bottom corners of the box lying flat, by moment balance about
        the centre of mass: ``lambda_L + lambda_R = m g``, ``lambda_L x_L + lambda_R x_R = 0``."""
        x_left, x_right = self.corners[0, 0], self.corners[1, 0]
        weight = self.mass * self.g
        return np.array([weight * x_right / (x_right - x_left), -weight * x_left / (x_right - x_left)])


def make_box_drop(*, mass: float = 1.0, width: float = 0.4, height: float = 0.2,
                  inertia: Optional[float] = None, com_offset: tuple[float, float] = (0.0, 0.0),
                  angle: float = 0.3, drop_height: float = 0.1, law: Optional[CollisionLaw] = None,
                  capture_speed: float = 0.05, g: float = 9.81) -> tuple[ContactSystem, np.ndarray]:
    """Box at rest, tilted by ``angle``, its lowest corner ``drop_height`` above the table."""
    model = BoxModel(mass, width, height, inertia, com_offset, g)
    law = law if law is not None else CollisionLaw(restitution=0.5, duration=1e-3, reference_speed=1.0)
    system = ContactSystem(model, law, capture_speed=capture_speed)
    y = drop_height - float(np.min(model.rotated_corners(angle)[:, 1]))
    return system, np.array([0.0, y, angle, 0.0, 0.0, 0.0])
