"""Bouncing ball on the FREE / COLLISION / CONTACT framework, with a coefficient of restitution."""
from deltafmi.component import Experiment, HybridSystemComponent, Input, Kernel, NativeKernels, Output, Parameter, State
from deltafmi.physics.contact_problems.restitution_kernels import (BallModes, RestitutionBall, ball_derivatives,
                                                             ball_evaluate, ball_indicators, ball_outputs)
from deltafmi.physics.contact_problems.bouncing_ball import BallModel
from deltafmi.physics.contact.law_kernels import law_constants
from deltafmi.physics.contact_problems.contact_kernels import KernelContactSystem
from deltafmi.physics.contact.collision_law import CollisionLaw

__all__ = ["BouncingBallRestitution"]


class BouncingBallRestitution(HybridSystemComponent):
    """Ball on a floor with a compliant collision law of given restitution and duration.

    Each impact rebounds with e times the impact speed (apex heights scale by e^2); a rebound
    slower than capture_speed is captured into CONTACT (soft stabilised constraint, lambda = weight
    at rest). Modes: 0 FREE, 1 COLLISION, 2 CONTACT.
    """

    model_name = "BouncingBallRestitution"
    default_experiment = Experiment(start=0.0, stop=5.0, step=1e-3, tolerance=1e-8)
    n_event_indicators = 2
    cs_options = dict(rtol=1e-9, atol=1e-11)

    g = Parameter(9.81, unit="m/s2", description="Gravity")
    m = Parameter(1.0, unit="kg", description="Mass of the ball", min=0.0)
    e = Parameter(0.8, description="Coefficient of restitution", min=0.01, max=1.0)
    duration = Parameter(1e-4, unit="s", description="Collision duration at the reference speed", min=0.0)
    reference_speed = Parameter(4.429446918, unit="m/s",
                                description="Impact speed at which a collision lasts 'duration' (a 1 m drop)")
    exponent = Parameter(3.0, description="Stiffening exponent p of the law (1 linear, 1.5 Hertz, 3 cubic)", min=1.0)
    capture_speed = Parameter(0.05, unit="m/s", description="Rebound speed below which the ball stays in CONTACT")
    alpha0 = Parameter(100.0, description="CONTACT law h'' + alpha1 h' + alpha0 h = 0: alpha0 (1/s2)")
    alpha1 = Parameter(20.0, description="CONTACT law: alpha1 (1/s)")
    q = State(1.0, unit="m", description="Height of the ball above the floor")
    v = State(0.0, unit="m/s", description="Vertical velocity")
    F = Input(0.0, unit="N", description="Extra vertical force on the ball")
    mode = Output(0, type=int, description="Floor contact mode: 0 FREE, 1 COLLISION, 2 CONTACT")
    lam = Output(unit="N", description="Contact force of the floor")
    energy = Output(unit="J", description="Kinetic + potential + elastic energy")

    #: the continuous part runs as generated C in the FMU; the mode machine (events) stays in
    #: Python and hands the mode over in ``_modes``
    native = NativeKernels(
        derivatives=Kernel(ball_derivatives, "_params", "_modes", "states", "F"),
        event_indicators=Kernel(ball_indicators, "_params", "_modes", "states", "F"),
        outputs=Kernel(ball_outputs, "_params", "_modes", "states", "F", returns=("lam", "energy")),
        attributes={"_params": RestitutionBall, "_modes": BallModes})

    def setup(self) -> None:
        super().setup()
        self._params = self._modes = None

    def build_system(self, t: float) -> KernelContactSystem:
        law = CollisionLaw(restitution=self.e, duration=self.duration,
                           reference_speed=self.reference_speed, exponent=self.exponent)
        self._params = RestitutionBall(self.m, self.g, law_constants(law), self.alpha0, self.alpha1)
        return KernelContactSystem(BallModel(self.m, self.g), law, ball_evaluate, self._params,
                                   alpha0=self.alpha0, alpha1=self.alpha1, capture_speed=self.capture_speed)

    def apply_inputs(self, system: KernelContactSystem) -> None:
        system.model.force = self.F
        system.inputs = (float(self.F),)

    def publish_modes(self, modes) -> None:
        self.mode = int(modes[0])
        self._modes = BallModes(*self.system.discrete())

    def derivatives(self, t: float) -> list:
        self.current_system()
        return ball_derivatives(self._params, self._modes, self.states.tolist(), float(self.F))

    def event_indicators(self, t: float) -> list:
        self.current_system()
        return ball_indicators(self._params, self._modes, self.states.tolist(), float(self.F))

    def outputs(self, t: float) -> None:
        self.current_system()
        self.lam, self.energy = ball_outputs(self._params, self._modes, self.states.tolist(), float(self.F))
