"""Peg contact estimator FMU: a thin sampled component over deltafmi.physics.estimation.peg_ekf."""
import numpy as np

from deltafmi.component import Clock, Experiment, Function, Input, NativeKernels, Output, Parameter, SampledComponent
from deltafmi.physics.delta.tactile import Readout
from deltafmi.physics.delta_wrist.params import WristMount
from deltafmi.physics.estimation.peg_ekf import PegEKF, PegEKFSettings
from deltafmi.physics.estimation.peg_kernels import FUNCTIONS
from deltafmi.physics.wrist.kernels import wrist_constants
from deltafmi.models.robot_parameters import robot_parameters
from deltafmi.models.wrist_declarations import hole_parameters, wrist_parameters
from deltafmi.models.wrist_parameters import peg_scene_of, wrist_params_of

__all__ = ["PegEstimator"]

#: the robot's parameters, as the estimator models them (they may differ from the plant's)
EstimatorRobotModel = robot_parameters("as the estimator models it")
#: the wrist, its peg and the hole as the estimator models them; the hole's pose is the prior's mean
EstimatorWristModel = wrist_parameters("as the estimator models it")
EstimatorHoleModel = hole_parameters("nominal", "as the estimator models it")

#: parameters handed to PegEKFSettings under the same names
_SETTINGS = ("sample_period", "y_std", "qw_std", "acceleration_std", "angular_acceleration_std", "force_rate_std",
             "moment_rate_std", "velocity_std0", "rate_std0", "force_std0", "moment_std0", "hole_std0", "tilt_std0",
             "contact_force_std", "contact_moment_std", "contact_threshold", "contact_samples", "reject_samples",
             "hole_drift_std", "tilt_drift_std", "law_hole_std", "law_tilt_std", "steady_force_rate_std",
             "steady_moment_rate_std", "force_acceleration_std", "moment_acceleration_std", "force_ramp_std",
             "moment_ramp_std", "manoeuvre_samples", "pole", "substeps", "contact_iterations", "jacobian_columns")


class PegEstimator(EstimatorHoleModel, EstimatorWristModel, EstimatorRobotModel, SampledComponent):
    """Extended Kalman filter of the peg's contact wrench and of the hole's position and tilt for the
    delta robot with its spherical wrist (DeltaWristPeg), sampled (1 kHz), from joint angles and
    motor torques only.

    Listens to the servo angles y, the wrist angles qw, the servo torques u and the wrist torques
    tau. Process model: the plant's DAE in its six coordinates (plate position, wrist angles) and
    rates, with the contact wrench on the peg (force at the tool tip and moment about it, world,
    the contact multipliers' resultant) as an integrated random walk (its rate a random walk: ramps
    followed) plus a random walk, slow between manoeuvres and fast in one
    (an impact, detected from the joint angles' innovations); the hole's x, y and tilt are a slow
    random walk tied to the wrench by the peg's contact law (the plant's, with the parameters below as the
    estimator models them) while the estimated force exceeds contact_threshold for
    contact_samples samples, in an iterated (Gauss-Newton) update of at most contact_iterations
    linearisations; a contact the law cannot place at the current hole estimate moves the estimate
    first along the felt lateral force (deltafmi/physics/estimation/peg_contact.py); the law's own
    error is a constant offset of the hole, considered (law_hole_std, law_tilt_std), so that the
    hole's reported uncertainty covers its error.
    hole_position and hole_tilt are the NOMINAL hole, the prior's mean. The filter starts at the
    first y and qw, at rest. sensor_noise adds seeded Gaussian noise to y and qw before the
    filter sees them. The first sample is one sample_period after the start. The process model
    and the contact law run as C compiled from their Python (the prediction, the law's
    linearisation, the hole locator: deltafmi/physics/estimation/peg_kernels.py), the covariance
    algebra in numpy; the cost per sample against the 1 ms of 1 kHz: benchmarks/assembly_realtime.py.
    Co-Simulation: doStep(t, h) takes the samples
    due in [t, t + h) with the inputs at t (use h = sample_period and list it after the plant and
    the controller in a Gauss-Seidel scenario, so that the angles and torques are of the same
    instant); Model Exchange: time events at the samples.
    """

    model_name = "PegEstimator"
    default_experiment = Experiment(start=0.0, stop=0.25, step=1e-3, tolerance=1e-6)
    #: the filter's process model and contact law, compiled; PegEKF calls them through native_functions
    native = NativeKernels(functions={name: Function(func, *types) for name, (func, types) in FUNCTIONS.items()})

    # the filter
    sample_period = Parameter(1e-3, unit="s", min=0.0, description="Estimator sample period")
    sample = Clock(period="sample_period", description="Sample instants: t_start + k * sample_period")
    y_std = Parameter(1e-6, unit="rad", min=0.0, description="Servo-angle noise (standard deviation)")
    qw_std = Parameter(1e-6, unit="rad", min=0.0, description="Wrist-angle noise (standard deviation)")
    acceleration_std = Parameter(2e-6, unit="m/s2", min=0.0,
                                 description="Model error as white plate-acceleration noise (per sqrt(Hz))")
    angular_acceleration_std = Parameter(1e-3, unit="rad/s2", min=0.0,
                                         description="Model error as white wrist-joint acceleration noise "
                                         "(per sqrt(Hz))")
    force_rate_std = Parameter(30.0, unit="N/s", min=0.0,
                               description="Random walk of the contact force in a manoeuvre (an impact; per "
                               "sqrt(Hz))")
    moment_rate_std = Parameter(2.0, unit="N.m/s", min=0.0,
                                description="Random walk of the contact moment in a manoeuvre (per sqrt(Hz))")
    steady_force_rate_std = Parameter(0.01, unit="N/s", min=0.0,
                                      description="Random walk of the contact force between manoeuvres (per "
                                      "sqrt(Hz); 0: force_rate_std always)")
    steady_moment_rate_std = Parameter(3e-4, unit="N.m/s", min=0.0,
                                       description="Random walk of the contact moment between manoeuvres (per "
                                       "sqrt(Hz); 0: moment_rate_std always)")
    force_acceleration_std = Parameter(0.7, unit="N/s2", min=0.0,
                                       description="Random walk of the contact force's rate (per sqrt(Hz)): the "
                                       "force an integrated random walk, its ramps followed")
    moment_acceleration_std = Parameter(0.02, unit="N.m/s2", min=0.0,
                                        description="Random walk of the contact moment's rate (per sqrt(Hz))")
    force_ramp_std = Parameter(5.0, unit="N/s", min=0.0,
                               description="The contact force's rate after a manoeuvre, about zero (a new contact's "
                               "ramp)")
    moment_ramp_std = Parameter(0.05, unit="N.m/s", min=0.0,
                                description="The contact moment's rate after a manoeuvre, about zero")
    manoeuvre_samples = Parameter(10, type=int, min=1,
                                  description="Samples of the joint angles' normalised innovations whose sum, above "
                                  "its chi-square 0.999 quantile, detects a manoeuvre")
    velocity_std0 = Parameter(0.01, unit="m/s", min=0.0, description="Initial plate velocity uncertainty (about rest)")
    rate_std0 = Parameter(0.01, unit="rad/s", min=0.0, description="Initial wrist rate uncertainty (about rest)")
    force_std0 = Parameter(1.0, unit="N", min=0.0, description="Initial contact force uncertainty (about zero)")
    moment_std0 = Parameter(0.05, unit="N.m", min=0.0, description="Initial contact moment uncertainty (about zero)")
    hole_std0 = Parameter(0.002, unit="m", min=0.0, description="Prior uncertainty of the hole's x and y")
    tilt_std0 = Parameter(0.02, unit="rad", min=0.0, description="Prior uncertainty of the hole's tilt")
    contact_force_std = Parameter(0.05, unit="N", min=0.0, description="Contact-law uncertainty, force")
    contact_moment_std = Parameter(0.005, unit="N.m", min=0.0, description="Contact-law uncertainty, moment")
    contact_threshold = Parameter(0.2, unit="N", min=0.0,
                                  description="Estimated contact force above which the peg is taken to touch")
    contact_samples = Parameter(5, type=int, min=1,
                                description="Samples in a row above contact_threshold before the contact law applies")
    hole_drift_std = Parameter(2e-3, unit="m", min=0.0,
                               description="Random walk of the hole's x, y (per sqrt(s); 0: constant): the filter "
                               "forgets old contacts, whose linearisation may have been wrong")
    tilt_drift_std = Parameter(2e-2, unit="rad", min=0.0,
                               description="Random walk of the hole's tilt (per sqrt(s); 0: constant)")
    law_hole_std = Parameter(3e-5, unit="m", min=0.0,
                             description="The contact law's error as a constant offset of the hole's x, y, considered "
                             "(not estimated): the least uncertainty the law leaves")
    law_tilt_std = Parameter(3e-3, unit="rad", min=0.0,
                             description="The contact law's error as a constant offset of the hole's tilt, considered")
    reject_samples = Parameter(50, type=int, min=1,
                               description="Contact-law updates refused in a row (the estimate locked in a wrong "
                               "hole) after which the hole's uncertainty goes back to its prior")
    contact_iterations = Parameter(5, type=int, min=1,
                                   description="Largest number of Gauss-Newton iterations of a contact-law update "
                                   "(1: the extended filter's single linearisation)")
    jacobian_columns = Parameter(3, type=int, min=1, max=18,
                                 description="Columns of the process Jacobian (of 18) evaluated again per sample, "
                                 "in turn (18: all of them every sample)")
    pole = Parameter(5.0, unit="1/s", min=0.0, description="Baumgarte pole of the process model")
    substeps = Parameter(1, type=int, min=1, description="Runge-Kutta steps per sample period in the prediction")
    sensor_noise = Parameter(0.0, unit="rad", min=0.0,
                             description="Seeded Gaussian noise added to y and qw before filtering (0: none)")
    seed = Parameter(1, type=int, min=0, description="Seed of sensor_noise")

    y = Input([0.0] * 3, unit="rad", description="Measured servo angles")
    qw = Input([0.0] * 3, unit="rad", description="Measured wrist joint angles")
    u = Input([0.0] * 3, unit="N.m", description="Servo torques (as commanded)")
    tau = Input([0.0] * 3, unit="N.m", description="Wrist torques (as commanded)")

    tip = Output(shape=3, unit="m", variability="discrete", description="Estimated tool tip position")
    force = Output(shape=3, unit="N", variability="discrete",
                   description="Estimated contact force on the peg (at the tool tip), world frame")
    moment = Output(shape=3, unit="N.m", variability="discrete",
                    description="Estimated contact moment about the tool tip, world frame")
    hole = Output(shape=2, unit="m", variability="discrete", description="Estimated hole top centre x, y")
    tilt = Output(shape=2, unit="rad", variability="discrete", description="Estimated hole tilt about x, then y")
    force_std = Output(shape=3, unit="N", variability="discrete", description="Standard deviation of force")
    moment_std = Output(shape=3, unit="N.m", variability="discrete", description="Standard deviation of moment")
    hole_std = Output(shape=2, unit="m", variability="discrete", description="Standard deviation of hole")
    tilt_std = Output(shape=2, unit="rad", variability="discrete", description="Standard deviation of tilt")
    in_contact = Output(0, type=int, description="1 while the contact law is applied, else 0")

    # the first sample one period after the start: at the start itself the event iteration of
    # exitInitializationMode samples before an importer has set the inputs (measured: u = 0
    # there in a master run, a 1.7 N ghost force for 20 ms)
    first_sample = 1

    def setup(self) -> None:
        self._ekf = None

    def initialize(self, t: float) -> None:
        self.start_sampling(t)
        self._settings = PegEKFSettings(**{name: getattr(self, name) for name in _SETTINGS})
        self._hole, self._peg, self._law = peg_scene_of(self)
        self._wrist = wrist_constants(wrist_params_of(self))
        self._mount = WristMount(*(float(c) for c in self.mount))
        self._readout = Readout(self.sensor_noise, 0.0, self.seed)
        self._ekf = None

    def take_sample(self) -> None:
        """One filter cycle with the inputs now; the filter starts at the first sample."""
        read = [self._readout.read(float(v), self.sample_index, i) for i, v in enumerate(np.r_[self.y, self.qw])]
        if self._ekf is None:
            self._ekf = PegEKF(self.robot_params(), self._wrist, self._mount, self._hole, self._peg, self._law,
                               self._settings, read[:3], read[3:], functions=self.native_functions)
        est = self._ekf.step(read[:3], read[3:], [float(v) for v in self.u], [float(v) for v in self.tau])
        self.write_reals((*est.tip, *est.force, *est.moment, *est.hole, *est.force_std, *est.moment_std,
                          *est.hole_std), "tip", "force", "moment", "hole", "tilt", "force_std", "moment_std",
                         "hole_std", "tilt_std")
        self.in_contact = int(est.in_contact)
