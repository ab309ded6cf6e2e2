"""Assembly controller FMU: 6-D impedance control of the delta robot with its spherical wrist and a
peg-in-hole insertion program, a thin sampled component over deltafmi.physics.assembly."""
import math

from deltafmi.component import Clock, Component, Experiment, Input, Kernel, NativeKernels, Output, Parameter
from deltafmi.physics.assembly import law as assembly_law
from deltafmi.physics.assembly.law import AssemblyLaw
from deltafmi.physics.assembly.program import InsertionProgram, hole_frame, make_program
from deltafmi.physics.assembly.rotation import F3
from deltafmi.physics.assembly.sampling import (AssemblySettings, AssemblyState, describe_status, initial_state,
                                                  sample)
from deltafmi.physics.wrist.kernels import WristConstants
from deltafmi.models.robot_parameters import robot_parameters
from deltafmi.models.wrist_declarations import hole_parameters, wrist_parameters
from deltafmi.models.wrist_parameters import wrist_params_of

__all__ = ["AssemblyController"]

F6 = tuple[float, float, float, float, float, float]
#: the robot's parameters as the controller models them (they may differ from the plant's)
ControllerRobotModel = robot_parameters("as the controller models it")
#: the wrist and its tool as the controller models them, and the hole the program aims at
ControllerWristModel = wrist_parameters("as the controller models it")
NominalHole = hole_parameters("nominal", names=("hole_position", "hole_tilt"))
#: the kernels' outputs, in order
OUTPUTS = ("u", "tau", "tip_est", "error", "rotation_error", "r_ref", "depth_ref", "phase", "status", "sigma_min")
#: the measurements and the external reference, in the kernels' order
INPUTS = ("y", "yd", "qw", "qwd", "ft", "r", "rd", "rdd", "phi", "phid", "phidd")


def _outputs(state: AssemblyState) -> tuple:
    return (state.u, state.tau, state.tip, state.error, state.rotation_error, state.r, state.depth_ref, state.phase,
            state.status, state.sigma_min)


def controller_step(law: AssemblyLaw, w: WristConstants, settings: AssemblySettings, program: InsertionProgram,
                    state: AssemblyState, longest_step: float, t0: float, k: int, t: float, h: float, y: F3,
                    yd: F3, qw: F3, qwd: F3, ft: F6, r: F3, rd: F3, rdd: F3, phi: F3, phid: F3, phidd: F3) -> tuple:
    """The Co-Simulation step from ``t`` over ``h``: the samples due in [t, t + h) with the inputs at
    t. Returns the state, the next sample's index, a flag for Python (a new warning, or a step
    longer than the sample period) and the outputs (OUTPUTS)."""
    period = settings.sample_period
    defer = 1 if h > longest_step else 0
    end = t + h - 1e-9 * period
    while t0 + k * period < end:
        state = sample(law, w, settings, program, state, k * period, y, yd, qw, qwd, ft, r, rd, rdd, phi, phid, phidd)
        defer = defer | state.new_warnings
        k += 1
    return (state, k, defer) + _outputs(state)


def controller_update(law: AssemblyLaw, w: WristConstants, settings: AssemblySettings, program: InsertionProgram,
                      state: AssemblyState, t0: float, k: int, t: float, y: F3, yd: F3, qw: F3, qwd: F3, ft: F6,
                      r: F3, rd: F3, rdd: F3, phi: F3, phid: F3, phidd: F3) -> tuple:
    """The event update at ``t`` (Model Exchange's time events, FMI 3.0's Clock ticks): the sample
    due at ``t``, if any. Returns the state, the next index, the warning flag, the next sample
    instant and the outputs."""
    period = settings.sample_period
    defer = 0
    if t >= t0 + k * period - 1e-9 * period:
        state = sample(law, w, settings, program, state, k * period, y, yd, qw, qwd, ft, r, rd, rdd, phi, phid, phidd)
        defer = state.new_warnings
        k += 1
        while t0 + k * period <= t:
            k += 1
    return (state, k, defer, t0 + k * period) + _outputs(state)


class AssemblyController(NominalHole, ControllerWristModel, ControllerRobotModel, Component):
    """6-D impedance controller of the delta robot with a spherical wrist (DeltaWrist,
    DeltaWristPeg), sampled (1 kHz), with a built-in peg-in-hole insertion program.

    At every sample it reads the servo angles/rates y, yd, the wrist angles/rates qw, qwd and the
    tool-frame force/torque sensor ft (force, and moment about the tool tip, on the peg) and
    outputs servo torques u and wrist torques tau, held until the next sample. The law
    (deltafmi/physics/assembly/law.py) is the delta's feedback linearisation with an inner
    computed-torque loop on the wrist, exact coupling both ways: in the NOMINAL hole frame the tip
    error e and the orientation error eR (rotation vector) obey per axis
    mass e'' + D e' + stiffness e = F and inertia eR'' + D_r eR' + rot_stiffness eR = M (F, M the
    sensed contact wrench at the tip), D = 2 zeta sqrt(stiffness mass): the chosen second-order
    dynamics in free space, the chosen impedance in contact, no switching.

    Reference: program = true runs the insertion program (approach above the nominal hole
    hole_position/hole_tilt from the pose at the first sample over approach_time, descent at
    entry_speed to entry_depth and on at insertion_speed to final_depth, axial push bounded by
    push_force); program = false follows
    the inputs r, rd, rdd (tool tip, world) and phi, phid, phidd (tool orientation as the
    rotation vector of R_ref R_down^T, R_down the tool-down pose, world). The kinematic and
    inertial parameters are the controller's own model of the robot and the wrist (the plant's
    declarations and names) and may differ from the plant's; payload is what the plate carries
    besides the wrist and its tool (those are the wrist parameters; the law compensates
    wrist_damping). Model Exchange: time events at the sample instants; Co-Simulation: use a
    communication step equal to the sample period.
    """

    model_name = "AssemblyController"
    default_experiment = Experiment(start=0.0, stop=2.0, step=1e-3, tolerance=1e-6)

    # the impedance, per axis of the nominal hole frame (x, y lateral, z along the hole)
    mass = Parameter([5.0, 5.0, 10.0], unit="kg", min=0.0, description="Apparent mass of the tip per hole axis, > 0")
    stiffness = Parameter([500.0, 500.0, 2000.0], unit="N/m", min=0.0, description="Tip stiffness per hole axis")
    inertia = Parameter([0.02, 0.02, 0.02], unit="kg.m2", min=0.0,
                        description="Apparent inertia of the tool about the tip per hole axis, > 0")
    rot_stiffness = Parameter([2.0, 2.0, 2.0], unit="N.m/rad", min=0.0,
                              description="Rotational stiffness about the tip per hole axis")
    zeta = Parameter(1.0, min=0.0, description="Damping ratio of every axis: D = 2 zeta sqrt(K M)")
    sigma0 = Parameter(0.2, min=0.0, max=1.0,
                       description="Gimbal lock: damped inverse of J_w below this smallest singular value")
    torque_limit = Parameter(300.0, unit="N.m", min=0.0, description="Servo torque saturation")
    wrist_torque_limit = Parameter(20.0, unit="N.m", min=0.0, description="Wrist torque saturation")
    cond_limit = Parameter(100.0, min=1.0, description="Status bit 4 (delta ill-conditioned) above this cond(Jc)")
    sample_period = Parameter(1e-3, unit="s", min=0.0, description="Controller sample period")
    zoh_lead = Parameter(True, description="Half-sample lead compensating the hold, on the torque's motion part "
                         "(the measured wrench's part is held as computed)")
    sample = Clock(period="sample_period", description="Sample instants: t_start + k * sample_period")
    # the insertion program (the nominal hole it aims at: NominalHole)
    program = Parameter(True, description="Run the insertion program (false: follow the reference inputs)")
    approach_height = Parameter(0.02, unit="m", min=0.0,
                                description="Program: tip height above the hole at the approach's end")
    approach_time = Parameter(0.5, unit="s", min=0.0, description="Program: duration of the approach")
    insertion_speed = Parameter(0.02, unit="m/s", min=0.0,
                                description="Program: descent speed along the hole axis below entry_depth")
    entry_speed = Parameter(0.02, unit="m/s", min=0.0,
                            description="Program: descent speed above entry_depth (where the peg meets the chamfer)")
    entry_depth = Parameter(0.004, unit="m", description="Program: depth below the hole top where entry_speed ends")
    final_depth = Parameter(0.03, unit="m", description="Program: depth below the hole top where the descent stops")
    push_force = Parameter(20.0, unit="N", min=0.0, description="Program: bound on the static axial push")

    y = Input([0.0] * 3, unit="rad", description="Measured servo angles")
    yd = Input([0.0] * 3, unit="rad/s", description="Measured servo rates")
    qw = Input([0.0] * 3, unit="rad", description="Measured wrist joint angles")
    qwd = Input([0.0] * 3, unit="rad/s", description="Measured wrist joint rates")
    ft = Input([0.0] * 6, unit="1",
               description="Force/torque sensor, tool frame: force on the peg (N), moment about the tip (N m)")
    r = Input([0.0, 0.0, -1.1], unit="m", description="Reference tool tip (program = false)")
    rd = Input([0.0] * 3, unit="m/s", description="Reference tip velocity (program = false)")
    rdd = Input([0.0] * 3, unit="m/s2", description="Reference tip acceleration (program = false)")
    phi = Input([0.0] * 3, unit="rad", description="Reference orientation: rotation vector from tool-down, world")
    phid = Input([0.0] * 3, unit="rad/s", description="Its rate")
    phidd = Input([0.0] * 3, unit="rad/s2", description="Its second derivative")

    u = Output(shape=3, unit="N.m", variability="discrete", description="Servo torques (held)")
    tau = Output(shape=3, unit="N.m", variability="discrete", description="Wrist torques (held)")
    tip_est = Output(shape=3, unit="m", variability="discrete", description="Tool tip estimated from the joint angles")
    error = Output(shape=3, unit="m", variability="discrete", description="Tip error, nominal hole frame")
    rotation_error = Output(shape=3, unit="rad", variability="discrete",
                            description="Orientation error (rotation vector), nominal hole frame")
    r_ref = Output(shape=3, unit="m", variability="discrete", description="The tip reference of the last sample")
    depth_ref = Output(unit="m", variability="discrete",
                       description="Program: reference depth below the nominal hole top")
    phase = Output(0, type=int, description="Program: 0 external reference, 1 approach, 2 descent, 3 hold")
    status = Output(0, type=int, description="Status bits: 1 servo torque saturated, 4 delta near a singularity, "
                    "8 singular (torques held), 16 wrist near gimbal lock (damped), 32 wrist torque saturated")
    sigma_min = Output(1.0, unit="1", variability="discrete",
                       description="Wrist distance from gimbal lock sqrt(1 - |sin q2|)")

    native = NativeKernels(
        step=Kernel(controller_step, "_law", "_wrist", "_settings", "_program", "_state", "_longest_step", "_t0", "_k",
                    "t", "h", *INPUTS, updates=("_state", "_k"), defer=True, returns=OUTPUTS),
        update=Kernel(controller_update, "_law", "_wrist", "_settings", "_program", "_state", "_t0", "_k", "t", *INPUTS,
                      updates=("_state", "_k"), defer=True, returns=OUTPUTS),
        attributes={"_law": AssemblyLaw, "_wrist": WristConstants, "_settings": AssemblySettings,
                    "_program": InsertionProgram, "_state": AssemblyState, "_longest_step": float, "_t0": float,
                    "_k": int})

    def setup(self) -> None:
        self._law = self._wrist = self._settings = self._program = self._state = None
        self._t0, self._k = 0.0, 0
        self._longest_step = math.inf

    def initialize(self, t: float) -> None:
        if not self.sample_period > 0.0:
            raise ValueError(f"sample_period must be > 0, got {self.sample_period}")
        tilt = (float(self.hole_tilt[0]), float(self.hole_tilt[1]))
        impedance = assembly_law.gains(self.mass, self.stiffness, self.inertia, self.rot_stiffness, self.zeta)
        self._law, self._wrist = assembly_law.make_assembly_law(self.robot_params(), wrist_params_of(self), self.mount,
                                                   hole_frame(tilt), impedance, self.sigma0, self.torque_limit,
                                                   self.wrist_torque_limit, self.cond_limit)
        self._program = make_program(tuple(self.hole_position), tilt, self.approach_height, self.approach_time,
                                     self.insertion_speed, self.final_depth, self.push_force, impedance.stiffness[2],
                                     self.entry_speed, self.entry_depth)
        self._settings = AssemblySettings(float(self.sample_period), bool(self.zoh_lead), bool(self.program))
        self._state = initial_state(tuple(float(c) for c in self.r))
        self._t0, self._k = t, 0
        self._longest_step = self.sample_period * (1.0 + 1e-9)

    def _inputs(self) -> tuple:
        v = self.read_reals(*INPUTS)
        return (v[0:3], v[3:6], v[6:9], v[9:12], v[12:18], v[18:21], v[21:24], v[24:27], v[27:30], v[30:33],
                v[33:36])

    def _publish(self, before: AssemblyState, outputs: tuple) -> None:
        u, tau, tip, error, rot_error, r, depth, phase, status, sigma = outputs
        self.write_reals((*u, *tau, *tip, *error, *rot_error, *r, depth, sigma), "u", "tau", "tip_est", "error",
                         "rotation_error", "r_ref", "depth_ref", "sigma_min")
        self.phase, self.status = phase, status
        new = self._state.warned - (self._state.warned & before.warned)
        if new:
            self.log(f"assembly controller: {describe_status(new)}", level="warning")

    def update(self, t: float) -> None:
        before = self._state
        self._state, self._k, _, _, *outputs = controller_update(self._law, self._wrist, self._settings, self._program,
                                                                 before, self._t0, self._k, t, *self._inputs())
        self._publish(before, tuple(outputs))

    def next_time_event(self, t: float) -> float:
        return self._t0 + self._k * self.sample_period

    def do_step(self, t: float, h: float) -> None:
        if h > self._longest_step:
            self._longest_step = math.inf
            self.log(f"communication step {h:g} s is longer than sample_period {self.sample_period:g} s: the samples "
                     "inside a step all see the inputs at its start; use a step of at most sample_period",
                     level="warning")
        before = self._state
        self._state, self._k, _, *outputs = controller_step(self._law, self._wrist, self._settings, self._program,
                                                            before, self._longest_step, self._t0, self._k, t, h,
                                                            *self._inputs())
        self._publish(before, tuple(outputs))
