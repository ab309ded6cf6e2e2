"""Delta robot parameters and frame: the RL5 parameter set and the arm rotations.

Frame (DESIGN.md): z up, gravity (0, 0, -g); the arm-1 servo axis is parallel to x through
(0, l0, 0) with y pointing radially out; arms 2 and 3 are arm 1 rotated about z by
R2 = Rz(+2pi/3) and R3 = Rz(-2pi/3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["DeltaParams", "RL5", "R2", "R3", "ARM_ROTATIONS", "rot_z"]


@dataclass(frozen=True)
class DeltaParams:
    """Geometry and inertia of a three-arm delta robot (SI units).

    Defaults are the Autonox24 RL5-1450-6kg CAD values published with
    github.com/testbedCIIRC/delta-robot-public.

    Attributes:
        l0: base radius, servo axis to robot axis (m).
        l1: upper-arm length, servo axis to elbow (m).
        l2: forearm length, elbow to wrist joint (m).
        l3: travelling-plate radius, robot axis to wrist joint (m).
        m1: upper-arm mass, elbow pins included (kg).
        r1: distance from the servo axis to the upper-arm centre of mass (m).
        J1: upper-arm moment of inertia ABOUT THE SERVO AXIS (kg m^2). It already contains the
            parallel-axis term m1 r1^2, as in the CAD data: 0.3295 = 0.0654 (arm about its CoM)
            + 3.696 * 0.2463^2 (arm) + 0.226 * 0.420^2 (elbow pins). Do not add m1 r1^2 again.
        Jm: gearbox-reflected rotor inertia on the servo axis (kg m^2), k^2 * I_gear.
        m2: forearm mass (both parallel bars), modelled as a thin uniform rod of length l2 (kg).
        mp: travelling-plate mass (kg); with the payload it is split into three point masses,
            one at each arm end (exact, since the plate only translates).
        payload: payload mass carried by the plate (kg).
        g: gravitational acceleration (m/s^2).
        damping: viscous damping on every one of the nine joints, D(v) = damping * v (N m s/rad).
    """

    l0: float = 0.330
    l1: float = 0.420
    l2: float = 1.055
    l3: float = 0.125
    m1: float = 3.922
    r1: float = 0.2563
    J1: float = 0.3295
    Jm: float = 0.6257
    m2: float = 1.050
    mp: float = 2.916
    payload: float = 0.0
    g: float = 9.81
    damping: float = 0.0

    # numbers only, frozen: a copy, deep or not, is the same value (FMU states share it)
    def __copy__(self) -> "DeltaParams":
        return self

    def __deepcopy__(self, memo: dict) -> "DeltaParams":
        return self


RL5 = DeltaParams()


def rot_z(angle: float) -> np.ndarray:
    """Rotation matrix about z by ``angle`` (rad)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


R2 = rot_z(2.0 * math.pi / 3.0)
R3 = rot_z(-2.0 * math.pi / 3.0)
ARM_ROTATIONS = (np.eye(3), R2, R3)
for _r in ARM_ROTATIONS:
    _r.setflags(write=False)
