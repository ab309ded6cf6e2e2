"""The wrist's gimbal singularity: where it is, how far away, and joint rates across it.

With the Z-X-Y axes of :mod:`.kinematics`, a_1 . a_2 = a_2 . a_3 = 0 and a_1 . a_3 = sin q2, so

    J_w^T J_w = [[1, 0, s2], [0, 1, 0], [s2, 0, 1]],  singular values 1, sqrt(1 +- |s2|),
    det J_w = cos q2.

At |q2| = pi/2 the axes a_1 and a_3 align ("gimbal lock"): J_w has rank 2, the angular velocity
along n = a_1 x a_2 cannot be produced, and only q1 + q3 (or q1 - q3) is defined by the tool's
orientation. The DYNAMICS stay regular there: every body's kinetic energy is positive along its
own axis (the rotors' axial inertias J_r,i > 0, with the links'), so qd^T M qd = 0 forces
omega_1 = a_1 qd1 = 0, then omega_2 = a_2 qd2 = 0, then omega_3 = a_3 qd3 = 0; M(q) is positive
definite for every q and the wrist simulates straight through the singularity.

What a controller must do near it: (1) plan orientations in the working cone (tool tilt theta
keeps a margin of pi/2 - theta, :func:`gimbal_distance` is the monitor); (2) control joint
angles, not world angular velocities, in the inner loop (regular everywhere); (3) map a desired
tool angular velocity to joint rates with the damped least-squares inverse of
:func:`joint_rates`, which bounds qd where J_w^-1 would blow up like 1/cos q2 (and gives up the
unreachable component along n instead); (4) at the singularity choose the split of q1 + q3
continuously (keep q1 from the previous sample, as :func:`.kinematics.inverse_kinematics` cannot).
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from .kinematics import joint_axes

__all__ = ["GimbalDistance", "gimbal_distance", "joint_rates"]


class GimbalDistance(NamedTuple):
    """How far the wrist is from gimbal lock."""

    angle: float  #: angle between the lines of a_1 and a_3, acos|sin q2| in [0, pi/2] (rad)
    sigma_min: float  #: smallest singular value of J_w, sqrt(1 - |sin q2|) = sqrt(2) sin(angle/2)
    det: float  #: det J_w = cos q2 (its sign tells the branch)


def gimbal_distance(q: Sequence[float] | np.ndarray) -> GimbalDistance:
    """Distance of the joint angles q (rad) from the gimbal singularity |q2| = pi/2."""
    s2 = min(1.0, abs(math.sin(float(q[1]))))
    return GimbalDistance(math.acos(s2), math.sqrt(1.0 - s2), math.cos(float(q[1])))


def joint_rates(q: Sequence[float] | np.ndarray, omega: Sequence[float] | np.ndarray,
                sigma0: float = 0.2) -> np.ndarray:
    """Joint rates for the tool angular velocity omega (world, rad/s) by damped least squares.

    qd = J_w^T (J_w J_w^T + lambda^2 1)^-1 omega with lambda^2 = sigma0^2 - sigma_min^2 when
    sigma_min < sigma0 (Nakamura & Hanafusa 1986; Wampler 1986), else the exact inverse. Each
    singular direction of J_w is scaled by sigma / (sigma^2 + lambda^2) <= 1 / sigma0, so
    |qd| <= |omega| / sigma0 everywhere, and at the singularity the unreachable component of
    omega (along a_1 x a_2) is dropped; away from it (sigma_min >=
    sigma0, i.e. the gimbal angle above 2 asin(sigma0 / sqrt 2), 16.3 degrees for 0.2) omega is
    met exactly.
    """
    J = joint_axes(q)
    w = np.asarray(omega, dtype=float)
    sigma_min = gimbal_distance(q).sigma_min
    if sigma_min >= sigma0:
        return np.linalg.solve(J, w)
    lam2 = sigma0 * sigma0 - sigma_min * sigma_min
    return J.T @ np.linalg.solve(J @ J.T + lam2 * np.eye(3), w)
