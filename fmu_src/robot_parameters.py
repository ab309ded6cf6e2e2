"""The delta robot's physical parameters, declared once for every component that carries them.

The plants (DeltaRobot, DeltaRobotContact, DeltaRobotBox) take :class:`RobotParameters` as a base
class; the controller takes the same declarations as its own model of the robot, from
:func:`robot_parameters` with a note after every description. Defaults are the RL5 set
(:data:`deltafmi.physics.delta.params.RL5`); the names are those of
:class:`~deltafmi.physics.delta.params.DeltaParams`.
"""
from __future__ import annotations

from typing import Dict, Optional, Tuple

from deltafmi.component import Parameter
from deltafmi.physics.delta.params import RL5, DeltaParams

__all__ = ["DECLARATIONS", "RobotParameters", "robot_parameters"]

#: name -> (unit, lower bound or None, description), in declaration (and value reference) order
DECLARATIONS: Dict[str, Tuple[str, Optional[float], str]] = {
    "l0": ("m", 0.0, "Base radius: robot axis to servo axes"),
    "l1": ("m", 0.0, "Upper-arm length: servo axis to elbow"),
    "l2": ("m", 0.0, "Forearm length: elbow to wrist joint"),
    "l3": ("m", 0.0, "Travelling-plate radius: plate centre to wrist joints"),
    "m1": ("kg", 0.0, "Upper-arm mass (elbow pins included)"),
    "r1": ("m", None, "Servo axis to upper-arm centre of mass"),
    "J1": ("kg.m2", 0.0, "Upper-arm inertia about the servo axis (includes m1*r1^2)"),
    "Jm": ("kg.m2", 0.0, "Gearbox-reflected rotor inertia on the servo axis"),
    "m2": ("kg", 0.0, "Forearm mass (both bars), modelled as a thin uniform rod"),
    "mp": ("kg", 0.0, "Travelling-plate mass (and any tool on it)"),
    "payload": ("kg", 0.0, "Payload carried by the plate"),
    "g": ("m/s2", None, "Gravitational acceleration (acts along -z)"),
    "damping": ("N.m.s/rad", 0.0, "Viscous damping on each of the nine joints"),
}


def robot_parameters(note: str = "") -> type:
    """A base class declaring the robot's parameters (before the component's own), with a
    :meth:`robot_params` method; ``note`` follows every description after a semicolon."""
    namespace: Dict[str, object] = {"__doc__": "The delta robot's parameters" + (f"; {note}" if note else "") + ".",
                                    "robot_params": _robot_params}
    for name, (unit, low, description) in DECLARATIONS.items():
        bounds = {} if low is None else {"min": low}
        namespace[name] = Parameter(getattr(RL5, name), unit=unit, **bounds,
                                    description=f"{description}; {note}" if note else description)
    return type("RobotParameters", (), namespace)


def _robot_params(self: object) -> DeltaParams:
    """The parameters' current values as the mechanics' :class:`DeltaParams`."""
    return DeltaParams(**{name: getattr(self, name) for name in DECLARATIONS})


#: the plants' base class: ``class DeltaRobot(RobotParameters, Component)``
RobotParameters = robot_parameters()
