"""Spherical-wrist parameters: links, direct-drive rotors, the tool (peg), gravity.

Frames: the wrist centre O (where the three axes meet) is the origin; at q = 0 every link frame
coincides with the world frame (z up). Link i turns about its axis a_i (Z, X, Y in the frame of
the link before it, see :mod:`.kinematics`). Link 3 carries the tool; the tool frame is link 3's
frame turned by pi about x, so its z axis (the tool or approach axis) points DOWN at q = 0.

Inertias are given about each body's own centre of mass in its own frame; :func:`link_inertias`
moves them to the centre O (parallel-axis theorem) and adds each rotor's axial inertia: in a
gear-less (direct-drive) joint the rotor turns with the link it drives, so rotor i is part of
link i's rigid body, and J_r,i > 0 is what keeps M(q) invertible at the gimbal singularity
(see :mod:`.singularity`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["Body", "Tool", "WristParams", "WRIST", "link_inertias", "TOOL_FLIP", "JOINT_AXES"]

#: link-3 frame -> tool frame: a half turn about x (tool z = approach axis = -z of link 3)
TOOL_FLIP = np.diag([1.0, -1.0, -1.0])
TOOL_FLIP.setflags(write=False)

Vec3 = tuple[float, float, float]
#: (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) about the body's centre of mass, in the body's frame (kg m^2)
Inertia6 = tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class Body:
    """A link: mass (kg), centre of mass in the link frame relative to O (m), inertia about the
    centre of mass in the link frame (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) (kg m^2). The stator of motor
    i+1 is carried by link i and belongs to its mass and inertia."""

    mass: float
    com: Vec3
    inertia: Inertia6


@dataclass(frozen=True)
class Tool:
    """A peg rigidly mounted on link 3, described in the tool frame (z along the tool axis).

    Attributes:
        mass: tool mass (kg).
        com: distance from O to the tool's centre of mass along the tool axis (m).
        tip: distance from O to the tool tip (tool-frame origin of the tip) along the axis (m).
        inertia: (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) about the tool's centre of mass, tool frame
            (kg m^2); a cylindrical peg has Ixx = Iyy = m (3 r^2 + L^2) / 12, Izz = m r^2 / 2.
    """

    mass: float
    com: float
    tip: float
    inertia: Inertia6


@dataclass(frozen=True)
class WristParams:
    """A 3-DOF direct-drive spherical wrist with its tool (SI units).

    Defaults: a compact wrist of frameless torque motors (rotors 1e-4 to 3e-4 kg m^2, the low
    impedance the talk asks for) and a steel peg of diameter 20 mm and length 100 mm mounted
    30 mm below O; the whole wrist (1.75 kg) stays inside the RL5's 6 kg payload.

    Attributes:
        links: the three links (link 1 carries motor 2's stator and the yoke, link 2 motor 3's).
        rotors: axial inertia of each motor's rotor about its joint axis (kg m^2), > 0.
        tool: the peg on link 3.
        g: gravitational acceleration (m/s^2), along -z of the world.
        damping: viscous friction in every joint, tau_f = -damping * qd (N m s/rad).
    """

    links: tuple[Body, Body, Body] = (
        Body(0.80, (0.0, 0.0, 0.02), (1.6e-3, 1.2e-3, 1.4e-3, 0.0, 0.0, 0.0)),
        Body(0.50, (0.0, 0.0, -0.01), (6.0e-4, 8.0e-4, 5.0e-4, 0.0, 0.0, 0.0)),
        Body(0.20, (0.0, 0.0, -0.02), (1.5e-4, 1.5e-4, 1.0e-4, 0.0, 0.0, 0.0)),
    )
    rotors: Vec3 = (3.0e-4, 2.0e-4, 1.0e-4)
    tool: Tool = Tool(0.25, 0.08, 0.13, (2.1e-4, 2.1e-4, 1.25e-5, 0.0, 0.0, 0.0))
    g: float = 9.81
    damping: float = 0.0


WRIST = WristParams()

#: joint i turns about z, x, y of the link before it (rows: the axes in that link's frame)
JOINT_AXES = np.eye(3)[[2, 0, 1]]
JOINT_AXES.setflags(write=False)


def _tensor(i6: Inertia6) -> np.ndarray:
    xx, yy, zz, xy, xz, yz = i6
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def _about_origin(mass: float, com: np.ndarray, inertia_com: np.ndarray) -> np.ndarray:
    """Parallel-axis theorem: I_O = I_c + m (|c|^2 1 - c c^T)."""
    return inertia_com + mass * (float(com @ com) * np.eye(3) - np.outer(com, com))


@lru_cache(maxsize=16)
def link_inertias(p: WristParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The three rigid bodies that rotate about O, each in its own link frame.

    Body i is link i + rotor i (+ the tool for i = 3). Returns (masses (3,) kg, first moments
    m_i c_i (3, 3) kg m with one row per body, inertias about O (3, 3, 3) kg m^2), read-only and
    cached per parameter set (WristParams is frozen and hashable).
    """
    masses = np.zeros(3)
    moments = np.zeros((3, 3))
    inertias = np.zeros((3, 3, 3))
    for i, (link, rotor) in enumerate(zip(p.links, p.rotors)):
        c = np.array(link.com, dtype=float)
        masses[i] = link.mass
        moments[i] = link.mass * c
        axis = JOINT_AXES[i]
        inertias[i] = _about_origin(link.mass, c, _tensor(link.inertia)) + rotor * np.outer(axis, axis)
    t = p.tool
    c_tool = TOOL_FLIP @ np.array([0.0, 0.0, t.com])
    masses[2] += t.mass
    moments[2] += t.mass * c_tool
    inertias[2] += _about_origin(t.mass, c_tool, TOOL_FLIP @ _tensor(t.inertia) @ TOOL_FLIP)
    for array in (masses, moments, inertias):
        array.setflags(write=False)
    return masses, moments, inertias
