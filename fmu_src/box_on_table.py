"""A planar box dropped on a frictionless table: bounces, rocks and rests on two corners."""
import numpy as np

from deltafmi.component import Experiment, HybridSystemComponent, Input, Kernel, NativeKernels, Output, Parameter, State
from deltafmi.physics.contact_problems.box_kernels import (BoxModes, BoxParams, box_derivatives, box_evaluate,
                                                     box_indicators, box_outputs)
from deltafmi.physics.contact_problems.box_on_table import BoxModel
from deltafmi.physics.contact.law_kernels import law_constants
from deltafmi.physics.contact_problems.contact_kernels import KernelContactSystem
from deltafmi.physics.contact.collision_law import CollisionLaw

__all__ = ["BoxOnTable"]

#: the outputs, in the order box_outputs returns them
_OUTPUTS = ("lam", "gap", "total_force", "energy")


class BoxOnTable(HybridSystemComponent):
    """Rigid box (x, y, theta) dropped at an angle on a table; its 4 corners are contacts.

    Corners collide with a compliant law (restitution, duration), are captured into CONTACT
    (soft stabilised constraint) once they cannot rebound, and leave CONTACT when their force
    turns negative. At rest the corner forces balance the weight and its moment.
    Corners: 1 bottom-left, 2 bottom-right, 3 top-right, 4 top-left (body frame).
    """

    model_name = "BoxOnTable"
    default_experiment = Experiment(start=0.0, stop=3.0, step=1e-3, tolerance=1e-8)
    n_event_indicators = 8
    cs_options = dict(rtol=1e-8, atol=1e-10)

    mass = Parameter(1.0, unit="kg", description="Mass of the box", min=0.0)
    width = Parameter(0.4, unit="m", description="Width of the box", min=0.0)
    height = Parameter(0.2, unit="m", description="Height of the box", min=0.0)
    inertia = Parameter(0.0, unit="kg.m2", description="Inertia about the centre of mass (0: uniform plate)")
    com_offset = Parameter([0.0, 0.0], unit="m", description="Centre of mass from the geometric centre (body frame)")
    e = Parameter(0.5, description="Coefficient of restitution of the corners", min=0.01, max=1.0)
    duration = Parameter(1e-3, unit="s", description="Corner collision duration at reference_speed", min=0.0)
    reference_speed = Parameter(1.0, unit="m/s", description="Impact speed at which a collision lasts 'duration'")
    exponent = Parameter(3.0, description="Stiffening exponent p of the law", min=1.0)
    capture_speed = Parameter(0.05, unit="m/s", description="Rebound speed below which a loaded corner stays in CONTACT")
    alpha0 = Parameter(100.0, description="CONTACT law h'' + alpha1 h' + alpha0 h = 0: alpha0 (1/s2)")
    alpha1 = Parameter(20.0, description="CONTACT law: alpha1 (1/s)")
    g = Parameter(9.81, unit="m/s2", description="Gravity")
    pos = State([0.0, 0.2546], unit="m", description="Centre of mass (x, y)")
    theta = State(0.3, unit="rad", description="Rotation of the box (counter-clockwise)")
    vel = State([0.0, 0.0], unit="m/s", description="Velocity of the centre of mass")
    omega = State(0.0, unit="rad/s", description="Angular velocity")
    push = Input([0.0, 0.0], unit="N", description="External force on the centre of mass")
    torque = Input(0.0, unit="N.m", description="External torque")
    mode = Output([0] * 4, type=int, description="Mode of each corner: 0 FREE, 1 COLLISION, 2 CONTACT")
    lam = Output(shape=4, unit="N", description="Normal force of the table on each corner")
    gap = Output(shape=4, unit="m", description="Height of each corner above the table")
    total_force = Output(unit="N", description="Sum of the corner forces")
    energy = Output(unit="J", description="Kinetic + potential + elastic energy")

    #: the continuous part runs as generated C in the FMU; the mode machine (events) stays in
    #: Python and hands the modes over in ``_modes``
    native = NativeKernels(
        derivatives=Kernel(box_derivatives, "_params", "_modes", "states", "push", "torque"),
        event_indicators=Kernel(box_indicators, "_params", "_modes", "states", "push", "torque"),
        outputs=Kernel(box_outputs, "_params", "_modes", "states", "push", "torque", returns=_OUTPUTS),
        attributes={"_params": BoxParams, "_modes": BoxModes})

    def setup(self) -> None:
        super().setup()
        self._params = self._modes = None

    def build_system(self, t: float) -> KernelContactSystem:
        model = BoxModel(self.mass, self.width, self.height, self.inertia if self.inertia > 0.0 else None,
                         tuple(self.com_offset), self.g)
        law = CollisionLaw(restitution=self.e, duration=self.duration,
                           reference_speed=self.reference_speed, exponent=self.exponent)
        self._params = BoxParams(model.mass, model.inertia, model.g,
                                 tuple((float(cx), float(cy)) for cx, cy in model.corners), law_constants(law),
                                 self.alpha0, self.alpha1)
        return KernelContactSystem(model, law, box_evaluate, self._params, alpha0=self.alpha0,
                                   alpha1=self.alpha1, capture_speed=self.capture_speed)

    def apply_inputs(self, system: KernelContactSystem) -> None:
        system.model.force = np.array([self.push[0], self.push[1], self.torque])
        system.inputs = (self.push.tolist(), float(self.torque))

    def publish_modes(self, modes) -> None:
        self.mode = modes
        self._modes = BoxModes(*self.system.discrete())

    def derivatives(self, t: float) -> list:
        self.current_system()
        return box_derivatives(self._params, self._modes, self.states.tolist(), self.push.tolist(), float(self.torque))

    def event_indicators(self, t: float) -> list:
        self.current_system()
        return box_indicators(self._params, self._modes, self.states.tolist(), self.push.tolist(), float(self.torque))

    def outputs(self, t: float) -> None:
        self.current_system()
        self.write_reals(box_outputs(self._params, self._modes, self.states.tolist(), self.push.tolist(),
                                     float(self.torque)), *_OUTPUTS)
