"""Contact estimator FMU: a thin sampled component over deltafmi.physics.estimation.contact_ekf."""
from deltafmi.component import Clock, Experiment, Function, Input, NativeKernels, Output, Parameter, SampledComponent
from deltafmi.physics.delta.dynamics import project_state
from deltafmi.physics.delta.params import DeltaParams
from deltafmi.physics.delta.tactile import Readout
from deltafmi.physics.estimation.contact_ekf import ContactEKF, ContactEKFSettings
from deltafmi.physics.estimation.delta_process_kernels import prediction_values, wrist_kinematics
from deltafmi.models.robot_parameters import robot_parameters

__all__ = ["ContactEstimator"]

#: the robot's parameters, as the estimator models them (they may differ from the plant's)
EstimatorRobotModel = robot_parameters("as the estimator models it")

#: parameters handed to ContactEKFSettings under the same names
_SETTINGS = ("sample_period", "y_std", "acceleration_std", "force_rate_std", "steady_force_rate_std", "friction",
             "manoeuvre_samples", "manoeuvre_hold", "force_acceleration_std", "force_ramp_std", "law_manoeuvre",
             "rest_force_rate_std", "rest_force_acceleration_std", "rest_samples", "rest_acceleration_std",
             "surface_drift_std",
             "position_std0", "velocity_std0", "force_std0", "surface_height0", "surface_std0", "tool",
             "contact_stiffness", "contact_damping", "contact_model_std", "contact_threshold", "contact_samples",
             "pole", "substeps")


class ContactEstimator(EstimatorRobotModel, SampledComponent):
    """Extended Kalman filter of the delta robot's contact force and surface height, sampled (1 kHz).

    Listens to the servo angles y and the servo torques u only. Its process model is the robot's
    stabilised DAE in the nine joint angles (exact Jacobians), augmented with the external wrist
    force (world frame, a random walk: for a tool on a plane it is n * lambda, the contact
    multiplier; with force_acceleration_std its rate a random walk too, an integrated random walk
    that follows a ramp without lag, restarted at force_ramp_std by a manoeuvre) and the surface height (a constant, tied to the force by the contact law
    lambda = k (-gap) + c (-gap') while the estimated normal force exceeds contact_threshold for
    contact_samples samples, and no manoeuvre is detected). The force walks at force_rate_std in
    every direction; with steady_force_rate_std it walks at that level along the surface normal
    (friction times it across) until the servo angles' normalised innovations over the last
    manoeuvre_samples exceed their chi-square 0.999 quantile (a manoeuvre: an impact; with
    law_manoeuvre also the contact law's, in contact: a ramp's end), and at force_rate_std while
    they do. With rest_force_rate_std, once the servo torques have held still for rest_samples
    (the force they balance moving by less than that walk would), the force and its rate walk at
    the rest levels and, with rest_acceleration_std, the wrist's acceleration is taken as zero (the
    force balances the torques). At each sample t_k it predicts from t_(k-1) with the torques read
    then (held over the period), then updates with y(t_k); the outputs are this estimate at t_k
    and its standard deviations. The filter starts at the forward kinematics of the first y, at
    rest. sensor_noise adds seeded Gaussian noise to y before the filter sees it (a noisier
    sensor, for studies). The process model's kernels (the Runge-Kutta period with the exact
    Jacobian, the projection onto the loops, the wrist kinematics) run as C generated from their
    Python (``native``; the Python functions without a C compiler, the same numbers), the
    covariance algebra in numpy. Co-Simulation:
    doStep(t, h) takes the samples due in [t, t + h) with the inputs at t (use h = sample_period;
    in a Gauss-Seidel scenario list it after the plant and the controller, so that y and u are
    of the same instant); Model Exchange: time events at the samples.
    """

    model_name = "ContactEstimator"
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3, tolerance=1e-6)

    sample_period = Parameter(1e-3, unit="s", min=0.0, description="Estimator sample period")
    sample = Clock(period="sample_period", description="Sample instants: t_start + k * sample_period")
    y_std = Parameter(1e-5, unit="rad", min=0.0, description="Servo-angle measurement noise (standard deviation)")
    acceleration_std = Parameter(0.05, unit="m/s2", min=0.0,
                                 description="Model error as white wrist-acceleration noise (per sqrt(Hz))")
    force_rate_std = Parameter(100.0, unit="N/s", min=0.0,
                               description="Random walk of the wrist force in a manoeuvre, e.g. an impact (per sqrt(Hz))")
    steady_force_rate_std = Parameter(0.0, unit="N/s", min=0.0,
                                      description="Its walk along the surface normal between manoeuvres (per sqrt(Hz); "
                                                  "0: force_rate_std throughout, no manoeuvre detector)")
    friction = Parameter(0.0, min=0.0, description="Friction coefficient: the steady walk across the normal is "
                                                   "friction times the one along it")
    manoeuvre_samples = Parameter(10, type=int, min=1,
                                  description="Samples of the servo innovations summed to detect a manoeuvre")
    manoeuvre_hold = Parameter(0, type=int, min=0, description="Samples a detected manoeuvre lasts at least")
    force_acceleration_std = Parameter(0.0, unit="N/s2", min=0.0,
                                       description="Random walk of the force's rate, its ramps (per sqrt(Hz); "
                                                   "0: the force a random walk alone)")
    force_ramp_std = Parameter(0.0, unit="N/s", min=0.0,
                               description="The force's rate after a manoeuvre (about zero): a new contact's ramp")
    law_manoeuvre = Parameter(False, description="The manoeuvre detector also watches the contact law's innovations "
                                                 "(a ramp's end, seen in contact)")
    rest_force_rate_std = Parameter(0.0, unit="N/s", min=0.0,
                                    description="Walk of the force at rest, the torques still (per sqrt(Hz); "
                                                "0: no rest level)")
    rest_force_acceleration_std = Parameter(0.0, unit="N/s2", min=0.0,
                                            description="Walk of the force's rate at rest (per sqrt(Hz))")
    rest_samples = Parameter(100, type=int, min=1,
                             description="Samples the torques stay still (the force they balance within the rest "
                                         "walk's 0.999 quantile) before the rest level applies")
    rest_acceleration_std = Parameter(0.0, unit="m/s2", min=0.0,
                                      description="The wrist's acceleration at rest: a pseudo-measurement of zero "
                                                  "(0: none)")
    surface_drift_std = Parameter(0.0, unit="m", min=0.0, description="Random walk of the surface height (per sqrt(s))")
    position_std0 = Parameter(1e-3, unit="m", min=0.0, description="Initial wrist position uncertainty")
    velocity_std0 = Parameter(0.01, unit="m/s", min=0.0, description="Initial wrist velocity uncertainty (about rest)")
    force_std0 = Parameter(10.0, unit="N", min=0.0, description="Initial wrist force uncertainty (about zero)")
    surface_height0 = Parameter(-1.1, unit="m", description="Prior surface height (where it crosses the robot axis)")
    surface_std0 = Parameter(0.05, unit="m", min=0.0, description="Prior surface height uncertainty")
    surface_normal = Parameter([0.0, 0.0, 1.0], description="Surface normal, towards the robot (known)")
    tool = Parameter([0.0, 0.0, -0.1], unit="m", description="Tool tip relative to the plate centre (known)")
    contact_stiffness = Parameter(2e5, unit="N/m", min=0.0, description="Contact spring, as the estimator models it")
    contact_damping = Parameter(2e3, unit="N.s/m", min=0.0, description="Contact damper, as the estimator models it")
    contact_model_std = Parameter(5.0, unit="N", min=0.0,
                                  description="Uncertainty of the contact law lambda = k (-gap) + c (-gap')")
    contact_threshold = Parameter(10.0, unit="N", min=0.0,
                                  description="Estimated normal force above which the tool is taken to press")
    contact_samples = Parameter(10, type=int, min=1,
                                description="Samples in a row above contact_threshold before the contact law applies")
    pole = Parameter(5.0, unit="1/s", min=0.0, description="Baumgarte pole of the process model")
    substeps = Parameter(1, type=int, min=1, description="Runge-Kutta steps per sample period in the prediction")
    sensor_noise = Parameter(0.0, unit="rad", min=0.0,
                             description="Seeded Gaussian noise added to y before filtering (0: none)")
    seed = Parameter(1, type=int, min=0, description="Seed of sensor_noise")

    y = Input([0.0] * 3, unit="rad", description="Measured servo angles")
    u = Input([0.0] * 3, unit="N.m", description="Servo torques (as commanded)")

    z = Output(shape=3, unit="m", variability="discrete", description="Estimated wrist (plate centre) position")
    zd = Output(shape=3, unit="m/s", variability="discrete", description="Estimated wrist velocity")
    force = Output(shape=3, unit="N", variability="discrete",
                   description="Estimated external (contact) force on the wrist, world frame")
    fn = Output(unit="N", variability="discrete", description="Estimated normal contact force (the multiplier)")
    surface_height = Output(unit="m", variability="discrete", description="Estimated surface height")
    gap = Output(unit="m", variability="discrete", description="Estimated gap of the tool tip from the surface")
    z_std = Output(shape=3, unit="m", variability="discrete", description="Standard deviation of z")
    zd_std = Output(shape=3, unit="m/s", variability="discrete", description="Standard deviation of zd")
    force_std = Output(shape=3, unit="N", variability="discrete", description="Standard deviation of force")
    fn_std = Output(unit="N", variability="discrete", description="Standard deviation of fn")
    surface_std = Output(unit="m", variability="discrete", description="Standard deviation of surface_height")
    in_contact = Output(0, type=int, description="1 while the contact law is applied, else 0")

    first_sample = 1  # the start instant's event iteration may run before the importer has set u

    #: the filter's process-model kernels, compiled (ContactEKF's ``kernels``: ProcessKernels)
    native = NativeKernels(functions={
        "predict": Function(prediction_values, DeltaParams, 9, 9, 3, 3, float, float, int),
        "project": Function(project_state, DeltaParams, 9, 9),
        "kinematics": Function(wrist_kinematics, DeltaParams, 9, 9)})

    def setup(self) -> None:
        self._ekf = None

    def initialize(self, t: float) -> None:
        self.start_sampling(t)
        self._settings = ContactEKFSettings(**{name: _plain(getattr(self, name)) for name in _SETTINGS},
                                            normal=tuple(self.surface_normal))
        self._readout = Readout(self.sensor_noise, 0.0, self.seed)
        self._ekf = None

    def take_sample(self) -> None:
        """One filter cycle with the inputs now; the filter starts at the first sample."""
        y = [self._readout.read(float(value), self.sample_index, i) for i, value in enumerate(self.y)]
        if self._ekf is None:
            self._ekf = ContactEKF(self.robot_params(), self._settings, y, kernels=self.native_functions)
        est = self._ekf.step(y, [float(value) for value in self.u])
        self.write_reals((*est.z, *est.zd, *est.force, est.fn, est.surface_height, self._ekf.gap(), *est.z_std,
                          *est.zd_std, *est.force_std, est.fn_std, est.surface_std),
                         "z", "zd", "force", "fn", "surface_height", "gap", "z_std", "zd_std", "force_std", "fn_std",
                         "surface_std")
        self.in_contact = int(est.in_contact)


def _plain(value):
    """A parameter's value as ContactEKFSettings takes it (arrays as tuples)."""
    return tuple(float(v) for v in value) if hasattr(value, "__len__") else value
