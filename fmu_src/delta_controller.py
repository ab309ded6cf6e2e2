"""Delta robot controller FMU: a thin sampled component over deltafmi.physics.delta.control."""
from deltafmi.component import Clock, Component, Experiment, Input, Kernel, NativeKernels, Output, Parameter
from deltafmi.physics.delta import control as delta_control
from deltafmi.physics.delta.control_law import ControlLaw
from deltafmi.physics.delta.sampling import F3, SampleSettings, SampleState, sample, warning_text
from deltafmi.models.robot_parameters import robot_parameters

__all__ = ["DeltaController"]

#: the robot's parameters, as the controller models them (they may differ from the plant's)
ControllerRobotModel = robot_parameters("as the controller models it")


def controller_step(law: ControlLaw, settings: SampleSettings, state: SampleState, longest_step: float, t0: float,
                    k: int, t: float, h: float, y: F3, yd: F3, r: F3, rd: F3, rdd: F3, force: F3, tactile: float,
                    z_est: F3) -> tuple[SampleState, int, int, F3, float, F3, float, int]:
    """The Co-Simulation step from ``t`` over ``h`` (DeltaController.do_step, and the FMU's compiled
    step): the samples due in [t, t + h) with the inputs at t. Returns the new state, the
    next sample's index, a flag for Python (a sample raised a warning, or the step is longer than
    the sample period: both are logged), and the outputs u, cond_Jc, z_est, shift, status."""
    period = settings.sample_period
    defer = 1 if h > longest_step else 0
    end = t + h - 1e-9 * period
    while t0 + k * period < end:
        state = sample(law, settings, state, y, yd, r, rd, rdd, force, tactile)
        defer = defer | state.new_warnings
        k += 1
    z = z_est if state.z is None else state.z
    return state, k, defer, state.u, state.cond, z, state.shift, state.status


def controller_update(law: ControlLaw, settings: SampleSettings, state: SampleState, t0: float, k: int, t: float,
                      y: F3, yd: F3, r: F3, rd: F3, rdd: F3, force: F3, tactile: float,
                      z_est: F3) -> tuple[SampleState, int, int, float, F3, float, F3, float, int]:
    """The event update at ``t`` (DeltaController.update, and the FMU's compiled update: Model
    Exchange's time events, FMI 3.0's Clock ticks): the sample due at ``t``, if any. Returns the new state, the next sample's index, a flag for Python (a warning to
    log), the next sample instant, and the outputs u, cond_Jc, z_est, shift, status."""
    period = settings.sample_period
    defer = 0
    if t >= t0 + k * period - 1e-9 * period:
        state = sample(law, settings, state, y, yd, r, rd, rdd, force, tactile)
        defer = state.new_warnings
        k += 1
        while t0 + k * period <= t:  # never schedule an instant already passed
            k += 1
    z = z_est if state.z is None else state.z
    return state, k, defer, t0 + k * period, state.u, state.cond, z, state.shift, state.status


class DeltaController(ControllerRobotModel, Component):
    """Feedback-linearising wrist-position controller of the delta robot, sampled (1 kHz).

    At every sample instant t_k = t_start + k * sample_period it reads the servo angles y and
    rates yd and the reference r, rd, rdd, estimates the wrist position (Newton forward
    kinematics, warm-started) and outputs the servo torques
    u = My Jc^-1 (kI int(r - z) + kP (r - z) + kD (rd - zd) + rdd) + velocity terms + gravity,
    held until the next sample. Impedance (soft-contact) mode, impedance = true: no PID; the outer
    loop is the wrist force stiffness (r - z) + task_damping (rd - zd) + force per world axis, with
    rdd fed forward through the robot's own inertia (u adds Jc^T of that force), so the robot is
    a mass-spring-damper about r in free space, at an impact and while pressing, with no switching.
    In either mode the tactile input (a pad-force difference, N) moves the reference along
    tactile_axis at tactile_gain * tactile m/s: the tactile loop that centres the tool on a
    feature. Model Exchange: time events at the sample instants. Co-Simulation:
    doStep(t, h) takes the samples due in [t, t + h) with the inputs given at t (use h equal to
    the sample period; a longer h gets one warning). The kinematic and inertial parameters and the joint damping (compensated)
    are the controller's own model of the robot (the DeltaRobot plant's declarations,
    deltafmi.models.robot_parameters) and may differ from the plant's.
    """

    model_name = "DeltaController"
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3, tolerance=1e-6)

    pole = Parameter(7.0, unit="1/s", min=0.0,
                     description="Outer-loop triple pole p: kI = p^3, kP = 3 p^2, kD = 3 p")
    kI = Parameter(-1.0, unit="1/s3", description="Integral gain; negative: p^3 from pole")
    kP = Parameter(-1.0, unit="1/s2", description="Proportional gain; negative: 3 p^2 from pole")
    kD = Parameter(-1.0, unit="1/s", description="Derivative gain; negative: 3 p from pole")
    integral_limit = Parameter(1.0, unit="m/s2", min=0.0,
                               description="Bound on the integral action kI*int(r - z) per axis")
    feedforward = Parameter(True, description="Feed the reference acceleration rdd forward")
    coriolis = Parameter(True, description="Compensate velocity terms (false: the seed's law)")
    zoh_lead = Parameter(True, description="Half-sample torque lead compensating the hold")
    newton_fk = Parameter(True, description="Newton forward kinematics (false: closed form)")
    torque_limit = Parameter(300.0, unit="N.m", min=0.0, description="Servo torque saturation")
    cond_limit = Parameter(100.0, min=1.0,
                           description="Status bit 4 (ill-conditioned) above this cond(Jc)")
    sample_period = Parameter(1e-3, unit="s", min=0.0, description="Controller sample period")
    #: FMI 3.0: the sample instants t_start + k * sample_period as a periodic input Clock
    sample = Clock(period="sample_period", description="Sample instants: t_start + k * sample_period")
    impedance = Parameter(False, description="Impedance (soft-contact) mode instead of the PID position loop")
    stiffness = Parameter([5000.0, 5000.0, 1000.0], unit="N/m", min=0.0,
                          description="Impedance mode: commanded stiffness per world axis x, y, z")
    task_damping = Parameter([400.0, 400.0, 250.0], unit="N.s/m", min=0.0,
                             description="Impedance mode: commanded damping per world axis x, y, z")
    tactile_gain = Parameter(0.0, unit="m/(N.s)",
                             description="Tactile loop: reference speed along tactile_axis per N of pad difference")
    tactile_axis = Parameter([1.0, 0.0, 0.0], description="Tactile loop: horizontal direction of the pad axis")

    y = Input([0.0] * 3, unit="rad", description="Measured servo angles")
    yd = Input([0.0] * 3, unit="rad/s", description="Measured servo rates")
    r = Input([0.0, 0.0, -1.0], unit="m", description="Reference wrist position")
    rd = Input([0.0] * 3, unit="m/s", description="Reference wrist velocity")
    rdd = Input([0.0] * 3, unit="m/s2", description="Reference wrist acceleration")
    force = Input([0.0] * 3, unit="N",
                  description="Impedance mode: commanded contact force, exerted by the tool on the world")
    tactile = Input(0.0, unit="N", description="Tactile sensor: pad-force difference (pad 1 - pad 2)")

    u = Output(shape=3, unit="N.m", variability="discrete", description="Servo torques (held)")
    cond_Jc = Output(variability="discrete",
                     description="Frobenius condition number of the control Jacobian Jc")
    status = Output(0, type=int, description="Status bits: 1 torque saturated, 2 integral "
                    "clamped, 4 near a singularity, 8 singular (torque held)")
    z_est = Output(shape=3, unit="m", variability="discrete",
                   description="Wrist position estimated by forward kinematics")
    shift = Output(unit="m", variability="discrete",
                   description="Tactile loop: shift of the reference along tactile_axis")

    #: Co-Simulation steps and event updates in C (generated from controller_step and
    #: controller_update), with no Python
    native = NativeKernels(
        step=Kernel(controller_step, "_ctl.law", "_ctl.settings", "_ctl.state", "_longest_step", "_t0", "_k", "t", "h",
                    "y", "yd", "r", "rd", "rdd", "force", "tactile", "z_est", updates=("_ctl.state", "_k"),
                    defer=True, returns=("u", "cond_Jc", "z_est", "shift", "status")),
        update=Kernel(controller_update, "_ctl.law", "_ctl.settings", "_ctl.state", "_t0", "_k", "t", "y", "yd", "r",
                      "rd", "rdd", "force", "tactile", "z_est", updates=("_ctl.state", "_k"), defer=True,
                      returns=("u", "cond_Jc", "z_est", "shift", "status")),
        attributes={"_ctl.law": ControlLaw, "_ctl.settings": SampleSettings, "_ctl.state": SampleState,
                    "_longest_step": float, "_t0": float, "_k": int})

    def setup(self) -> None:
        self._ctl = None
        self._t0 = 0.0
        self._k = 0          # index of the next sample instant

    def initialize(self, t: float) -> None:
        if not self.sample_period > 0.0:
            raise ValueError(f"sample_period must be > 0, got {self.sample_period}")
        model = self.robot_params()
        self._ctl = delta_control.DeltaController(
            model, pole=self.pole, kI=self.kI, kP=self.kP, kD=self.kD,
            integral_limit=self.integral_limit, feedforward=self.feedforward,
            torque_limit=self.torque_limit, sample_period=self.sample_period,
            coriolis=self.coriolis, zoh_lead=self.zoh_lead,
            fk="newton" if self.newton_fk else "closed", cond_limit=self.cond_limit,
            impedance=self.impedance, stiffness=self.stiffness, task_damping=self.task_damping,
            tactile_gain=self.tactile_gain, tactile_axis=self.tactile_axis)
        self._t0, self._k = t, 0
        self._longest_step = self.sample_period * (1.0 + 1e-9)  # longer: warn once (do_step)

    def _inputs(self) -> tuple:
        """y, yd, r, rd, rdd, force, tactile and the estimate held, as the kernels take them (lists:
        one read_reals is cheaper than eight attribute reads)."""
        v = self.read_reals("y", "yd", "r", "rd", "rdd", "force", "tactile", "z_est")
        return v[0:3], v[3:6], v[6:9], v[9:12], v[12:15], v[15:18], v[18], v[19:22]

    def _publish(self, before: SampleState, state: SampleState, u: F3, cond: float, z: F3, shift: float,
                 status: int) -> None:
        """The state and the outputs after samples; a warning for each status bit they raised first."""
        self._ctl.state = state
        self.write_reals((*u, cond, *z, shift), "u", "cond_Jc", "z_est", "shift")
        self.status = status
        new = state.warned & ~before.warned
        if new:
            self.log(warning_text(state._replace(new_warnings=new), self._ctl.law.torque_limit), level="warning")

    def update(self, t: float) -> None:
        ctl = self._ctl
        before = ctl.state
        state, self._k, _, _, *outputs = controller_update(ctl.law, ctl.settings, before, self._t0, self._k, t,
                                                           *self._inputs())
        self._publish(before, state, *outputs)

    def next_time_event(self, t: float) -> float:
        return self._t0 + self._k * self.sample_period

    def do_step(self, t: float, h: float) -> None:
        if h > self._longest_step:
            self._warn_long_step(h)
        ctl = self._ctl
        before = ctl.state
        state, self._k, _, *outputs = controller_step(ctl.law, ctl.settings, before, self._longest_step, self._t0,
                                                      self._k, t, h, *self._inputs())
        self._publish(before, state, *outputs)

    def _warn_long_step(self, h: float) -> None:
        """Once per run: a communication step longer than the sample period changes the loop."""
        self._longest_step = float("inf")
        self.log(f"communication step {h:g} s is longer than sample_period {self.sample_period:g} s: the "
                 "samples inside a step all see the inputs at its start, a different closed loop from the "
                 "sampled controller's; use a step of at most sample_period", level="warning")
