"""The 6-DOF plant's own parameters: where the wrist sits on the plate, and a cylindrical peg tool.

The delta's travelling plate only translates (its parallelograms hold its orientation), so the
wrist is mounted by a constant offset: the wrist centre O (where the three wrist axes meet) is
O = z + d, z the plate centre (delta.wrist_position) and d = (x, y, z) of :class:`WristMount`,
world frame. The default hangs O 50 mm under the plate centre, the depth of a flange and the
first motor's housing; at wrist angles 0 the tool points straight down from O.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..wrist.params import WRIST, Tool, WristParams

__all__ = ["WristMount", "MOUNT", "peg_tool", "wrist_params"]


@dataclass(frozen=True)
class WristMount:
    """Offset d from the plate centre to the wrist centre O, world frame (m); the kernels read it."""

    x: float = 0.0
    y: float = 0.0
    z: float = -0.05


MOUNT = WristMount()


def peg_tool(mass: float, length: float, radius: float, tip: float) -> Tool:
    """A solid cylindrical peg of ``mass`` (kg), ``length`` and ``radius`` (m) on the tool axis, its
    tip ``tip`` (m) from O (its centre of mass at tip - length / 2):

        Ixx = Iyy = m (3 r^2 + L^2) / 12,  Izz = m r^2 / 2     (about its centre of mass)

    Raises ValueError naming the parameter for a negative size or a peg reaching above O."""
    for name, value in (("tool mass", mass), ("tool length", length), ("tool radius", radius)):
        if not value >= 0.0:
            raise ValueError(f"{name} must be >= 0, got {value!r}")
    if not tip >= length:
        raise ValueError(f"tool tip distance {tip!r} m must be at least the tool length {length!r} m "
                         "(the peg hangs below the wrist centre)")
    side = mass * (3.0 * radius * radius + length * length) / 12.0
    return Tool(mass, tip - 0.5 * length, tip, (side, side, 0.5 * mass * radius * radius, 0.0, 0.0, 0.0))


def wrist_params(rotors: tuple[float, float, float], tool: Tool, g: float, damping: float) -> WristParams:
    """The default wrist's links (:data:`~deltafmi.physics.wrist.params.WRIST`) with these rotor
    inertias (kg m^2, each > 0), tool, gravity (m/s^2) and joint damping (N m s/rad)."""
    for k, rotor in enumerate(rotors):
        if not rotor > 0.0:
            raise ValueError(f"rotor inertia {k + 1} must be > 0 (it keeps the wrist's mass matrix regular "
                             f"at gimbal lock), got {rotor!r}")
    if not damping >= 0.0:
        raise ValueError(f"wrist damping must be >= 0, got {damping!r}")
    rotor_inertias = (float(rotors[0]), float(rotors[1]), float(rotors[2]))
    return WristParams(links=WRIST.links, rotors=rotor_inertias, tool=tool, g=float(g), damping=float(damping))
