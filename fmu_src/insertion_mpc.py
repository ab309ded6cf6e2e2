"""Insertion MPC FMU: plans the tool tip reference of an impedance-controlled peg insertion
(a thin sampled component over deltafmi.physics.control.insertion, DAQP or OSQP)."""
import math

from deltafmi.component import Experiment, Input, Output, Parameter, SampledComponent
from deltafmi.physics.control.insertion import InsertionMpc as Planner, InsertionTask
from deltafmi.physics.control.model_file import LinearModelFile, find_model_file
from deltafmi.physics.assembly.program import hole_frame
from deltafmi.models.wrist_declarations import hole_parameters

__all__ = ["InsertionMpc"]


class InsertionMpc(hole_parameters("nominal", names=("hole_position", "hole_tilt", "hole_depth")),
                   SampledComponent):
    """Linear MPC of a peg-in-hole approach and insertion that drives the reference inputs (r, rd,
    rdd) of an AssemblyController (program = false), whose lateral and rotational compliance stays:
    the chamfer still centres the peg.

    Its model is the closed loop "impedance controller + robot" linearized by ``deltafmi
    linearize`` of a scenario with inputs r, rd, rdd of the controller and outputs tip,
    tip_velocity of the plant (``python -m deltafmi.apps.insertion_mpc_model SCENARIO -o NAME``
    writes it; NAME.npz, read at initialization from the working directory or the FMU's
    resources). Every sample_period it reads the tip and its velocity and chooses the reference
    acceleration for the sample (deltafmi/physics/control/insertion.py): the tip to goal_depth below the
    nominal hole top; the impedance's axial push if the tip were blocked, K_ax lead + D_ax lead
    rate, <= force_limit; the speed into the hole <= speed_limit, contact_speed in the contact zone
    around the nominal top, bore_speed deeper, bottom_speed near the bottom (hole_depth); |rdd| <=
    acceleration_limit. While the F/T sensor ft measures the peg pushed back along its axis by
    contact_force or more, the prediction holds the tip blocked along the hole.
    Between samples it outputs r + rd t + rdd t^2 / 2, rd + rdd t, rdd (the plan's first move) at
    the end of each communication step (Co-Simulation; use the controller's sample period as the
    step). Model Exchange samples at time events and holds r, rd, rdd of the sample instant until
    the next one (a staircase reference: prefer Co-Simulation).
    """

    model_name = "InsertionMpc"
    default_experiment = Experiment(start=0.0, stop=2.0, step=1e-3, tolerance=1e-6)

    linear_model = Parameter("peg_in_hole_mpc_model.npz", type=str,
                             description="The closed loop's .npz written by deltafmi linearize (inputs r, rd, "
                             "rdd; outputs tip, tip_velocity)")
    sample_period = Parameter(0.01, unit="s", min=0.0, description="MPC sample period (a multiple of the model's step)")
    horizon = Parameter(30, type=int, min=1, description="Prediction horizon (samples)")
    goal_depth = Parameter(0.035, unit="m", description="Depth below the nominal hole top the tip is sent to")
    start = Parameter([0.0, 0.0, -1.17], unit="m", description="The reference at the start (the tip's position)")
    axial_mass = Parameter(10.0, unit="kg", min=0.0, description="The impedance's apparent mass along the hole")
    axial_stiffness = Parameter(1500.0, unit="N/m", min=0.0, description="The impedance's stiffness along the hole")
    zeta = Parameter(1.0, min=0.0, description="The impedance's damping ratio: D_ax = 2 zeta sqrt(K_ax M_ax)")
    force_limit = Parameter(15.0, unit="N", min=0.0, description="Bound on the axial push K_ax lead + D_ax lead rate")
    speed_limit = Parameter(0.1, unit="m/s", min=0.0, description="Reference speed into the hole above the zone")
    contact_speed = Parameter(0.01, unit="m/s", min=0.0, description="Reference speed into the hole in the zone")
    bore_speed = Parameter(0.03, unit="m/s", min=0.0, description="Reference speed into the hole below the zone")
    bottom_speed = Parameter(0.003, unit="m/s", min=0.0,
                             description="Reference speed into the hole near the bottom (contact_zone[0] above it)")
    contact_force = Parameter(2.0, unit="N", min=0.0,
                              description="Measured push-back along the peg above which the tip is predicted blocked")
    contact_zone = Parameter([0.002, 0.003], unit="m",
                             description="Contact zone: from this far above the nominal top to this far below it")
    acceleration_limit = Parameter(2.0, unit="m/s2", min=0.0, description="Bound on each component of rdd")
    qp_tolerance = Parameter(1e-5, min=0.0,
                             description="The QP's tolerance: DAQP's primal feasibility, OSQP's absolute and relative")
    qp_iterations = Parameter(4000, type=int, min=1, description="The QP solver's iteration cap per sample")
    qp_polish = Parameter(True, type=bool,
                          description="OSQP: polish each QP's solution (the active set's exact solution: the same on "
                          "any machine)")
    qp_solver = Parameter("daqp", type=str,
                          description="daqp (dual active set: the active set's exact solution) or osqp (ADMM)")

    tip = Input([0.0, 0.0, -1.17], unit="m", description="Measured tool tip (world)")
    tip_velocity = Input([0.0] * 3, unit="m/s", description="Measured tool tip velocity (world)")
    ft = Input([0.0] * 6, unit="1",
               description="Force/torque sensor, tool frame (force on the peg, N; moment about the tip, N m)")

    r = Output(shape=3, unit="m", variability="discrete", description="Reference tool tip")
    rd = Output(shape=3, unit="m/s", variability="discrete", description="Reference tip velocity")
    rdd = Output(shape=3, unit="m/s2", variability="discrete", description="Reference tip acceleration")
    depth_ref = Output(unit="m", variability="discrete", description="The reference's depth below the nominal top")
    axial_force = Output(unit="N", variability="discrete",
                         description="The axial push K_ax lead + D_ax lead rate at the last sample")
    planned_force = Output(unit="N", variability="discrete",
                           description="The largest axial push the last plan predicts (what force_limit bounds)")
    time_qp = Parameter(False, type=bool,
                        description="Put the wall-clock time of each QP in solve_time (off: 0; a clock makes runs differ)")
    solve_time = Output(unit="s", variability="discrete", description="Wall-clock time of the last QP (time_qp)")
    iterations = Output(0, type=int, description="The QP solver's iterations of the last QP")
    status = Output(0, type=int, description="0 solved, 1 solved inaccurately or at the iteration limit")

    def setup(self) -> None:
        self._mpc = None
        self._ref = ([0.0] * 3, [0.0] * 3, [0.0] * 3)   # r, rd at the last sample, rdd held

    def initialize(self, t: float) -> None:
        self.start_sampling(t)
        frame = hole_frame((float(self.hole_tilt[0]), float(self.hole_tilt[1])))
        task = InsertionTask(
            hole_top=list(self.hole_position), hole_axis=[frame[2], frame[5], frame[8]], goal_depth=self.goal_depth,
            axial_stiffness=self.axial_stiffness,
            axial_damping=2.0 * self.zeta * math.sqrt(self.axial_stiffness * self.axial_mass),
            force_limit=self.force_limit, speed_limit=self.speed_limit, contact_speed=self.contact_speed,
            bore_speed=self.bore_speed, contact_zone=list(self.contact_zone),
            acceleration_limit=self.acceleration_limit, sample_period=self.sample_period, horizon=int(self.horizon),
            bottom_depth=self.hole_depth, bottom_speed=self.bottom_speed, contact_force=self.contact_force,
            tolerance=self.qp_tolerance, max_iterations=int(self.qp_iterations),
            polish=bool(self.qp_polish), solver=str(self.qp_solver))
        self._mpc = Planner(LinearModelFile.read(find_model_file(self.linear_model, self.resources_dir,
                                                                      "`python -m deltafmi.apps.insertion_mpc_model SCENARIO -o NAME`")), task)
        self._ref = ([float(c) for c in self.start], [0.0] * 3, [0.0] * 3)
        self._publish(0.0)

    def take_sample(self) -> None:
        r, rd, a = self._ref
        if self.sample_index > 0:  # the reference at this sample: the last sample's polynomial, a period on
            T = self.sample_period
            r = [r[i] + rd[i] * T + 0.5 * a[i] * T * T for i in range(3)]
            rd = [rd[i] + a[i] * T for i in range(3)]
        v = self.read_reals("tip", "tip_velocity", "ft")
        # the tool's z axis points into the hole (aligned to within the misalignment's cosine)
        rdd, plan = self._mpc.step(v[0:3], v[3:6], r, rd, push_back=-v[8])
        self._ref = (r, rd, [float(c) for c in rdd])
        self.write_reals([self._mpc.axial_force(plan.x[0]), self._mpc.planned_force(plan),
                          plan.solve_time if self.time_qp else 0.0], "axial_force", "planned_force", "solve_time")
        self.iterations = plan.iterations
        self.status = 0 if plan.status == "solved" else 1

    def _publish(self, tau: float) -> None:
        """Outputs tau seconds after the last sample."""
        r, rd, a = self._ref
        rt = [r[i] + rd[i] * tau + 0.5 * a[i] * tau * tau for i in range(3)]
        rdt = [rd[i] + a[i] * tau for i in range(3)]
        self.write_reals([*rt, *rdt, *a], "r", "rd", "rdd")
        self.depth_ref = float(self._mpc.depth(self._mpc.state(rt, rdt, rt, rdt))[0])

    def do_step(self, t: float, h: float) -> None:
        super().do_step(t, h)
        self._publish(t + h - (self.next_time_event(t) - self.sample_period))
