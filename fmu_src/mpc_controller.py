"""Linear MPC controller FMU: a thin sampled component over deltafmi.physics.control.contact_mpc (OSQP)."""
from deltafmi.component import Clock, Experiment, Input, Output, Parameter, SampledComponent
from deltafmi.physics.control.contact_mpc import PlaneContactMpc, PressTask
from deltafmi.physics.control.model_file import LinearModelFile, find_model_file

__all__ = ["MpcController"]

#: how to make the linear model file
_HOW = ("`deltafmi linearize DeltaRobotContact --set z0=0,0,-1.049 --rest --free u -u u -u f -y y -y yd -y z "
        "-y zd -o NAME`")


class MpcController(SampledComponent):
    """Model-predictive controller of a robot whose tool approaches and presses on a plane.

    Its model is a linearization made by ``deltafmi linearize ... -o NAME`` (NAME.npz, read at
    initialization; a relative path is looked up in the FMU's resources, where a scenario's
    ``resources:`` or ``deltafmi build --resource`` put it, then in the working directory), e.g.
    of the delta robot just above the touching height:
    ``deltafmi linearize DeltaRobotContact --set z0=0,0,-1.049 --rest --free u -u u -u f -y y -y yd
    -y z -y zd -o press_linear``. From it, the hybrid MPC of deltafmi.physics.control.contact_mpc: FREE and
    CONTACT (the contact spring-damper closed around the model's wrist-force input) along the
    horizon by the predicted gap; the wrist tracks r (previewed along rd), the contact force tracks
    `force` in contact, the servo torques stay within [-torque_limit, torque_limit] and the contact
    force under force_limit (soft limits with an exact penalty); with disturbance_gain > 0 it
    estimates a constant servo-torque disturbance (offset-free: an unknown payload). OSQP solves
    the condensed QP each sample, warm-started from the previous plan. Every sample_period it
    reads the servo angles y and rates yd (they give the state), and holds the first move
    (clipped to the torque box against OSQP's tolerance) until the next sample.
    Model Exchange: time events at the sample instants; Co-Simulation: doStep takes the samples
    due in [t, t + h) with the inputs at t.
    """

    model_name = "MpcController"
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3, tolerance=1e-6)

    linear_model = Parameter("mpc_press_model.npz", type=str,
                             description="The .npz written by deltafmi linearize -o (inputs u and f; outputs y, "
                             "yd, z, zd)")
    sample_period = Parameter(4e-3, unit="s", min=0.0, description="Controller sample period")
    sample = Clock(period="sample_period", description="Sample instants: t_start + k * sample_period")
    horizon = Parameter(25, type=int, min=1, description="Prediction horizon (samples)")
    torque_limit = Parameter(40.0, unit="N.m", min=0.0, description="Servo torque bound |u| <= torque_limit")
    force_limit = Parameter(25.0, unit="N", min=0.0, description="Contact force bound fn <= force_limit")
    position_weight = Parameter(1e4, unit="1/m2", min=0.0, description="Cost of the wrist position error")
    velocity_weight = Parameter(10.0, unit="s2/m2", min=0.0, description="Cost of the wrist velocity error")
    force_weight = Parameter(1.0, unit="1/N2", min=0.0, description="Cost of the contact force error (in contact)")
    torque_weight = Parameter(1e-4, unit="1/(N.m)2", min=0.0,
                              description="Cost of the torques' deviation from the linearization's")
    disturbance_gain = Parameter(0.0, min=0.0, max=1.0,
                                 description="Offset-free: per-sample gain of the servo-torque disturbance "
                                 "estimate (0: no disturbance model)")
    qp_tolerance = Parameter(1e-3, min=0.0, description="OSQP's absolute and relative tolerance")
    qp_iterations = Parameter(4000, type=int, min=1,
                              description="OSQP's iteration cap per sample (bounds the solve time; status 1 "
                              "when reached)")
    tool = Parameter([0.0, 0.0, -0.1], unit="m", description="Tool tip relative to the wrist (the model's)")
    surface_height = Parameter(-1.15, unit="m", description="Height at which the plane crosses the robot axis")
    surface_normal = Parameter([0.0, 0.0, 1.0], description="Plane normal, pointing towards the robot")
    contact_stiffness = Parameter(2e5, unit="N/m", min=0.0, description="Contact spring (the model's)")
    contact_damping = Parameter(2e3, unit="N.s/m", min=0.0, description="Contact damper (the model's)")

    y = Input([0.0] * 3, unit="rad", description="Measured servo angles")
    yd = Input([0.0] * 3, unit="rad/s", description="Measured servo rates")
    r = Input([0.0, 0.0, -1.0], unit="m", description="Reference wrist position")
    rd = Input([0.0] * 3, unit="m/s", description="Reference wrist velocity")
    force = Input(20.0, unit="N", description="Commanded contact force (pushing on the plane)")

    u = Output(shape=3, unit="N.m", variability="discrete", description="Servo torques (held)")
    predicted_force = Output(unit="N", variability="discrete",
                             description="Contact force the model gives the measured state (in contact)")
    contact = Output(0, type=int, description="1 when the model puts the tool in contact")
    time_qp = Parameter(False, type=bool,
                        description="Put the wall-clock time of each QP in solve_time (off: 0; a clock makes runs differ)")
    solve_time = Output(unit="s", variability="discrete", description="Wall-clock time of the last QP (time_qp)")
    iterations = Output(0, type=int, description="OSQP iterations of the last QP")
    status = Output(0, type=int, description="0 solved, 1 solved inaccurately or at the iteration limit, "
                    "2 the plan exceeds force_limit by more than 1 %")

    def setup(self) -> None:
        self._mpc = None

    def initialize(self, t: float) -> None:
        self.start_sampling(t)
        task = PressTask(tool=list(self.tool), plane_point=[0.0, 0.0, self.surface_height],
                         normal=list(self.surface_normal), stiffness=self.contact_stiffness,
                         damping=self.contact_damping, position_weight=self.position_weight,
                         velocity_weight=self.velocity_weight, force_weight=self.force_weight,
                         effort_weight=self.torque_weight, effort_min=[-self.torque_limit] * 3,
                         effort_max=[self.torque_limit] * 3, force_limit=self.force_limit,
                         sample_period=self.sample_period, horizon=int(self.horizon),
                         tolerance=self.qp_tolerance, disturbance_gain=self.disturbance_gain,
                         max_iterations=int(self.qp_iterations))
        self._mpc = PlaneContactMpc(LinearModelFile.read(find_model_file(self.linear_model, self.resources_dir, _HOW)), task)

    def take_sample(self) -> None:
        v = self.read_reals("y", "yd", "r", "rd", "force")
        u, plan, touching = self._mpc.step(v[0:6], v[6:9], v[9:12], v[12])
        x = plan.x[0]
        self.write_reals([*u, self._mpc.force(x), plan.solve_time if self.time_qp else 0.0], "u", "predicted_force",
                         "solve_time")
        self.contact, self.iterations = int(touching), plan.iterations
        self.status = 0 if plan.status == "solved" else 1
        if plan.slack > 1e-2 * max(self.force_limit, 1.0):  # well above OSQP's tolerance
            self.status = 2
