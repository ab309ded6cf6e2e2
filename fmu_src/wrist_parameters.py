"""What the 6-DOF models build alike from their parameters: the wrist with its peg tool
(DeltaWrist, DeltaWristPeg, AssemblyController, PegEstimator) and the peg-in-hole scene
(DeltaWristPeg, PegEstimator). Each takes a component declaring the parameters of those names
(declared once, in :mod:`.wrist_declarations`)."""
from __future__ import annotations

from typing import Any

from deltafmi.physics import delta_wrist
from deltafmi.physics.peg import Hole, Peg, PegContact, validate
from deltafmi.physics.wrist.params import WristParams

__all__ = ["peg_scene_of", "wrist_params_of"]


def wrist_params_of(component: Any) -> WristParams:
    """The wrist from tool_mass, tool_length, tool_radius, tool_tip, rotor_inertia, g, wrist_damping."""
    c = component
    tool = delta_wrist.peg_tool(c.tool_mass, c.tool_length, c.tool_radius, c.tool_tip)
    return delta_wrist.wrist_params(tuple(c.rotor_inertia), tool, c.g, c.wrist_damping)


def peg_scene_of(component: Any) -> tuple[Hole, Peg, PegContact]:
    """The hole, the peg (the tool) and the contact law from hole_position, hole_tilt, bore_radius,
    chamfer_width, chamfer_angle, hole_depth, edge_radius, tool_radius, tool_length,
    contact_stiffness, contact_damping, mu, v_eps, viscous; ValueError naming a bad one."""
    c = component
    x, y, z = (float(v) for v in c.hole_position)
    tilt_x, tilt_y = (float(v) for v in c.hole_tilt)
    hole = Hole(x, y, z, tilt_x, tilt_y, c.bore_radius, c.chamfer_width, c.chamfer_angle, c.hole_depth,
                c.edge_radius)
    peg = Peg(c.tool_radius, c.tool_length)
    law = PegContact(c.contact_stiffness, c.contact_damping, c.mu, c.v_eps, c.viscous)
    validate(hole, peg, law)
    return hole, peg, law
