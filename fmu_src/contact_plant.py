"""What the delta robot's contact plants (DeltaRobotContact, DeltaRobotBox) share.

Each is a hybrid system over a :class:`~deltafmi.physics.delta.contact.RobotContactSystem`: the
FREE / COLLISION / CONTACT machine runs in Python at events (initialization, ``update``), and the
continuous part between events (derivatives, event indicators, outputs) is three kernels of
:mod:`deltafmi.physics.delta.contact_kernels`, declared by :func:`contact_kernels` as the
component's ``native`` (compiled into the FMU) and called by the methods below alike. They read
the robot's parameters (``_plant``) and the contacts' modes and laws (``_contact``), which the
component takes from the system after initialization and every event.
"""
from __future__ import annotations

from typing import Any, Callable

from deltafmi.component import HybridSystemComponent, Kernel, NativeKernels
from deltafmi.physics import delta
from deltafmi.physics.delta.dynamics import project_state
from deltafmi.physics.delta.params import DeltaParams
from deltafmi.models.robot_parameters import RobotParameters

__all__ = ["RobotContactPlant", "contact_kernels"]

#: the kernels' arguments: robot parameters, contacts, states, servo torques, wrist force
_ARGUMENTS = ("_plant", "_contact", "states", "u", "f")


def contact_kernels(derivatives: Callable, indicators: Callable, outputs: Callable, contacts: type,
                    returns: tuple) -> NativeKernels:
    """The ``native`` of a contact plant: its three kernels over :data:`_ARGUMENTS`, ``contacts``
    the NamedTuple of its system's ``kernel_state``, ``returns`` the outputs in the order
    ``outputs`` gives them; and the projection onto the closed loops (its ``project``)."""
    return NativeKernels(derivatives=Kernel(derivatives, *_ARGUMENTS),
                         event_indicators=Kernel(indicators, *_ARGUMENTS),
                         outputs=Kernel(outputs, *_ARGUMENTS, returns=returns),
                         project=Kernel(project_state, "_plant", "q", "v", returns=("q", "v")),
                         attributes={"_plant": DeltaParams, "_contact": contacts})


class RobotContactPlant(RobotParameters, HybridSystemComponent):
    """Base of the contact plants: ``native`` from :func:`contact_kernels`, ``build_system``
    returning a RobotContactSystem; the variables ``q``, ``v``, ``u``, ``f``, ``mode``,
    ``loop_tolerance`` and the outputs are the subclass's declarations."""

    native: NativeKernels

    def setup(self) -> None:
        super().setup()
        self._plant = None  # the kernels' arguments, from the system after initialization and events
        self._contact = None

    def apply_inputs(self, system: Any) -> None:
        system.model.u = self.u.tolist()
        system.model.f = self.f.tolist()

    def publish_modes(self, modes: Any) -> None:
        """The mode output(s), and the system's state for the kernels."""
        super().publish_modes(modes)
        self._plant, self._contact = self.system.params, self.system.kernel_state()

    def project(self, t: float) -> None:
        """Close the loops (CS after every solver step, ME at a step event past loop_tolerance)."""
        self.q, self.v = delta.project_to_constraints(self._plant, self.q, self.v)

    def needs_projection(self, t: float) -> bool:
        tolerance = self.loop_tolerance
        return tolerance > 0.0 and delta.loop_residual(self._plant, self.q) > tolerance

    def _arguments(self) -> tuple:
        return self._plant, self._contact, self.states, self.u, self.f

    def derivatives(self, t: float) -> list:
        return self.native.derivatives.func(*self._arguments())

    def event_indicators(self, t: float) -> tuple:
        return self.native.event_indicators.func(*self._arguments())

    def outputs(self, t: float) -> None:
        values = self.native.outputs.func(*self._arguments())
        self.write_reals([v for item in values for v in (item if isinstance(item, tuple) else (item,))],
                         *self.native.outputs.returns)
