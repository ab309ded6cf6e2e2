"""The 6-DOF plant FMU: the delta robot with a spherical wrist, a thin component over
deltafmi.physics.delta_wrist (RL5 delta, the default wrist and a steel peg)."""
from deltafmi.component import Component, Experiment, Input, Kernel, NativeKernels, Output, Parameter, State
from deltafmi.physics import delta
from deltafmi.physics.delta.params import DeltaParams
from deltafmi.physics.delta_wrist import dynamics
from deltafmi.physics.delta_wrist.dynamics import project_state
from deltafmi.physics.delta_wrist.params import WristMount
from deltafmi.physics.wrist.kernels import WristConstants, wrist_constants
from deltafmi.models.robot_parameters import RobotParameters
from deltafmi.models.wrist_declarations import WristParameters
from deltafmi.models.wrist_parameters import wrist_params_of

__all__ = ["ARGUMENTS", "DeltaWrist", "OUTPUTS", "project_state"]

#: the outputs, in the order dynamics.plant_outputs returns them
OUTPUTS = ("y", "yd", "qw", "qwd", "z", "zd", "tip", "tip_velocity", "R", "omega", "centre", "lam", "residual",
           "energy", "gimbal")
#: the kernels' arguments: delta, wrist, mount, the 24 states, inputs, Baumgarte pole
ARGUMENTS = ("_plant", "_wrist", "_mount", "states", "u", "tau", "f", "moment", "pole")


class DeltaWrist(WristParameters, RobotParameters, Component):
    """RL5 delta robot carrying a 3-DOF direct-drive spherical wrist (Z-X-Y axes) with a peg tool.

    States: the delta's nine joint angles (loops closed by multipliers solved at every evaluation,
    Baumgarte-stabilised) and the wrist's three joint angles qw, and their rates. The wrist centre
    O hangs at `mount` from the plate centre; the tool (a solid cylinder of tool_mass, tool_length,
    tool_radius) points down from O at qw = 0, its tip tool_tip from O. Inputs: servo torques u,
    wrist joint torques tau, a force f on the tool tip and a moment on the tool (world frame). The
    robot starts at rest with the tip at tip0 and the wrist at qw0 (inverse kinematics; an
    unreachable tip fails initialization with the plate centre it needs and the workspace).
    Gimbal lock is |q2| = pi/2 (output gimbal = |cos q2| -> 0); the dynamics stay regular there.
    Frame: z up, as DeltaRobot.
    """

    model_name = "DeltaWrist"
    direct_feedthrough = {"lam": ["u", "tau", "f", "moment"]}
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3, tolerance=1e-8)

    pole = Parameter(5.0, unit="1/s", min=0.0,
                     description="Baumgarte pole p: hdd + 2 p hd + p^2 h = 0 stabilises the loops")
    loop_tolerance = Parameter(
        0.0, unit="m", min=0.0,
        description="Model Exchange: after an integrator step with loop residual |h| above this, a step event "
        "projects the state onto the closed loops; 0: never (Co-Simulation projects after every step)")
    tip0 = Parameter([0.0, 0.0, -1.18], unit="m", description="Initial tool tip position; the robot starts at rest")
    qw0 = Parameter([0.0, 0.0, 0.0], unit="rad", description="Initial wrist joint angles (0: tool pointing down)")

    # nominals scale the solvers' absolute tolerance (atol = rtol * nominal)
    q = State([0.0] * 9, unit="rad", initial="calculated", nominal=0.01,
              description="Delta joint angles per arm: servo q_i1, forearm polar q_i2, azimuth q_i3")
    # the wrist's angles swing over radians (and its outputs, the tool's rotation, are flat near
    # qw = 0): their scale is 1 rad, for the solvers' tolerances and the runtime's differences
    q_w = State([0.0] * 3, unit="rad", initial="calculated", nominal=1.0,
                description="Wrist joint angles (Z-X-Y axes)")
    v = State([0.0] * 9, unit="rad/s", initial="calculated", nominal=0.01, description="Delta joint rates")
    v_w = State([0.0] * 3, unit="rad/s", initial="calculated", nominal=1.0, description="Wrist joint rates")

    u = Input([0.0] * 3, unit="N.m", description="Servo torques")
    tau = Input([0.0] * 3, unit="N.m", description="Wrist joint torques")
    f = Input([0.0] * 3, unit="N", description="Force on the tool tip, world frame")
    moment = Input([0.0] * 3, unit="N.m", description="Moment (couple) on the tool, world frame")

    y = Output(shape=3, unit="rad", description="Servo angles q_i1 (measured)")
    yd = Output(shape=3, unit="rad/s", description="Servo rates")
    qw = Output(shape=3, unit="rad", description="Wrist joint angles (measured)")
    qwd = Output(shape=3, unit="rad/s", description="Wrist joint rates (measured)")
    z = Output(shape=3, unit="m", description="Plate centre position")
    zd = Output(shape=3, unit="m/s", description="Plate centre velocity, Jv v")
    tip = Output(shape=3, unit="m", description="Tool tip position")
    tip_velocity = Output(shape=3, unit="m/s", description="Tool tip velocity")
    R = Output(shape=9, unit="1", description="Tool rotation (world <- tool), row-major; R[3], R[6], R[9]: the "
               "tool axis")
    omega = Output(shape=3, unit="rad/s", description="Tool angular velocity, world frame")
    centre = Output(shape=3, unit="m", description="Wrist centre O (where the three wrist axes meet)")
    lam = Output(shape=6, unit="N", name="lambda",
                 description="Loop-closure forces (world), as in DeltaRobot")
    residual = Output(unit="m", description="Loop-closure residual |h(q)| (Euclidean norm)")
    energy = Output(unit="J", description="Kinetic plus potential energy (zero potential at z = 0)")
    gimbal = Output(unit="1", description="Distance from gimbal lock |cos q2| (1: tool down, 0: locked)")

    #: what the FMU's C layer computes itself (generated from the same kernels as the methods below)
    native = NativeKernels(
        derivatives=Kernel(dynamics.state_derivative, *ARGUMENTS),
        outputs=Kernel(dynamics.plant_outputs, *ARGUMENTS, returns=OUTPUTS),
        project=Kernel(project_state, "_plant", "_wrist", "states"),
        attributes={"_plant": DeltaParams, "_wrist": WristConstants, "_mount": WristMount})

    def setup(self) -> None:
        self._plant = None  # DeltaParams, WristConstants and WristMount, built at initialization
        self._wrist = None
        self._mount = None

    def initialize(self, t: float) -> None:
        self._plant = self.robot_params()
        self._wrist = wrist_constants(wrist_params_of(self))
        self._mount = WristMount(*(float(c) for c in self.mount))
        self.states[:] = dynamics.start_state(self._plant, self._wrist, self._mount, self.tip0, self.qw0)

    def project(self, t: float) -> None:
        """Close the loops (mass-weighted): CS after every solver step, ME at a step event once the
        residual exceeds loop_tolerance."""
        self.states[:] = project_state(self._plant, self._wrist, self.states.tolist())  # the kernel C runs

    def needs_projection(self, t: float) -> bool:
        tolerance = self.loop_tolerance
        return tolerance > 0.0 and delta.loop_residual(self._plant, self.q) > tolerance

    def derivatives(self, t: float) -> list:
        return dynamics.state_derivative(self._plant, self._wrist, self._mount, self.states, self.u, self.tau,
                                         self.f, self.moment, self.pole)

    def outputs(self, t: float) -> None:
        values = dynamics.plant_outputs(self._plant, self._wrist, self._mount, self.states, self.u, self.tau, self.f,
                                        self.moment, self.pole)
        self.write_reals([v for item in values for v in (item if isinstance(item, tuple) else (item,))], *OUTPUTS)
