"""Peg-in-hole parameters: the hole (a chamfered bore in a fixture), the peg, the contact law.

Frozen dataclasses of floats only: the kernels of :mod:`.contact` take them as C structs when the
code generator translates them (deltafmi/builder/codegen). :func:`validate` is the Python-side
check a component runs once at initialization.

Hole frame: origin at the hole's top centre (x, y, z), axis e_z pointing up out of the hole,
turned from the world by R_h = Ry(tilt_y) Rx(tilt_x) (first about the world x axis, then about
the world y axis). In that frame the fixture is the solid below its top plane z = 0 minus the
bore (radius ``bore_radius``, from the chamfer down to the bottom z = -depth) and the chamfer
cone, which meets the top plane at radius ``bore_radius + chamfer_width`` and the bore at
z = -chamfer_width tan(chamfer_angle), the angle measured between the chamfer surface and the
top plane (45 deg: a 45 x w chamfer); the two convex edges are rounded by ``edge_radius``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Hole", "Peg", "PegContact", "validate"]


@dataclass(frozen=True)
class Hole:
    """A chamfered bore in a fixture (m, rad); position and tilt are the TRUE hole.

    Attributes:
        x, y, z: the hole's top centre in the world (m).
        tilt_x, tilt_y: the hole axis' tilt, R_h = Ry(tilt_y) Rx(tilt_x) (rad).
        bore_radius: radius of the bore (m); clearance = bore_radius - peg radius.
        chamfer_width: radial width of the chamfer at the top plane (m), >= 0.
        chamfer_angle: angle between the chamfer surface and the top plane (rad), in (0, pi/2).
        depth: bore depth from the top plane to the bottom (m).
        edge_radius: fillet radius of the two convex edges, top/chamfer and chamfer/bore (m): a
            deburred edge; it keeps the contact normals continuous (0: sharp edges).
    """

    x: float = 0.0
    y: float = 0.0
    z: float = -1.2
    tilt_x: float = 0.0
    tilt_y: float = 0.0
    bore_radius: float = 0.0101
    chamfer_width: float = 0.002
    chamfer_angle: float = math.pi / 4.0
    depth: float = 0.04
    edge_radius: float = 2.0e-4


@dataclass(frozen=True)
class Peg:
    """A cylindrical peg: its axis is the tool z axis, its bottom face centre the tool tip (m).
    Defaults: the spherical wrist's default tool (deltafmi/physics/wrist/params.py), 20 mm x 100 mm."""

    radius: float = 0.010
    length: float = 0.100


@dataclass(frozen=True)
class PegContact:
    """The penalty contact law of every contact point (see :mod:`.contact`).

    Attributes:
        stiffness: k, normal force per metre of penetration of ONE contact point (N/m); a flat
            face on a plane touches with all rim points, so its stiffness is RIM_POINTS * k.
        damping: c in f_n = max(k delta + c delta', 0) (N s/m).
        mu: Coulomb friction coefficient (kinetic; the regularised law has no static one).
        v_eps: regularisation speed of the friction law (m/s): f_t = -mu f_n tanh(|v_t|/v_eps) e_t.
        viscous: c_v, a viscous tangential force -c_v v_t while a point touches (lubricant; N s/m).
    """

    stiffness: float = 2.0e5
    damping: float = 50.0
    mu: float = 0.3
    v_eps: float = 1.0e-3
    viscous: float = 0.0


def validate(hole: Hole, peg: Peg, contact: PegContact) -> None:
    """Raise ValueError, one line naming the parameter, for a geometry or law that makes no sense."""
    checks = (
        (peg.radius > 0.0, f"peg radius must be > 0 m, got {peg.radius}"),
        (peg.length > 0.0, f"peg length must be > 0 m, got {peg.length}"),
        (hole.bore_radius > peg.radius,
         f"hole bore_radius {hole.bore_radius} m must exceed the peg radius {peg.radius} m (positive clearance)"),
        (hole.chamfer_width >= 0.0, f"hole chamfer_width must be >= 0 m, got {hole.chamfer_width}"),
        (0.0 < hole.chamfer_angle < 0.5 * math.pi,
         f"hole chamfer_angle must lie in (0, pi/2) rad, got {hole.chamfer_angle}"),
        (hole.depth > hole.chamfer_width * math.tan(hole.chamfer_angle),
         f"hole depth {hole.depth} m must exceed the chamfer's depth "
         f"{hole.chamfer_width * math.tan(hole.chamfer_angle)} m"),
        (hole.edge_radius >= 0.0, f"hole edge_radius must be >= 0 m, got {hole.edge_radius}"),
        (hole.edge_radius * (1.0 - math.tan(0.5 * hole.chamfer_angle)) <= hole.chamfer_width,
         f"hole edge_radius {hole.edge_radius} m does not fit the chamfer: at most "
         f"chamfer_width / (1 - tan(chamfer_angle / 2)) = "
         f"{hole.chamfer_width / (1.0 - math.tan(0.5 * hole.chamfer_angle))} m"),
        (contact.stiffness > 0.0, f"contact stiffness must be > 0 N/m, got {contact.stiffness}"),
        (contact.damping >= 0.0, f"contact damping must be >= 0 N s/m, got {contact.damping}"),
        (contact.mu >= 0.0, f"contact mu must be >= 0, got {contact.mu}"),
        (contact.v_eps > 0.0, f"contact v_eps must be > 0 m/s, got {contact.v_eps}"),
        (contact.viscous >= 0.0, f"contact viscous must be >= 0 N s/m, got {contact.viscous}"),
    )
    for ok, message in checks:
        if not ok:
            raise ValueError(message)
