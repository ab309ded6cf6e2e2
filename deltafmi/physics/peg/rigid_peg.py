"""A free rigid peg (6 DOF) in the fixture: the reference plant the peg tests integrate with scipy.

State y = [x (centre of mass, world, m), q (unit quaternion w, x, y, z: peg -> world), v (m/s),
w (angular velocity in the peg frame, rad/s)], 13 floats. The peg frame is the tool frame of
:mod:`.contact` (z = peg axis pointing to the tip); the centre of mass lies L/2 above the tip:
tip = x + (L/2) R e_z. Newton-Euler with the contact wrench W = (F, M_tip):

    x' = v,   q' = 1/2 q (0, w),   m v' = F + f_app + m g,
    I w' = R^T (M_tip + (tip - x) x (F + f_app)) - w x I w,     I = diag(Ixx, Ixx, Izz)

with a constant applied force f_app at the tip. Energy 1/2 m |v|^2 + 1/2 w.I w + m g z + the
contacts' elastic energy is conserved when the contact has no damping and no friction.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from .contact import PegWrench
from .params import Peg

__all__ = ["RigidPeg", "WrenchFunction"]

#: (tip, R row-major, v_tip, omega) -> PegWrench, e.g. contact.peg_wrench with hole/peg/law bound
WrenchFunction = Callable[[tuple, tuple, tuple, tuple], PegWrench]


def _rotation(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion (normalised here, so integration drift does not scale R)."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


@dataclass(frozen=True)
class RigidPeg:
    """A homogeneous cylinder of ``density`` (kg/m^3) with the shape of ``peg`` under gravity g
    (along -z) and a constant force ``applied`` (N, world) at its tip."""

    peg: Peg
    density: float = 7850.0
    g: float = 9.81
    applied: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def mass(self) -> float:
        return self.density * np.pi * self.peg.radius ** 2 * self.peg.length

    @property
    def inertia(self) -> np.ndarray:
        """Principal moments about the centre of mass: m (3 r^2 + L^2) / 12 twice, m r^2 / 2."""
        r, L, m = self.peg.radius, self.peg.length, self.mass
        side = m * (3.0 * r * r + L * L) / 12.0
        return np.array([side, side, 0.5 * m * r * r])

    def state(self, tip: Sequence[float], R: np.ndarray, v_tip: Sequence[float] = (0.0, 0.0, 0.0),
              omega_body: Sequence[float] = (0.0, 0.0, 0.0)) -> np.ndarray:
        """The 13-float state of the peg with its tip at ``tip``, orientation ``R`` (3x3), tip velocity
        ``v_tip`` (world) and angular velocity ``omega_body`` (peg frame)."""
        R = np.asarray(R, float)
        w = np.asarray(omega_body, float)
        lever = 0.5 * self.peg.length * R[:, 2]
        x = np.asarray(tip, float) - lever
        v = np.asarray(v_tip, float) - np.cross(R @ w, lever)
        t = np.trace(R)  # R -> quaternion (Shepperd): the largest of 1 + t, 1 + 2 R_ii - t
        k = int(np.argmax([t, R[0, 0], R[1, 1], R[2, 2]]))
        if k == 0:
            s = 2.0 * np.sqrt(1.0 + t)
            q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
        else:
            i, j, l = k - 1, k % 3, (k + 1) % 3
            s = 2.0 * np.sqrt(1.0 + 2.0 * R[i, i] - t)
            q = [0.0] * 4
            q[0], q[1 + i] = (R[l, j] - R[j, l]) / s, 0.25 * s
            q[1 + j], q[1 + l] = (R[j, i] + R[i, j]) / s, (R[l, i] + R[i, l]) / s
        return np.concatenate([x, q, v, w])

    def pose(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(tip, R, v_tip, omega world) of the state y."""
        R = _rotation(y[3:7])
        omega = R @ y[10:13]
        lever = 0.5 * self.peg.length * R[:, 2]
        return y[:3] + lever, R, y[7:10] + np.cross(omega, lever), omega

    def contact(self, y: np.ndarray, wrench: WrenchFunction) -> PegWrench:
        """The contact wrench at the state y."""
        tip, R, v_tip, omega = self.pose(y)
        return wrench(tuple(tip), tuple(R.ravel()), tuple(v_tip), tuple(omega))

    def derivative(self, y: Sequence[float], wrench: WrenchFunction) -> list[float]:
        """y' (module docstring), in plain floats: an integrator calls it ~1e4 times a run."""
        x0, x1, x2, qw, qx, qy, qz, v0, v1, v2, w0, w1, w2 = (float(t) for t in y)
        R = _rotation(np.array([qw, qx, qy, qz])).ravel().tolist()
        o0 = R[0] * w0 + R[1] * w1 + R[2] * w2
        o1 = R[3] * w0 + R[4] * w1 + R[5] * w2
        o2 = R[6] * w0 + R[7] * w1 + R[8] * w2
        h = 0.5 * self.peg.length
        l0, l1, l2 = h * R[2], h * R[5], h * R[8]
        cw = wrench((x0 + l0, x1 + l1, x2 + l2), tuple(R),
                    (v0 + o1 * l2 - o2 * l1, v1 + o2 * l0 - o0 * l2, v2 + o0 * l1 - o1 * l0), (o0, o1, o2))
        f0, f1, f2 = cw.force[0] + self.applied[0], cw.force[1] + self.applied[1], cw.force[2] + self.applied[2]
        m0 = cw.moment[0] + l1 * f2 - l2 * f1
        m1 = cw.moment[1] + l2 * f0 - l0 * f2
        m2 = cw.moment[2] + l0 * f1 - l1 * f0
        b0 = R[0] * m0 + R[3] * m1 + R[6] * m2
        b1 = R[1] * m0 + R[4] * m1 + R[7] * m2
        b2 = R[2] * m0 + R[5] * m1 + R[8] * m2
        i0, i1, i2 = self.inertia.tolist()
        m = self.mass
        return [v0, v1, v2,
                0.5 * (-qx * w0 - qy * w1 - qz * w2), 0.5 * (qw * w0 + qy * w2 - qz * w1),
                0.5 * (qw * w1 + qz * w0 - qx * w2), 0.5 * (qw * w2 + qx * w1 - qy * w0),
                f0 / m, f1 / m, f2 / m - self.g,
                (b0 - (w1 * i2 * w2 - w2 * i1 * w1)) / i0, (b1 - (w2 * i0 * w0 - w0 * i2 * w2)) / i1,
                (b2 - (w0 * i1 * w1 - w1 * i0 * w0)) / i2]

    def energy(self, y: np.ndarray, wrench: WrenchFunction) -> float:
        """Kinetic + gravitational (zero at z = 0) + the contacts' elastic energy (J)."""
        w = y[10:13]
        return float(0.5 * self.mass * y[7:10] @ y[7:10] + 0.5 * w @ (self.inertia * w)
                     + self.mass * self.g * y[2] + self.contact(y, wrench).potential)
