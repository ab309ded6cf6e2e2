"""The wrist's, its tool's and the hole's parameters, declared once for every 6-DOF model that
carries them.

The plants (DeltaWrist, DeltaWristPeg) and the components that model the plant (AssemblyController,
PegEstimator, InsertionMpc) take these declarations as base classes, from :func:`wrist_parameters`
and :func:`hole_parameters`, with one default each, as
:func:`~deltafmi.models.robot_parameters.robot_parameters` does for the delta. List a model's bases
as ``(HoleParameters, WristParameters, RobotParameters, Component)``: its FMU declares the robot's
parameters first, then the wrist's, then the hole's, then its own. What the models build from
them (the wrist, the hole, the peg and the contact law) is in :mod:`.wrist_parameters`; this
module imports nothing but the declarations, so that a model that only names the hole (the MPC)
carries no robot code.
"""
from __future__ import annotations

from typing import Dict, Iterable, Optional, Tuple, Union

from deltafmi.component import Parameter

__all__ = ["HOLE_DECLARATIONS", "WRIST_DECLARATIONS", "WristParameters", "hole_parameters", "wrist_parameters"]

Default = Union[float, Tuple[float, ...]]
#: name -> (default, unit, lower bound or None, description), in declaration (and value reference) order
Declarations = Dict[str, Tuple[Default, str, Optional[float], str]]

#: the wrist and its tool (a solid cylinder, the peg), DeltaWrist's defaults
WRIST_DECLARATIONS: Declarations = {
    "tool_mass": (0.25, "kg", 0.0, "Tool (peg) mass, a solid cylinder on the tool axis"),
    "tool_length": (0.1, "m", 0.0, "Tool (peg) length"),
    "tool_radius": (0.01, "m", 0.0, "Tool (peg) radius"),
    "tool_tip": (0.13, "m", 0.0, "Distance from the wrist centre to the tool tip along the tool axis"),
    "rotor_inertia": ((3.0e-4, 2.0e-4, 1.0e-4), "kg.m2", 0.0,
                      "Axial inertia of each wrist motor's rotor (direct drive), > 0"),
    "wrist_damping": (0.0, "N.m.s/rad", 0.0, "Viscous friction in each wrist joint"),
    "mount": ((0.0, 0.0, -0.05), "m", None, "Wrist centre relative to the plate centre (the plate only translates)"),
}

#: the hole (its pose: ``{hole}`` is "true" or "nominal") and the peg's contact law with the fixture.
#: The hole's top is 2 cm below the plants' default tip (tip0 = (0, 0, -1.18)): the peg starts
#: above it, on its axis.
HOLE_DECLARATIONS: Declarations = {
    "hole_position": ((0.0, 0.0, -1.2), "m", None, "Top centre of the {hole} hole, world"),
    "hole_tilt": ((0.0, 0.0), "rad", None, "Axis tilt of the {hole} hole: about the world x axis, then about the "
                  "world y axis (hole frame Ry(tilt_y) Rx(tilt_x))"),
    "bore_radius": (0.0101, "m", 0.0, "Bore radius; the clearance is bore_radius - tool_radius"),
    "chamfer_width": (0.002, "m", 0.0, "Radial width of the chamfer at the top plane"),
    "chamfer_angle": (0.7853981633974483, "rad", 0.0,
                      "Angle between the chamfer surface and the top plane (pi/4: 45 deg)"),
    "hole_depth": (0.04, "m", 0.0, "Depth of the bore, top plane to bottom"),
    "edge_radius": (2.0e-4, "m", 0.0, "Fillet radius of the hole's two convex edges (0: sharp, normals jump)"),
    "contact_stiffness": (2.0e5, "N/m", 0.0, "Penalty stiffness of one contact point (a flat face: 32 points)"),
    "contact_damping": (50.0, "N.s/m", 0.0, "Penalty damping of one contact point; normal force >= 0 always"),
    "mu": (0.3, "1", 0.0, "Coulomb friction coefficient peg/fixture"),
    "v_eps": (1.0e-3, "m/s", 0.0, "Friction regularisation speed: f_t = -mu f_n tanh(|v_t|/v_eps) v_t/|v_t|"),
    "viscous": (0.0, "N.s/m", 0.0, "Viscous tangential force -viscous v_t at each touching point (lubricant)"),
}


def wrist_parameters(note: str = "") -> type:
    """A base class declaring the wrist's and its tool's parameters; ``note`` follows every
    description after a semicolon."""
    return _declaring("WristParameters", "The wrist's and its tool's parameters", WRIST_DECLARATIONS, note)


def hole_parameters(hole: str, note: str = "", names: Optional[Iterable[str]] = None) -> type:
    """A base class declaring the hole's parameters: ``hole`` says which hole the pose is ("true"
    for a plant, "nominal" for a component that models it), ``note`` follows every description
    after a semicolon, ``names`` picks some of :data:`HOLE_DECLARATIONS` (all by default; the
    table's order either way)."""
    chosen = set(HOLE_DECLARATIONS if names is None else names)
    unknown = chosen - set(HOLE_DECLARATIONS)
    if unknown:
        raise ValueError(f"no hole parameters named {', '.join(sorted(unknown))}")
    table = {name: (default, unit, low, description.format(hole=hole))
             for name, (default, unit, low, description) in HOLE_DECLARATIONS.items() if name in chosen}
    return _declaring("HoleParameters", f"The {hole} hole's parameters", table, note)


def _declaring(name: str, doc: str, table: Declarations, note: str) -> type:
    namespace: Dict[str, object] = {"__doc__": doc + (f"; {note}" if note else "") + "."}
    for attribute, (default, unit, low, description) in table.items():
        bounds = {} if low is None else {"min": low}
        start = list(default) if isinstance(default, tuple) else default
        namespace[attribute] = Parameter(start, unit=unit, **bounds,
                                         description=f"{description}; {note}" if note else description)
    return type(name, (), namespace)


#: the plants' wrist: ``class DeltaWrist(WristParameters, RobotParameters, Component)``
WristParameters = wrist_parameters()
