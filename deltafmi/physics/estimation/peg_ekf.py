"""An extended Kalman filter of the peg's contact wrench and of the hole's position and tilt, for the
delta robot with its spherical wrist (DeltaWristPeg), from joint angles and motor torques only.

Measured: the servo angles y (3, noise y_std) and the wrist angles qw (3, noise qw_std); known
inputs: the servo torques u and the wrist torques tau, held over each sample period. Estimated,
28 states X = [s (12), W (6), h (4), V (6)]:

- s = [z, qw, zd, vw]: the plant's six independent coordinates and their rates, process model
  the plant's DAE (:mod:`.wrist_process`), with white acceleration noise for the model's errors
  (acceleration_std on the plate, angular_acceleration_std on the wrist joints);
- W = [F, M]: the contact wrench on the peg, force at the tool tip and moment about it, world
  frame (the resultant of the contact multipliers; the plant's contact_force, contact_moment),
  and V = W' its rate: a sliding contact's wrench follows ramps (the controller pushing, the
  peg moving along the chamfer or the bore), so W is an integrated random walk (W' = V, V' white,
  force_acceleration_std, moment_acceleration_std: a ramp is followed without lag) plus a random
  walk (W' also white) at two levels (Bar-Shalom, Li, Kirubarajan 2001, section 11.2: adjustable
  process noise): steady_force_rate_std, steady_moment_rate_std while the joint angles'
  innovations are consistent, and force_rate_std, moment_rate_std in a manoeuvre (an impact):
  detected when the sum of the last manoeuvre_samples normalised innovations r^T S^-1 r exceeds
  its chi-square 0.999 quantile, the wrench's covariance then first given what the fast walk
  would have added over that window, and its rate starting over (zero, force_ramp_std,
  moment_ramp_std, uncorrelated: the new contact's ramp is not the last one's). The levels are
  what the plant's force does (benchmarks/estimator_consistency.py prints them, docs/assembly.md):
  over tens of milliseconds in the bore its rate wanders as an integrated walk of ~0.7 N/s^2 per
  sqrt(Hz), over one sample it moves as a walk of ~0.01 N/s per sqrt(Hz), and sliding down the
  chamfer its ramps reach ~5 N/s. With a plain random walk wide enough for the chamfer the
  filter was under-confident in the bore (force NEES 0.5 of its 3), and one at the bore's level
  lagged the ramp there (NEES rising to tens as the ramp steepened);
- h = [x, y, tilt_x, tilt_y]: the hole (:mod:`.peg_contact`), with a prior (the nominal hole,
  hole_std0, tilt_std0) and a slow random walk (hole_drift_std, tilt_drift_std): the hole does
  not move, but the law's updates are linearised at the estimate, and a walk makes the filter
  forget the old ones (fading memory) instead of trusting each of thousands forever, so that an
  estimate the first chamfer contacts put in the wrong place can leave it;
- b (4, not in the state: a Schmidt "consider" parameter, never estimated): the contact law's
  error as a constant offset of the hole, the law seeing h + b (law_hole_std, law_tilt_std). The
  law's errors (the wrench's estimate, the pose's, the linearisation over its switching contact
  points) are correlated over the whole contact, not white: updates with white noise alone would
  each be taken as new information, and the hole's covariance would shrink without bound while
  its error does not. The considered offset keeps what all the updates together can tell at the
  offset's level: the filter carries b's covariance and its cross-covariance with the state, so
  that the Joseph form stays the exact covariance of its suboptimal gain (Simon 2006, section 7.4).

The hole is tied in by the contact law as a pseudo-measurement, as :mod:`.contact_ekf` ties the
surface height, applied while the filter believes the peg touches (|F| > contact_threshold for
contact_samples samples in a row):

    0 = W - c(h, s)   (6 rows, noise contact_force_std, contact_moment_std: the law's errors).

This update corrects h only (a Schmidt-Kalman "consider" update, :func:`.kalman.joseph_update`):
W and s enter its innovation covariance but keep the values the dynamics gave them. Why: the
wrench is to come from the joint angles and torques, and a contact law evaluated at a hole
still wrong (its tilt unknown at first) would otherwise bend it (measured: 3 N of error in the
bore when the law corrected W too, 0.003 N when it does not).

The update is iterated (an iterated extended Kalman filter: Gauss-Newton on the update's
least-squares problem; Bell and Cathey, IEEE Trans. Automatic Control 38(2), 1993): the law is
linearised at the current iterate h_i, h_(i+1) = h_prior + K_i (c(h_i) - W - H_i (h_prior - h_i)),
until an iteration moves h by less than contact_tolerance prior standard deviations or after
contact_iterations; the covariance takes the last linearisation (Joseph form). The stiff law
(2e5 N/m a point) is linear over micrometres only: a single linearisation at a hole estimate
tens of micrometres off predicts the wrong contacts, and its update is confident about them.
Each iteration re-evaluates the law and its hole columns (5 evaluations); the columns of s stay
the first linearisation's (they enter only the innovation covariance, through s's micrometres).

The law is applied only while it is consistent with the estimate: the normalised innovation
r^T S^-1 r of its last iteration (chi-square with 6 degrees of freedom for a right model) at
most contact_gate (22.46: the 0.999 quantile). It is not at an impact, where the wrench's random
walk lags the truth by newtons, and the hole would be moved to explain a wrench the peg does not
feel.
Where c(h, s) has no contact while the robot feels one and h is still about as uncertain as its
prior (standard deviation above half of hole_std0), the estimate of h is first moved to where the
law explains the felt wrench (:func:`.peg_contact.locate_hole`); the updates then refine it.
A contact constrains h along its normals only: in a bore with clearance, the hole's position
across the contact normal stays at what the chamfer told (its standard deviation says so).

Consistency (tests/models/test_peg_estimator_consistency.py, benchmarks/estimator_consistency.py:
Monte Carlo over seeded encoder noise on the real plant; docs/assembly.md has the figures): with
the wrench's integrated walk and its two levels, the considered law offset and the hole's walk,
the mean NEES of the hole (4 dof) and of the force sliding on the chamfer and in the bore lie
within their chi-square intervals; with the wrench at its fast level throughout and no law error
(the previous defaults) the hole's NEES was 1e4-1e5 and the force's 0.1. A lock-in shows as the
gate refusing the law reject_samples times in a row while in contact; the hole's covariance then
goes back to its prior's about the current mean (its correlations dropped), and the law's updates
start over from it (Bar-Shalom, Li, Kirubarajan 2001, ch. 11: a filter that detects its
innovations are inconsistent raises its uncertainty instead of refusing the data).

Cycle per sample t_k (:meth:`PegEKF.step`), as ContactEKF: predict from t_(k-1) with the torques
held since then, update with y(t_k), qw(t_k), then the gated contact update. The prediction's
transition matrix needs the process Jacobian (18 columns, each an evaluation of the plant's
accelerations): jacobian_columns of them are evaluated again per sample, in turn, the others kept
from the samples before (a Jacobian a few milliseconds old, as a stiff solver reuses its Newton
matrix; it enters only the covariance's propagation, the mean is the Runge-Kutta step's). The
process model, the servo kinematics and the contact law are the float kernels of
:mod:`.peg_kernels`, called through ``functions`` (compiled in the PegEstimator FMU, Python
otherwise: the same numbers); the covariance algebra is numpy. Cost per sample, either way:
benchmarks/assembly_realtime.py.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any, Callable, NamedTuple, Sequence

import numpy as np

from ..delta.kinematics import forward_kinematics
from ..delta.params import DeltaParams
from ..delta_wrist.params import WristMount
from ..peg.params import Hole, Peg, PegContact
from ..wrist.kernels import WristConstants
from .kalman import MANOEUVRE_Z, chi_square_quantile, white_acceleration_noise
from .peg_contact import HOLE_STATES, linearization_parts, located
from .peg_kernels import FUNCTIONS, JACOBIAN_COLUMNS
from .wrist_process import N_REDUCED, tool_pose

__all__ = ["PegEKFSettings", "PegEstimate", "PegEKF", "N_STATES", "PYTHON_FUNCTIONS"]

# the wrench's rate V last, so that the hole keeps its place (18:22) among the states
_S, _W, _H, _V = slice(0, 12), slice(12, 18), slice(18, 22), slice(22, 28)
#: the states the prediction's transition involves: s, W and W's rate V (the hole walks alone)
_Z = np.r_[0:18, 22:28]
N_STATES = N_REDUCED + 6 + HOLE_STATES + 6
#: terms of exp(A T)'s Taylor series in the prediction (:func:`.kalman.transition_matrix`'s default)
TAYLOR_ORDER = 4


def _flat(func: Callable) -> Callable:
    def call(*args: Any) -> np.ndarray:
        return np.array(func(*args), dtype=float)
    call.__name__ = func.__name__
    return call


#: the filter's kernels (:mod:`.peg_kernels`) as Python, each result a flat float array, as a
#: component's compiled functions give it (``native_functions``)
PYTHON_FUNCTIONS = SimpleNamespace(**{name: _flat(func) for name, (func, _) in FUNCTIONS.items()})


@dataclass(frozen=True)
class PegEKFSettings:
    """Noise levels, priors and the contact gate of :class:`PegEKF` (SI units)."""

    sample_period: float = 1e-3  #: s
    y_std: float = 1e-6  #: servo-angle noise (rad)
    qw_std: float = 1e-6  #: wrist-angle noise (rad)
    acceleration_std: float = 2e-6  #: white plate-acceleration noise (m/s^2/sqrt(Hz))
    angular_acceleration_std: float = 1e-3  #: white wrist-joint acceleration noise (rad/s^2/sqrt(Hz))
    force_rate_std: float = 30.0  #: random walk of the contact force in a manoeuvre (N/s/sqrt(Hz))
    moment_rate_std: float = 2.0  #: random walk of the contact moment in a manoeuvre (N m/s/sqrt(Hz))
    position_std0: float = 1e-5  #: initial plate position (m) about forward kinematics of y0
    angle_std0: float = 1e-5  #: initial wrist angles (rad) about qw0
    velocity_std0: float = 0.01  #: initial plate velocity (m/s) about rest
    rate_std0: float = 0.01  #: initial wrist rates (rad/s) about rest
    force_std0: float = 1.0  #: initial contact force (N) about zero
    moment_std0: float = 0.05  #: initial contact moment (N m) about zero
    hole_std0: float = 0.002  #: prior hole position x, y (m) about the nominal hole
    tilt_std0: float = 0.02  #: prior hole tilt (rad) about the nominal tilt
    contact_force_std: float = 0.05  #: contact-law pseudo-measurement noise, force (N)
    contact_moment_std: float = 0.005  #: contact-law pseudo-measurement noise, moment (N m)
    contact_threshold: float = 0.2  #: estimated contact force above which the peg touches (N)
    contact_samples: int = 5  #: samples in a row above contact_threshold before the law applies
    contact_gate: float = 22.46  #: largest normalised innovation r^T S^-1 r of an applied contact update
    contact_iterations: int = 10  #: largest number of Gauss-Newton iterations of a contact-law update (1: EKF)
    contact_tolerance: float = 1e-3  #: an iteration's largest hole change, in prior standard deviations, that ends them
    reject_samples: int = 50  #: contact updates refused in a row after which the hole's covariance reopens
    hole_drift_std: float = 2e-3  #: random walk of the hole's x, y (m/sqrt(s)): forgets old contacts
    tilt_drift_std: float = 2e-2  #: random walk of the hole's tilt (rad/sqrt(s))
    law_hole_std: float = 3e-5  #: the contact law's error as a constant offset of the hole's x, y (m), considered
    law_tilt_std: float = 3e-3  #: the contact law's error as a constant offset of the hole's tilt (rad), considered
    steady_force_rate_std: float = 0.01  #: the force's random walk while no manoeuvre is detected (0: force_rate_std)
    steady_moment_rate_std: float = 3e-4  #: the moment's walk while no manoeuvre is detected (0: moment_rate_std)
    manoeuvre_samples: int = 10  #: samples of the angles' normalised innovations summed to detect a manoeuvre
    force_acceleration_std: float = 0.7  #: white noise on the contact force's rate (N/s^2/sqrt(Hz)): its ramps
    moment_acceleration_std: float = 0.02  #: white noise on the contact moment's rate (N m/s^2/sqrt(Hz))
    force_ramp_std: float = 5.0  #: the force's rate (N/s) after a manoeuvre, about zero: a new contact's ramp (0: kept)
    moment_ramp_std: float = 0.05  #: the moment's rate (N m/s) after a manoeuvre, about zero (0 both: kept)
    pole: float = 5.0  #: Baumgarte pole of the process model (1/s)
    substeps: int = 1  #: Runge-Kutta steps per sample period
    jacobian_columns: int = 3  #: process-Jacobian columns (of 18) evaluated again per sample, in turn

    def __post_init__(self) -> None:
        for name in ("sample_period", "y_std", "qw_std", "position_std0", "angle_std0", "velocity_std0", "rate_std0",
                     "force_std0", "moment_std0", "hole_std0", "tilt_std0", "contact_force_std",
                     "contact_moment_std"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"estimator setting {name} must be > 0, got {getattr(self, name)}")
        for name in ("acceleration_std", "angular_acceleration_std", "force_rate_std", "moment_rate_std",
                     "hole_drift_std", "tilt_drift_std", "law_hole_std", "law_tilt_std", "steady_force_rate_std",
                     "steady_moment_rate_std", "force_acceleration_std", "moment_acceleration_std", "force_ramp_std",
                     "moment_ramp_std", "contact_threshold", "contact_gate", "pole",
                     "contact_tolerance"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"estimator setting {name} must be >= 0, got {getattr(self, name)}")
        for name in ("substeps", "contact_samples", "reject_samples", "contact_iterations", "jacobian_columns",
                     "manoeuvre_samples"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"estimator setting {name} must be >= 1, got {getattr(self, name)}")
        if int(self.jacobian_columns) > 18:
            raise ValueError(f"estimator setting jacobian_columns must be <= 18, got {self.jacobian_columns}")


class PegEstimate(NamedTuple):
    """The filter's estimate with one standard deviation per quantity (SI units, world frame)."""

    tip: np.ndarray  #: tool tip position (3,)
    force: np.ndarray  #: contact force on the peg at the tip (3,)
    moment: np.ndarray  #: contact moment about the tip (3,)
    hole: np.ndarray  #: hole x, y (m), tilt_x, tilt_y (rad)
    force_std: np.ndarray
    moment_std: np.ndarray
    hole_std: np.ndarray
    in_contact: bool  #: the contact-law pseudo-measurement was applied at the last update


class PegEKF:
    """Extended Kalman filter of the peg's contact wrench and the hole (module docstring).

    Args:
        p, w, m: the robot, wrist and mount as the estimator models them.
        hole: the nominal hole (position and tilt: the prior's mean; the rest: the geometry).
        peg, law: the peg and the contact law as the estimator models them.
        settings: noise levels, priors, contact gate.
        y0, qw0: the first servo and wrist angles (rad); the filter starts there, at rest.
        functions: the kernels of :mod:`.peg_kernels` by name (prediction, contact_linearization,
            hole_search, servo_kinematics), each returning its result as a flat float array: a component's
            compiled ``native_functions``; default :data:`PYTHON_FUNCTIONS` (the same numbers).
    """

    def __init__(self, p: DeltaParams, w: WristConstants, m: WristMount, hole: Hole, peg: Peg, law: PegContact,
                 settings: PegEKFSettings, y0: Sequence[float], qw0: Sequence[float],
                 functions: Any = None) -> None:
        self.p, self.w, self.m, self.hole, self.peg, self.law, self.settings = p, w, m, hole, peg, law, settings
        self.functions = PYTHON_FUNCTIONS if functions is None else functions
        st = settings
        self.x = np.zeros(N_STATES)
        self.x[0:3], self.x[3:6] = forward_kinematics(p, y0), np.asarray(qw0, float)
        self.x[_H] = hole.x, hole.y, hole.tilt_x, hole.tilt_y
        std = ([st.position_std0] * 3 + [st.angle_std0] * 3 + [st.velocity_std0] * 3 + [st.rate_std0] * 3
               + [st.force_std0] * 3 + [st.moment_std0] * 3 + [st.hole_std0] * 2 + [st.tilt_std0] * 2 + [0.0] * 6)
        self.P = np.diag(np.square(std))
        self.in_contact = False
        self.consistency = 0.0  #: r^T S^-1 r of the last contact update (module docstring)
        self._touching = 0  # samples in a row with |F| above contact_threshold
        self._rejected = 0  # contact updates in a row the gate refused
        self.reopened = 0  #: times the hole's covariance went back to its prior (_reopen_hole)
        self._inputs: tuple[list, list] | None = None  # torques held since the last sample
        self._A: np.ndarray | None = None  # the process Jacobian d s'/d[s, W] (12, 18) as last evaluated
        self._column = 0  # the next of its columns to evaluate again
        self._R = np.diag([st.y_std ** 2] * 3 + [st.qw_std ** 2] * 3)
        self._F0 = np.eye(N_REDUCED, 18)  # the identity's rows of s in the transition matrix
        self._H_angles = np.eye(6)  # the angles' rows over [z, qw]: z's block set per sample
        self._G_contact = np.hstack([np.zeros((6, N_REDUCED)), np.eye(6)])  # the law's rows over [s, W]
        # the law's offset b (consider states, never estimated): its covariance and cross-covariance
        self._Pbb = np.diag([st.law_hole_std ** 2] * 2 + [st.law_tilt_std ** 2] * 2)
        self._Pxb = np.zeros((N_STATES, HOLE_STATES))
        self._Rc = np.diag([st.contact_force_std ** 2] * 3 + [st.contact_moment_std ** 2] * 3)
        T = st.sample_period
        W = white_acceleration_noise(T)
        Q = np.zeros((N_STATES, N_STATES))
        for i, a in enumerate([st.acceleration_std] * 3 + [st.angular_acceleration_std] * 3):
            Q[np.ix_([i, i + 6], [i, i + 6])] = a * a * W
        Q[_H, _H] = np.diag([st.hole_drift_std ** 2] * 2 + [st.tilt_drift_std ** 2] * 2) * T
        # the wrench's rate V: an integrated random walk of the wrench (W' = V, V' = white noise)
        for i, a in enumerate([st.force_acceleration_std] * 3 + [st.moment_acceleration_std] * 3):
            Q[np.ix_([12 + i, 22 + i], [12 + i, 22 + i])] = a * a * W
        walk = Q.copy()
        Q[_W, _W] += np.diag([st.force_rate_std ** 2] * 3 + [st.moment_rate_std ** 2] * 3) * T
        self._Q = Q
        # the wrench's random walk between manoeuvres (the steady levels), and the detector's state
        steady = ([st.steady_force_rate_std or st.force_rate_std] * 3
                  + [st.steady_moment_rate_std or st.moment_rate_std] * 3)
        self._Q_steady = walk
        self._Q_steady[_W, _W] += np.diag(np.square(steady)) * T
        self._ramp = np.diag([st.force_ramp_std ** 2] * 3 + [st.moment_ramp_std ** 2] * 3)
        self._Phi = np.zeros((18, 24))  # the transition's rows of [s, W] over [s, W, V]
        self._Phi[12:18, 12:18] = np.eye(6)
        self._Phi[12:18, 18:24] = T * np.eye(6)
        self._nis: list[float] = []  # the joint angles' last normalised innovations r^T S^-1 r
        self._nis_gate = chi_square_quantile(6 * st.manoeuvre_samples, MANOEUVRE_Z)
        self.manoeuvre = False  #: a manoeuvre (an impact: the wrench changing fast) is detected
        self.manoeuvres = 0  #: manoeuvres detected so far

    # --------------------------------------------------------------------------------- cycle
    def step(self, y: Sequence[float], qw: Sequence[float], u: Sequence[float], tau: Sequence[float]) -> PegEstimate:
        """One sample t_k: predict with the torques held since t_(k-1) (none at the first sample),
        update with y and qw (rad) at t_k; u and tau (N m) are held from now on."""
        if self._inputs is not None:
            self.predict(*self._inputs)
        self.update(y, qw)
        self._inputs = ([float(v) for v in u], [float(v) for v in tau])
        return self.estimate()

    def predict(self, u: Sequence[float], tau: Sequence[float]) -> None:
        """Propagate the state over one sample period with u and tau held, the covariance with it."""
        st = self.settings
        if self._A is None:  # all columns the first time
            first, count = 0, JACOBIAN_COLUMNS
            self._A = np.zeros((N_REDUCED, 18))
            self._A[0:6, 6:12] = np.eye(6)
        else:  # the next jacobian_columns columns, in turn (the rest as last evaluated)
            first, count = self._column, int(st.jacobian_columns)
            self._column = (first + count) % 18
        # the Runge-Kutta step and the columns due, from one call (:func:`.peg_kernels.prediction`)
        values = self.functions.prediction(self.p, self.w, self.m, self.x[_S].tolist(), u, tau, self.x[_W].tolist(),
                                           float(st.pole), float(st.sample_period), int(st.substeps), first, count)
        due = [(first + i) % 18 for i in range(count)]
        self._A[6:12, due] = np.reshape(values[12:], (18, 6)).T[:, due]
        # Phi = exp(A T) (:func:`.kalman.transition_matrix`'s series) over z = [s, W, V] (W' = V; the
        # hole walks alone) is the identity but for the rows of s and W: those rows as the series of
        # A's nonzero rows (s's: F over [s, W], F_V over V, from A's W columns times V's T / k;
        # W's: [0, I, T I]), and Phi P Phi^T by them
        T = st.sample_period
        AT = self._A * T
        term = AT
        F = self._F0 + AT
        FV = np.zeros((N_REDUCED, 6))
        for k in range(2, TAYLOR_ORDER + 1):
            FV += term[:, N_REDUCED:] * (T / k)
            term = term[:, :N_REDUCED] @ AT / k
            F += term
        Phi = self._Phi
        Phi[:12, :18], Phi[:12, 18:] = F, FV
        self.x[_S] = values[:12]
        self.x[_W] += T * self.x[_V]
        P, Pxb = self.P, self._Pxb
        FP = Phi @ P[_Z]  # (18, 28)
        FPF = FP[:, _Z] @ Phi.T
        P[:18, :18] = 0.5 * (FPF + FPF.T)
        P[:18, 18:] = FP[:, 18:]
        P[18:, :18] = FP[:, 18:].T
        P += self._Q if self.manoeuvre else self._Q_steady
        Pxb[:18] = Phi @ Pxb[_Z]

    def update(self, y: Sequence[float], qw: Sequence[float]) -> None:
        """Measurement update with the joint angles, then the gated contact-law update."""
        servo = self.functions.servo_kinematics(self.p, self.x[0:3].tolist())  # angles, rows of dq/dz
        H = self._H_angles  # dh/d[z, qw]: the angles' rows touch those six states only
        H[0:3, 0:3] = servo[3:12].reshape(3, 3)
        residual = np.concatenate([np.asarray(y, float) - servo[0:3], np.asarray(qw, float) - self.x[3:6]])
        st = self.settings
        S = H @ (self.P[:6, :6] @ H.T) + self._R
        Sinv = np.linalg.inv(S)
        self._detect_manoeuvre(float(residual @ Sinv @ residual))  # changes the wrench's rows, not P[:6, :6]
        PHt = self.P[:, :6] @ H.T
        self._correct_angles(H, PHt, S, PHt @ Sinv, residual)
        force = self.x[12:15]
        touching = math.sqrt(force @ force) > st.contact_threshold
        self._touching = self._touching + 1 if touching else 0
        self.in_contact = self._touching >= self.settings.contact_samples
        if self.in_contact:
            self._contact_update()
        else:
            self._rejected = 0

    # ------------------------------------------------------------------------------ outputs
    def estimate(self) -> PegEstimate:
        """The current estimate and its standard deviations."""
        std = np.sqrt(np.maximum(np.diag(self.P), 0.0))
        tip = np.array(tool_pose(self.w, self.m, self.x[_S])[0])
        return PegEstimate(tip, self.x[12:15].copy(), self.x[15:18].copy(), self.x[_H].copy(), std[12:15],
                           std[15:18], std[_H], self.in_contact)

    # ------------------------------------------------------------------------------ helpers
    def _wrench_jacobian(self, h: np.ndarray, hole_only: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
        """:func:`.peg_contact.wrench_jacobian` at the state's s and the hole h, by the filter's kernel."""
        return linearization_parts(self.functions.contact_linearization(
            self.hole, self.peg, self.law, self.w, self.m, self.x[_S].tolist(), np.asarray(h, float).tolist(),
            hole_only))

    def _hole_linearization(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(c (6), dc/dh (6, 4)) at the state's s and the hole h: :meth:`_wrench_jacobian`'s
        hole_only values, views of the kernel's flat result (module :mod:`.peg_kernels`' layout)."""
        values = np.asarray(self.functions.contact_linearization(
            self.hole, self.peg, self.law, self.w, self.m, self.x[_S].tolist(), h.tolist(), True), float)
        first = 6 + 6 * N_REDUCED
        return values[:6], values[first:first + 6 * HOLE_STATES].reshape(HOLE_STATES, 6).T

    def _locate_hole(self, weights: np.ndarray) -> np.ndarray | None:
        """:func:`.peg_contact.locate_hole` at the state's s, hole and wrench, by the filter's kernel."""
        return located(self.functions.hole_search(self.hole, self.peg, self.law, self.w, self.m, self.x[_S].tolist(),
                                                  self.x[_H].tolist(), self.x[_W].tolist(), weights.tolist()))

    def _contact_update(self) -> None:
        st = self.settings
        c, J, active = self._wrench_jacobian(self.x[_H])
        unplaced = float(np.sqrt(self.P[18:20, 18:20].diagonal()).max()) > 0.5 * st.hole_std0
        if not active > 0.0 and unplaced:
            weights = np.sqrt(np.diag(self._Rc))
            found = self._locate_hole(weights)
            if found is None:
                return
            self.x[_H] = found
            c, J, active = self._wrench_jacobian(self.x[_H])
        # the law's rows: H = [G, Hh] with G = [-dc/ds, I] over z = [s, W] (fixed over the iterations) and
        # Hh = -dc/dh over the hole, which the law sees as h + b; S and P H^T by blocks, the parts
        # that do not involve Hh formed once
        P, Pxb, Pbb = self.P, self._Pxb, self._Pbb
        G = self._G_contact
        G[:, :N_REDUCED] = -J[:, :N_REDUCED]
        GP = G @ P[:18]  # (6, 22)
        GPxb = G @ Pxb[:18]
        A0 = GP[:, :18] @ G.T + self._Rc
        D = P[_H, _H] + Pxb[_H]  # cov(h, h + b)
        E = D + Pxb[_H].T + Pbb  # cov(h + b)
        Z = np.vstack([-(GP[:, _H] + GPxb), -D, E])  # [-G cov(z, h + b); -cov(h, h + b); cov(h + b)]
        C = GP[:, _H].T  # P[h, z] G^T
        prior = self.x[_H].copy()
        wrench = self.x[_W].copy()
        scale = np.sqrt(np.diag(P)[_H])
        hi = prior
        for iteration in range(st.contact_iterations):
            if iteration:
                c, Jh = self._hole_linearization(hi)
            else:
                Jh = J[:, N_REDUCED:]  # Hh = -Jh: the signs below flip exactly
            # the law linearised at hi, its innovation taken about the prior (Gauss-Newton step)
            innovation = c - wrench + Jh @ (prior - hi)
            Y = Z @ Jh.T  # [G cov(z, h + b) Hh^T; cov(h, h + b) Hh^T; cov(h + b) Jh^T]
            S = A0 + Y[:6] + Y[:6].T + Jh @ Y[10:]
            PHt = C + Y[6:10]  # the hole's rows of P H^T (the law seeing h + b)
            Sinv = np.linalg.inv(S)
            weighted = Sinv @ innovation
            new = prior + PHt @ weighted
            done = float((np.abs(new - hi) / scale).max()) < st.contact_tolerance
            hi = new
            if done:
                break
        self.consistency = float(innovation @ weighted)  # the last iteration's S^-1 innovation
        if self.consistency <= st.contact_gate:
            self._rejected = 0
            self._correct_hole(GP, GPxb, -Jh, PHt @ Sinv, innovation)
            return
        self._rejected += 1
        if self._rejected >= st.reject_samples:
            self._reopen_hole()

    def _detect_manoeuvre(self, nis: float) -> None:
        """The wrench's process noise level from the joint angles' innovations (Bar-Shalom, Li,
        Kirubarajan 2001, section 11.2: adjustable process noise): while the sum of the last
        manoeuvre_samples normalised innovations stays within its chi-square 0.999 quantile the
        wrench walks at the steady levels; above it, at force_rate_std and moment_rate_std, and the
        wrench's covariance first gets what that walk would have added over the window, its rate V
        starting over (zero mean, force_ramp_std and moment_ramp_std, uncorrelated). ``nis``: the
        angles' normalised innovation r^T S^-1 r at this sample."""
        st = self.settings
        if not (st.steady_force_rate_std or st.steady_moment_rate_std):
            return
        self._nis.append(nis)
        del self._nis[:-st.manoeuvre_samples]
        manoeuvre = len(self._nis) == st.manoeuvre_samples and sum(self._nis) > self._nis_gate
        if manoeuvre and not self.manoeuvre:
            window = st.manoeuvre_samples
            self.P[_W, _W] += window * (self._Q[_W, _W] - self._Q_steady[_W, _W])
            if st.force_ramp_std or st.moment_ramp_std:
                # the wrench's rate starts over: a new contact's ramp, unrelated to the last one's
                self.x[_V] = 0.0
                self.P[_V, :] = 0.0
                self.P[:, _V] = 0.0
                self.P[_V, _V] = self._ramp
                self._Pxb[_V] = 0.0
            self.manoeuvres += 1
        self.manoeuvre = manoeuvre

    def _reopen_hole(self) -> None:
        """The law has disagreed with the estimate for reject_samples samples in a row: the hole's
        estimate is wrong by more than its covariance says (a contact linearised in the wrong
        place), and gating keeps it so. Its covariance goes back to the prior's about the current
        mean, its correlations with the rest dropped (module docstring)."""
        st = self.settings
        self.P[_H, :] = 0.0
        self.P[:, _H] = 0.0
        self.P[_H, _H] = np.diag([st.hole_std0 ** 2] * 2 + [st.tilt_std0 ** 2] * 2)
        self._Pxb[_H] = 0.0
        self._rejected = 0
        self.reopened += 1

    def _correct_angles(self, H: np.ndarray, PHt: np.ndarray, S: np.ndarray, K: np.ndarray,
                        residual: np.ndarray) -> None:
        """The joint angles' Joseph update of all the states, the law's offset b considered (the
        angles do not see it; its rows of the gain are zero). H: the rows' columns of the first six
        states (the others are zero), PHt = P H^T, S = H P H^T + R, K = P H^T S^-1. The Joseph
        product (I - K H) P (I - K H)^T + K R K^T with (I - K H) X = X - K (H X): H touches six
        columns, so each factor is a rank-6 correction; P_xb <- (I - K H) P_xb."""
        M = self.P - K @ PHt.T  # (I - K H) P
        P = M - (M[:, :6] @ H.T) @ K.T + (K @ self._R) @ K.T
        self.P = 0.5 * (P + P.T)
        self._Pxb -= K @ (H @ self._Pxb[:6])
        self.x += K @ residual

    def _correct_hole(self, GP: np.ndarray, GPxb: np.ndarray, Hh: np.ndarray, K: np.ndarray,
                      innovation: np.ndarray) -> None:
        """The contact law's Joseph update of the hole only (Schmidt: the gain's other rows and b's
        are zero), the law seeing h + b: rows H = [G, Hh] over [z, h] and Hh over b (``GP``,
        ``GPxb``: G P[z], G P_xb[z]), the hole's gain K (4, 6). The augmented Joseph product
        (I - K_a H_a) P_a (I - K_a H_a)^T + K_a R K_a^T with K_a nonzero in the hole's rows only:
        the left factor changes the hole's rows of [P, P_xb] by -K (H_a P_a), the right one the
        hole's columns of P by -(M H_a^T) K^T (M: the left product), then K R K^T in the hole's
        block; P_xb keeps the left product's (b's gain rows are zero)."""
        P, Pxb = self.P, self._Pxb
        P[_H] -= K @ (GP + Hh @ (P[_H] + Pxb.T))  # H_a P_a's x columns: G P[z] + Hh (P[h] + P_xb^T)
        Pxb[_H] -= K @ (GPxb + Hh @ (Pxb[_H] + self._Pbb))  # its b columns
        MHt = P[:, :18] @ self._G_contact.T + (P[:, _H] + Pxb) @ Hh.T
        P[:, _H] -= MHt @ K.T
        P[_H, _H] += (K @ self._Rc) @ K.T
        self.P = 0.5 * (P + P.T)
        self.x[_H] += K @ innovation
