"""Spherical-wrist kinematics: link rotations, tool frame, Jacobians, inverse orientation.

Axis sequence Z-X-Y (yaw about the vertical, then two tilts), all through the centre O:

    R_1 = Rz(q1),  R_2 = R_1 Rx(q2),  R_3 = R_2 Ry(q3),  R_tool = R_3 Rx(pi)
    a_1 = e_z,     a_2 = R_1 e_x,     a_3 = R_2 e_y          (joint axes, world frame)

The tool axis (tool z) is -z of link 3: it points down at q = 0 and q1 then spins the tool about
its own axis. Angular velocity of link k and of the tool (Sciavicco & Siciliano, ch. 3):

    omega_k = sum_{j<=k} a_j qd_j,      omega = J_w(q) qd,  J_w = [a_1 a_2 a_3]

and, every axis passing through O, the tool tip p = R_3 (0, 0, -tip) moves with

    p_dot = omega x p = J_p(q) qd,      J_p = -[p]x J_w.

det J_w = a_1 . (a_2 x a_3) = cos q2: the gimbal singularity is |q2| = pi/2, where a_3 turns
parallel to a_1 (link 3's y axis vertical, the tool axis horizontal). Why Z-X-Y: the classical
Z-Y-Z (roll-pitch-roll) wrist is singular when the tool is aligned with its first axis, which
for a vertical first axis is exactly the tool-down pose of a vertical insertion. With Z-X-Y
the tool-down pose is the best-conditioned one (J_w orthogonal) and every tool direction
tilted by theta < pi/2 from the vertical stays at least pi/2 - theta away from the singularity
(see :mod:`.singularity`): a 30 degree working cone keeps 60 degrees of margin.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .params import JOINT_AXES, TOOL_FLIP, WristParams

__all__ = ["link_rotations", "joint_axes", "tool_rotation", "tool_tip", "angular_jacobian",
           "tip_jacobian", "inverse_kinematics", "skew", "axes_of"]

ArrayLike = Sequence[float] | np.ndarray


def skew(v: ArrayLike) -> np.ndarray:
    """[v]x, the matrix with [v]x w = v x w."""
    x, y, z = (float(t) for t in v)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _basis_rotation(axis: int, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about the basis vector e_axis (0: x, 1: y, 2: z)."""
    c, s = math.cos(angle), math.sin(angle)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def link_rotations(q: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World rotations (R_1, R_2, R_3) of the three links at joint angles q (rad)."""
    R = np.eye(3)
    out = []
    for axis, angle in zip(JOINT_AXES, q):
        R = R @ _basis_rotation(int(np.argmax(axis)), float(angle))
        out.append(R)
    return out[0], out[1], out[2]


def joint_axes(q: ArrayLike) -> np.ndarray:
    """(3, 3) matrix whose column j is the unit axis a_j of joint j in the world frame; it is
    also the angular-velocity Jacobian J_w (every link turns about O)."""
    return axes_of(link_rotations(q))


def axes_of(rotations: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """joint_axes() from the link rotations already at hand: a_1 = e_z, a_2 = R_1 e_x, a_3 = R_2 e_y."""
    return np.column_stack((JOINT_AXES[0], rotations[0] @ JOINT_AXES[1], rotations[1] @ JOINT_AXES[2]))


angular_jacobian = joint_axes


def tool_rotation(q: ArrayLike) -> np.ndarray:
    """R_tool = R_3 Rx(pi): world <- tool frame; its third column is the tool (approach) axis."""
    return link_rotations(q)[2] @ TOOL_FLIP


def tool_tip(p: WristParams, q: ArrayLike) -> np.ndarray:
    """Tool-tip position relative to the wrist centre O, world frame (m)."""
    return tool_rotation(q)[:, 2] * p.tool.tip


def tip_jacobian(p: WristParams, q: ArrayLike) -> np.ndarray:
    """J_p(q) with tip velocity (relative to O) = J_p qd: J_p = -[p]x J_w, (3, 3) m/rad."""
    return -skew(tool_tip(p, q)) @ joint_axes(q)


def inverse_kinematics(R_tool: np.ndarray) -> np.ndarray:
    """Joint angles giving the tool orientation R_tool, branch |q2| <= pi/2 (cos q2 >= 0).

    From R_3 = R_tool Rx(pi) = Rz(q1) Rx(q2) Ry(q3): R_3[2,1] = sin q2,
    (R_3[0,1], R_3[1,1]) = cos q2 (-sin q1, cos q1), (R_3[2,0], R_3[2,2]) = cos q2 (-sin q3, cos q3).
    At the singularity (cos q2 = 0) only q1 - q3 or q1 + q3 is defined; this returns q3 = 0.
    """
    R3 = np.asarray(R_tool, dtype=float) @ TOOL_FLIP
    q2 = math.asin(max(-1.0, min(1.0, float(R3[2, 1]))))
    if math.cos(q2) < 1e-12:
        return np.array([math.atan2(R3[1, 0], R3[0, 0]), q2, 0.0])
    return np.array([math.atan2(-R3[0, 1], R3[1, 1]), q2, math.atan2(-R3[2, 0], R3[2, 2])])
