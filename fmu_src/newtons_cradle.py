"""Newton's cradle: up to 7 balls, as pendulums or a free chain, with compliant two-body impacts."""
from deltafmi.component import Experiment, HybridSystemComponent, Kernel, NativeKernels, Output, Parameter, State
from deltafmi.physics.contact.collision_law import CollisionLaw
from deltafmi.physics.contact_problems.cradle_kernels import (CradleModes, CradleParams, cradle_derivatives,
                                                       cradle_indicators, cradle_outputs)
from deltafmi.physics.contact_problems.newtons_cradle import make_cradle

__all__ = ["NewtonsCradle"]

N_MAX = 7


class NewtonsCradle(HybridSystemComponent):
    """Newton's cradle of n (2..7) equal balls; each contact is a two-body compliant impact.

    Pendulums (theta states, rad) or a free chain (x states, m); unused balls are frozen with
    constant indicators. Contact modes: 0 FREE, 1 COLLISION, 2 CONTACT (never used: a cradle has
    no resting loads). The striker, ball 1, is released from striker_angle (pendulums) or moves
    at striker_speed.
    """

    model_name = "NewtonsCradle"
    default_experiment = Experiment(start=0.0, stop=2.0, step=1e-3, tolerance=1e-8)
    n_event_indicators = 2 * (N_MAX - 1)
    cs_options = dict(rtol=1e-9, atol=1e-12)

    n = Parameter(3, type=int, description="Number of balls (2..7)", min=2, max=N_MAX)
    pendulum = Parameter(True, description="Balls hang as pendulums (else a free chain on a line)")
    mass = Parameter(0.1, unit="kg", description="Mass of each ball", min=0.0)
    radius = Parameter(0.0125, unit="m", description="Radius of each ball", min=0.0)
    length = Parameter(0.3, unit="m", description="Pendulum length, pivot to ball centre", min=0.0)
    gap = Parameter(0.0, unit="m", description="Surface gap between neighbours at rest", min=0.0)
    striker_angle = Parameter(0.3, unit="rad", description="Release angle of ball 1 (pendulums; 0: use striker_speed)")
    striker_speed = Parameter(1.0, unit="m/s", description="Initial speed of ball 1 towards the others")
    e = Parameter(1.0, description="Coefficient of restitution of each contact", min=0.01, max=1.0)
    duration = Parameter(1e-4, unit="s", description="Two-ball collision duration at reference_speed", min=0.0)
    reference_speed = Parameter(1.0, unit="m/s", description="Impact speed at which a collision lasts 'duration'")
    exponent = Parameter(3.0, description="Stiffening exponent p of the law (1.5 Hertz, 3 cubic)", min=1.0)
    g = Parameter(9.81, unit="m/s2", description="Gravity (pendulums)")
    q = State([0.0] * N_MAX, initial="calculated", derivative_unit="",
              description="Pendulum angles (rad) or chain positions (m) of balls 1..7")
    v = State([0.0] * N_MAX, initial="calculated", derivative_unit="",
              description="Angular velocities (rad/s) or velocities (m/s)")
    x = Output(shape=N_MAX, unit="m", description="Horizontal position of each ball centre")
    vx = Output(shape=N_MAX, unit="m/s", description="Horizontal velocity of each ball")
    mode = Output([0] * (N_MAX - 1), type=int, description="Mode of contact i (balls i, i+1)")
    lam = Output(shape=N_MAX - 1, unit="N", description="Contact force between balls i and i+1")
    energy = Output(unit="J", description="Kinetic + potential + elastic energy")
    momentum = Output(unit="N.s", description="Horizontal momentum of the balls")

    #: the continuous part (derivatives, indicators, outputs) runs as generated C in the FMU; the
    #: mode machine (events) stays in Python and hands the modes over in ``_modes``
    native = NativeKernels(
        derivatives=Kernel(cradle_derivatives, "_params", "_modes", "states"),
        event_indicators=Kernel(cradle_indicators, "_params", "_modes", "states"),
        outputs=Kernel(cradle_outputs, "_params", "_modes", "states",
                       returns=("x", "vx", "lam", "energy", "momentum")),
        attributes={"_params": CradleParams, "_modes": CradleModes})

    def setup(self) -> None:
        super().setup()
        self._params = self._modes = None

    def build_system(self, t: float):
        if not 2 <= self.n <= N_MAX:
            raise ValueError(f"n must be in 2..{N_MAX}, got {self.n}")
        law = CollisionLaw(restitution=self.e, duration=self.duration,
                           reference_speed=self.reference_speed, exponent=self.exponent)
        system, x0 = make_cradle(
            self.n, pendulum=self.pendulum, mass=self.mass, radius=self.radius, length=self.length,
            gap=self.gap, striker_speed=self.striker_speed,
            striker_angle=self.striker_angle if self.pendulum else 0.0, law=law, n_max=N_MAX, g=self.g,
            kernels=True)
        self._params = system.params
        self.q = x0[:N_MAX]
        self.v = x0[N_MAX:]
        return system

    def publish_modes(self, modes) -> None:
        self.mode = modes
        self._modes = CradleModes(*self.system.discrete())

    def derivatives(self, t: float) -> list:
        self.current_system()
        return cradle_derivatives(self._params, self._modes, self.states.tolist())

    def event_indicators(self, t: float) -> list:
        self.current_system()
        return cradle_indicators(self._params, self._modes, self.states.tolist())

    def outputs(self, t: float) -> None:
        self.current_system()
        self.write_reals(cradle_outputs(self._params, self._modes, self.states.tolist()),
                         "x", "vx", "lam", "energy", "momentum")
