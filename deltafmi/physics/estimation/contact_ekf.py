"""An extended Kalman filter of the delta robot's contact force and of the surface's height.

The talk asks "Task State or Parameter Estimation: can we estimate?" the unmeasured multipliers
lambda. Measured: the three servo angles y (noise y_std) and the commanded servo torques u (known
inputs). Estimated, 25 states X = [q (9), v (9), f (3), s, r (3)]:

- q, v: the robot's joint angles and rates; process model the stabilised DAE of
  :mod:`deltafmi.physics.delta.dynamics` (see :mod:`.delta_process` for the coordinates and
  how the covariance stays on the closed loops), with white task-space acceleration noise
  (acceleration_std) for the model's errors;
- f: the external force on the wrist, world frame, a random walk (force_rate_std): for the tool
  on a plane with normal n, f = n lambda, lambda the contact multiplier (the plant's fn). With
  steady_force_rate_std the walk has two levels (:meth:`ContactEKF._detect_manoeuvre`: slow
  between manoeuvres, force_rate_std in one, an impact detected from the servo angles'
  innovations, its window filtered again) and follows the contact: along n, friction times
  that across it;
- r: the force's rate, f' = r, a random walk (force_acceleration_std, along n and friction times
  it across): f is then an integrated random walk over the small steady walk, which follows a
  pressing force's ramp without lag and holds still when it stops. A manoeuvre restarts r about
  zero (force_ramp_std: a new contact's ramp, unrelated to the last); with law_manoeuvre the
  contact law's innovations, summed as the servo angles' are, reopen r by force_ramp_std when the
  force leaves the course r predicts (a ramp's end). With both levels 0 r stays zero and the force
  is the random walk alone;
- s: the height at which the surface crosses the robot axis, a constant.

At rest (rest_force_rate_std, with two levels; :meth:`ContactEKF._detect_rest`): the servo
torques are known exactly and, the robot still, balance the wrist force, so once the force they
balance has moved by less than the rest walk would over rest_samples samples, for that many
samples in a row, the force and its rate walk at the rest levels (rest_force_rate_std,
rest_force_acceleration_std) and, with rest_acceleration_std, the wrist's acceleration
Jv a(q, v, u, f) is a pseudo-measurement of zero: the force is then known from the torques'
balance, which the servo angles (the force integrates twice into them) and the contact law
(through the gap, which the angles' noise blurs) tell only over thousands of samples; without it
the force's deviation at rest stays some 15 times its error. A manoeuvre or torques that move end
the rest.

s is tied to the rest by the contact law as a pseudo-measurement, applied only while the filter
believes the tool presses (n . f > contact_threshold for contact_samples samples in a row, so that
noise on the force estimate does not fake a contact): the plant's spring-damper
lambda = k (-gap) + c (-gap') with gap = n . (z(q) + tool) - n_z s gives

    0 = n . f + k gap + c gap'   (noise contact_model_std, N: stiffness and damping errors),

so in contact s ~ tool height + lambda / k; out of contact s keeps its prior (and its standard
deviation says so). Why an EKF and not moving-horizon estimation: the model is smooth between
contact-mode changes, the noise Gaussian and the rate 1 kHz; a horizon of N samples would cost N
DAE linearisations per sample for little gain without inequality constraints to enforce.

Cycle per sample t_k (:meth:`ContactEKF.step`): predict from t_(k-1) with u(t_(k-1)), the
torque held over that period (at rest after the zero acceleration's update at t_(k-1), with that
period's Jacobian), then update with y(t_k) (Joseph form) and the gated contact update.
The published estimate is the posterior at t_k: it uses y(t_k) and is time-aligned with it.
Cost per sample: one exact DAE Jacobian (whose accelerations are the Runge-Kutta step's first
stage), three more DAE evaluations, one or two projections onto the loops and the wrist kinematics
once per state, all plain-float kernels (:mod:`.delta_process_kernels`; ``kernels`` may hand the
filter compiled ones, as the ContactEstimator FMU does), and the covariance algebra in numpy;
benchmarks/assembly_realtime.py times it.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np

from ..delta.jacobian import _SENSITIVITIES
from ..delta.kinematics import forward_kinematics, inverse_kinematics
from ..delta.params import DeltaParams
from .delta_process_kernels import PYTHON_KERNELS, ProcessKernels
from .kalman import MANOEUVRE_Z, chi_square_quantile, white_acceleration_noise

__all__ = ["ContactEKFSettings", "ContactEstimate", "ContactEKF"]

#: slices of the estimator state X = [q, v, f, s, r]
_Q, _V, _F, _S, _R = slice(0, 9), slice(9, 18), slice(18, 21), 21, slice(22, 25)
_N = 25
_Z = np.r_[0:21, 22:25]  #: the states the prediction's transition involves: [q, v, f, r] (s is constant)
_SERVOS = slice(0, 9, 3)  # q_11, q_21, q_31: the servo angles


@dataclass(frozen=True)
class ContactEKFSettings:
    """Noise levels, priors and contact model of :class:`ContactEKF` (SI units)."""

    sample_period: float = 1e-3  #: s
    y_std: float = 1e-5  #: servo-angle noise (rad)
    acceleration_std: float = 0.05  #: white wrist-acceleration noise, model error (m/s^2/sqrt(Hz))
    force_rate_std: float = 100.0  #: random walk of the wrist force (in a manoeuvre, with two levels) (N/s/sqrt(Hz))
    steady_force_rate_std: float = 0.0  #: its walk between manoeuvres (0: force_rate_std throughout, every direction)
    friction: float = 0.0  #: with two levels: the walk across the normal is friction times the one along it
    manoeuvre_samples: int = 10  #: samples of the angles' normalised innovations summed to detect a manoeuvre
    manoeuvre_hold: int = 0  #: samples a detected manoeuvre lasts at least (an impact's transient)
    force_acceleration_std: float = 0.0  #: white noise on the force's rate, its ramps (N/s^2/sqrt(Hz); 0: no rate)
    force_ramp_std: float = 0.0  #: the force's rate (N/s) after a manoeuvre, about zero: a new contact's ramp
    law_manoeuvre: bool = False  #: the detector also sums the contact law's normalised innovations (in contact)
    rest_force_rate_std: float = 0.0  #: the force's walk at rest (N/s/sqrt(Hz); 0: no rest level)
    rest_force_acceleration_std: float = 0.0  #: its rate's walk at rest (N/s^2/sqrt(Hz))
    rest_samples: int = 100  #: samples of still torques before the rest level applies
    rest_acceleration_std: float = 0.0  #: the wrist's acceleration at rest, a pseudo-measurement of 0 (m/s^2; 0: none)
    surface_drift_std: float = 0.0  #: random walk of the surface height (m/sqrt(s))
    position_std0: float = 1e-3  #: initial wrist position (m), around forward kinematics of y0
    velocity_std0: float = 0.01  #: initial wrist velocity (m/s), around zd0
    force_std0: float = 10.0  #: initial wrist force (N), around zero
    surface_height0: float = -1.1  #: prior surface height (m)
    surface_std0: float = 0.05  #: prior surface height standard deviation (m)
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)  #: surface normal, towards the robot
    tool: tuple[float, float, float] = (0.0, 0.0, -0.1)  #: tool tip from the plate centre (m)
    contact_stiffness: float = 2e5  #: N/m
    contact_damping: float = 2e3  #: N s/m
    contact_model_std: float = 5.0  #: noise of the contact-law pseudo-measurement (N)
    contact_threshold: float = 10.0  #: estimated normal force above which the tool presses (N)
    contact_samples: int = 10  #: samples in a row above contact_threshold before the contact law applies
    pole: float = 5.0  #: Baumgarte pole of the process model (1/s)
    substeps: int = 1  #: Runge-Kutta steps per sample period

    def __post_init__(self) -> None:
        positive = ("sample_period", "y_std", "contact_model_std", "position_std0", "velocity_std0",
                    "force_std0", "surface_std0")
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise ValueError(f"estimator setting {name} must be > 0, got {getattr(self, name)}")
        for name in ("acceleration_std", "force_rate_std", "steady_force_rate_std", "friction", "surface_drift_std",
                     "force_acceleration_std", "force_ramp_std", "rest_force_rate_std", "rest_force_acceleration_std",
                     "rest_acceleration_std",
                     "contact_stiffness", "contact_damping", "pole"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"estimator setting {name} must be >= 0, got {getattr(self, name)}")
        for name in ("substeps", "contact_samples", "manoeuvre_samples", "rest_samples"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"estimator setting {name} must be >= 1, got {getattr(self, name)}")
        if int(self.manoeuvre_hold) < 0:
            raise ValueError(f"estimator setting manoeuvre_hold must be >= 0, got {self.manoeuvre_hold}")
        n = np.asarray(self.normal, dtype=float).reshape(-1)
        norm = float(np.linalg.norm(n)) if n.shape == (3,) else 0.0
        if not norm > 0.0 or abs(n[2]) < 1e-6 * norm:
            raise ValueError(f"estimator surface normal must be a 3-vector with a z component "
                             f"(the surface crosses the robot axis), got {self.normal!r}")
        object.__setattr__(self, "normal", tuple(float(c) / norm for c in n))
        object.__setattr__(self, "tool", tuple(float(c) for c in self.tool))


class ContactEstimate(NamedTuple):
    """The filter's estimate with one standard deviation per quantity (SI units, world frame)."""

    z: np.ndarray  #: wrist (plate centre) position (3,)
    zd: np.ndarray  #: wrist velocity (3,)
    force: np.ndarray  #: external (contact) force on the wrist (3,)
    fn: float  #: normal contact force n . force (the multiplier lambda)
    surface_height: float  #: where the surface crosses the robot axis
    z_std: np.ndarray
    zd_std: np.ndarray
    force_std: np.ndarray
    fn_std: float
    surface_std: float
    in_contact: bool  #: the contact-law pseudo-measurement was applied at the last update


class ContactEKF:
    """Extended Kalman filter of the delta robot's wrist force and surface height (module docstring).

    Args:
        params: the robot as the estimator models it.
        settings: noise levels, priors, contact model.
        y0: the first servo-angle measurement (rad); the filter starts at its forward kinematics.
        zd0: the assumed initial wrist velocity (m/s).
        kernels: the process model's kernels (``predict``, ``project``, ``kinematics``: see
            :class:`.delta_process_kernels.ProcessKernels`), compiled ones for speed; by default
            the Python functions, which give the same numbers.
    """

    def __init__(self, params: DeltaParams, settings: ContactEKFSettings, y0: Sequence[float],
                 zd0: Sequence[float] = (0.0, 0.0, 0.0), kernels: ProcessKernels = PYTHON_KERNELS) -> None:
        self.params, self.settings = params, settings
        self._kernels = kernels
        z0 = forward_kinematics(params, y0)
        q = inverse_kinematics(params, z0)
        Tz = kernels.kinematics(params, q, np.zeros(9))[57:].reshape(9, 3)  # dq/dz
        self.x = np.zeros(_N)
        self.x[_Q], self.x[_V], self.x[_S] = q, Tz @ np.asarray(zd0, float), settings.surface_height0
        P = np.zeros((_N, _N))
        P[_Q, _Q] = settings.position_std0 ** 2 * Tz @ Tz.T
        P[_V, _V] = settings.velocity_std0 ** 2 * Tz @ Tz.T
        P[_F, _F] = settings.force_std0 ** 2 * np.eye(3)
        P[_S, _S] = settings.surface_std0 ** 2
        self.P = P
        self.in_contact = False
        self._pressing = 0  # samples in a row with n . f above contact_threshold
        self._u: list[float] | None = None  # servo torques held since the last sample
        n = np.array(settings.normal)
        self._n = n
        self._tool_along = float(n @ np.array(settings.tool))
        self._Ry = settings.y_std ** 2 * np.eye(3)
        self._ry = settings.y_std ** 2
        self._Rc = settings.contact_model_std ** 2
        self._G = np.zeros((6, 18))
        T = settings.sample_period
        self._W = settings.acceleration_std ** 2 * white_acceleration_noise(T)
        self._Qd = np.zeros((_N, _N))  # the process noise but for the joint block, which moves with q
        self._Qd[_F, _F] = settings.force_rate_std ** 2 * T * np.eye(3)
        self._Qd[_S, _S] = settings.surface_drift_std ** 2 * T
        # with two levels the force is the contact's: it walks along n, across it at friction times that
        # (a contact force stays in its friction cone), fast in a manoeuvre, at the steady level between
        steady = settings.steady_force_rate_std
        self._Qd_steady = self._Qd.copy()
        if steady:
            nn = np.outer(n, n)
            cone = T * (nn + settings.friction ** 2 * (np.eye(3) - nn))
            self._Qd[_F, _F] = settings.force_rate_std ** 2 * cone
            self._Qd_steady[_F, _F] = steady ** 2 * cone
        # at rest (the torques still: :meth:`_detect_rest`) the force and its rate walk at the rest levels
        self._Qd_rest = self._Qd_steady.copy()
        if steady:
            self._Qd_rest[_F, _F] = settings.rest_force_rate_std ** 2 * cone
        # the force's rate r: f' = r, r' white (an integrated random walk of f), in the walk's directions
        D = cone / T if steady else np.eye(3)
        for Qd, a in ((self._Qd, settings.force_acceleration_std), (self._Qd_steady, settings.force_acceleration_std),
                      (self._Qd_rest, settings.rest_force_acceleration_std)):
            Qd[_F, _F] += a * a * T ** 3 / 3.0 * D
            Qd[_F, _R] = Qd[_R, _F] = a * a * T ** 2 / 2.0 * D
            Qd[_R, _R] = a * a * T * D
        self._ramp = settings.force_ramp_std ** 2 * D  # the rate's covariance after a manoeuvre
        self._nis: list[float] = []  # the servo angles' last normalised innovations r^T S^-1 r
        self._nis_gate = chi_square_quantile(3 * int(settings.manoeuvre_samples), MANOEUVRE_Z)
        self._law_nis: list[float] = []  # the contact law's last normalised innovations, in contact
        self._law_gate = chi_square_quantile(int(settings.manoeuvre_samples), MANOEUVRE_Z)
        self.manoeuvre = False  #: a manoeuvre (an impact: the force changing fast) is detected
        self.manoeuvres = 0  #: manoeuvres detected so far
        self.rate_restarts = 0  #: changes of the force's rate the contact law detected (law_manoeuvre)
        # the detector's window: (x, P, torques held, pressing count, y) before each of its samples
        self._window: deque | None = deque(maxlen=int(settings.manoeuvre_samples)) if steady else None
        self._refilter = False  # the detector fired at this sample: filter its window again
        # the rest detector: the force the torques balance, where it was when they last moved, and since when
        self._rest_gate = MANOEUVRE_Z * settings.rest_force_rate_std * math.sqrt(settings.rest_samples * T)
        self._still_at: np.ndarray | None = None
        self._still = 0
        self.resting = False  #: the torques have been still for rest_samples: the force walks at the rest levels
        self._H_rest = np.zeros((3, _N))
        self._R_rest = settings.rest_acceleration_std ** 2 * np.eye(3)
        self._held = 0  # samples since the manoeuvre was detected
        self._kinematics_at: bytes = b""  # the (q, v) that _kinematics holds
        self._A = np.zeros((24, 24))  # d[q'; v'; f'; r']/d[q; v; f; r]: q' = v, f' = r, r' = 0 but for noise
        self._A[_Q, _V] = np.eye(9)
        self._A[_F, 21:24] = np.eye(3)
        self._I24 = np.eye(24)

    # --------------------------------------------------------------------------------- cycle
    def step(self, y: Sequence[float], u: Sequence[float]) -> ContactEstimate:
        """One sample t_k: predict over the last period with the torques held since t_(k-1) (none
        at the first sample), update with y (rad) at t_k; u (N m) is held from now on."""
        if self._window is not None:
            self._window.append((self.x.copy(), self.P.copy(), self._u, self._pressing, y))
        self._advance(y)
        if self._refilter:  # a manoeuvre began within the window: filter it again at the fast walk
            x, P, _, self._pressing, _ = self._window[0]
            self.x, self.P = x.copy(), P.copy()
            # the force's rate starts over: a new contact's ramp, unrelated to the last one's
            self.x[_R] = 0.0
            self.P[_R, :] = self.P[:, _R] = 0.0
            self.P[_R, _R] = self._ramp
            for _, _, self._u, _, earlier in self._window:
                self._advance(earlier)
            self._refilter = False
        self._u = [float(value) for value in u]
        self._detect_rest(self._u)
        return self.estimate()

    def _advance(self, y: Sequence[float]) -> None:
        if self._u is not None:
            self.predict(self._u)
        self.update(y)

    def update(self, y: Sequence[float]) -> None:
        """Measurement update with the servo angles, then the gated contact-law update."""
        self._correct_servos(np.asarray(y, float) - self.x[_SERVOS])
        pressing = float(self._n @ self.x[_F]) > self.settings.contact_threshold
        self._pressing = self._pressing + 1 if pressing else 0
        self.in_contact = self._pressing >= self.settings.contact_samples and not self.manoeuvre
        if not self.in_contact:
            self._law_nis.clear()
            return
        H, value = self._contact_row()
        self._law_manoeuvre(value * value / (H @ self.P @ H + self._Rc))
        self._correct_row(H, -value)

    def predict(self, u: Sequence[float]) -> None:
        """Propagate the state over one sample period with u held, and the covariance with it."""
        st, p = self.settings, self.params
        T = st.sample_period
        Tz = self._kinematics()[3]
        # (q, v) after the period and the exact Jacobian at its start (jacobian_values' floats)
        # the force held at its mid-period value (f + r T/2: the same as f for a plain walk)
        force = self.x[_F] + 0.5 * T * self.x[_R]
        out = self._kernels.predict(p, self.x[_Q], self.x[_V], u, force, T, st.pole, st.substeps)
        columns = out[18 + _SENSITIVITIES:].reshape(24, 15)  # per known [q, v, u, f]: [da (9); dlam (6)]
        A = self._A
        A[_V, :18] = columns[:18, :9].T
        A[_V, _F] = columns[21:24, :9].T
        # Phi = exp(A T) of z = [q, v, f, r] (s is constant: its row of the 25 is e_s) to (A T)^4 / 24,
        # as kalman.transition_matrix, by Horner's rule: I + AT (I + AT/2 (I + AT/3 (I + AT/4)))
        AT, I = A * T, self._I24
        Phi = I + AT / 4.0
        for k in (3.0, 2.0):
            Phi = I + AT @ Phi / k
        Phi = I + AT @ Phi
        TT = Tz @ Tz.T  # the process noise of [q, v]: kron(W, TT) = [[W00 TT, W01 TT], [W10 TT, W11 TT]]
        noise = (self._W[:, None, :, None] * TT[None, :, None, :]).reshape(18, 18)
        dx = self._correct_rest(columns, out[18:27]) if self.resting and st.rest_acceleration_std else None
        self.x[:18] = out[:18]
        self.x[_F] += T * self.x[_R]
        if dx is not None:  # the corrected state propagated: to first order, the prediction plus Phi dx
            self.x[_Z] += Phi @ dx[_Z]
            self.x[_S] += dx[_S]
        P = np.empty((_N, _N))
        PhiP = Phi @ self.P[_Z]
        P[np.ix_(_Z, _Z)] = PhiP[:, _Z] @ Phi.T
        P[_Z, _S] = P[_S, _Z] = PhiP[:, _S]
        P[_S, _S] = self.P[_S, _S]
        P += self._Qd if self.manoeuvre else self._Qd_rest if self.resting else self._Qd_steady
        P[:18, :18] += noise
        self.P = 0.5 * (P + P.T)

    # ------------------------------------------------------------------------------ outputs
    def estimate(self) -> ContactEstimate:
        """The current estimate and its standard deviations."""
        v, P = self.x[_V], self.P
        z, Jv, D, _ = self._kinematics()
        G = self._G  # rows: d z / d[q, v], d zd / d[q, v] = [D, Jv]
        G[:3, _Q] = G[3:, _V] = Jv
        G[3:, _Q] = D
        deviations = np.sqrt(np.maximum((G @ P[:18, :18] * G).sum(axis=1), 0.0))  # diag(G P G^T)
        n = self._n
        f = self.x[_F].copy()
        return ContactEstimate(
            z.copy(), Jv @ v, f, float(n @ f), float(self.x[_S]), deviations[:3], deviations[3:],
            np.sqrt(np.maximum(P.diagonal()[_F], 0.0)), math.sqrt(max(float(n @ P[_F, _F] @ n), 0.0)),
            math.sqrt(max(P[_S, _S], 0.0)), self.in_contact)

    def gap(self) -> float:
        """The estimated gap n . (z + tool) - n_z s (m) of the tool tip from the surface."""
        n = self._n
        return float(n @ self._kinematics()[0]) + self._tool_along - n[2] * float(self.x[_S])

    # ------------------------------------------------------------------------------ helpers
    def _kinematics(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """z(q), Jv(q), D(q, v) (:func:`.delta_process.wrist_jacobians`) and the tangent basis
        dq/dz (:func:`.delta_process.tangent_basis`) at the current state, computed once per state
        (the estimate, the gap, the contact row and the next prediction's process noise need them)."""
        key = self.x[:18].tobytes()
        if key != self._kinematics_at:
            values = self._kernels.kinematics(self.params, self.x[_Q], self.x[_V])
            arms = values[3:30].reshape(3, 3, 3)
            Jv = arms.transpose(1, 0, 2).reshape(3, 9) / 3.0  # [arm 1, arm 2, arm 3] / 3
            self._wrist = (values[:3], Jv, values[30:57].reshape(3, 9), values[57:].reshape(9, 3))
            self._kinematics_at = key
        return self._wrist

    def _contact_terms(self) -> tuple[float, float, np.ndarray, np.ndarray]:
        v, n = self.x[_V], self._n
        _, Jv, D, _ = self._kinematics()
        nJv = n @ Jv
        return self.gap(), float(nJv @ v), nJv, n @ D

    def _contact_row(self) -> tuple[np.ndarray, float]:
        """h_c(X) = n . f + k gap + c gap' and its gradient (22,)."""
        st, n = self.settings, self._n
        k, c = st.contact_stiffness, st.contact_damping
        gap, rate, nJv, nD = self._contact_terms()
        H = np.zeros(_N)
        H[_Q] = k * nJv + c * nD
        H[_V] = c * nJv
        H[_F] = n
        H[_S] = -k * n[2]
        return H, float(n @ self.x[_F]) + k * gap + c * rate

    def _correct_servos(self, residual: np.ndarray) -> None:
        """The Joseph update (:func:`.kalman.joseph_update`) with the servo angles, whose H selects
        three states: P H^T and H P H^T are columns and entries of P, and (I - K H) P (I - K H)^T
        is M - (M H^T) K^T with M = P - K (H P), two products of rank 3."""
        PHt = self.P[:, _SERVOS]
        Sinv = _inverse3(PHt[_SERVOS] + self._Ry)
        self._detect_manoeuvre(float(residual @ Sinv @ residual))  # changes P's force block only, not P H^T
        P = self.P
        K = PHt @ Sinv
        M = P - K @ P[_SERVOS]
        self._correct(M - M[:, _SERVOS] @ K.T + self._ry * (K @ K.T), K @ residual)

    def _detect_manoeuvre(self, nis: float) -> None:
        """The force's process noise level from the servo angles' innovations (Bar-Shalom, Li,
        Kirubarajan 2001, section 11.2: adjustable process noise; as :class:`.peg_ekf.PegEKF`): while
        the sum of the last manoeuvre_samples normalised innovations stays within its chi-square
        0.999 quantile the force walks at the steady level; above it at force_rate_std, for at
        least manoeuvre_hold samples. When it starts, :meth:`step` filters the window's samples again from the state
        before them at the fast walk (the manoeuvre began somewhere within the window; raising the
        force's covariance at the end only would have the force alone explain a motion the joints'
        states had already taken up, and overshoot). ``nis``: the angles' normalised innovation
        r^T S^-1 r at this sample."""
        st = self.settings
        if not st.steady_force_rate_std or self._refilter:
            return
        self._nis.append(nis)
        del self._nis[:-st.manoeuvre_samples]
        manoeuvre = len(self._nis) == st.manoeuvre_samples and sum(self._nis) > self._nis_gate
        if manoeuvre and not self.manoeuvre:
            self._refilter = True
            self.manoeuvres += 1
            self._held = 0
        self._held += 1
        self.manoeuvre = manoeuvre or (self.manoeuvre and self._held < st.manoeuvre_hold)

    def _detect_rest(self, u: list[float]) -> None:
        """With rest_force_rate_std (and two levels): whether the force is at rest over the next
        period. The servo torques u are known exactly; held still with the robot at rest they balance
        the wrist force, f = (dq_s/dz)^T u up to gravity's torque (virtual work, q_s the servo
        angles), so the force they imply moving by less than the rest walk would over rest_samples
        samples (its 0.999 quantile, MANOEUVRE_Z sigma) for rest_samples samples in a row says the
        force is still: its walk drops to the rest levels until the torques move or a manoeuvre is
        detected. A controller fed noisy angles moves its torques by more than that: no rest."""
        st = self.settings
        if not (st.rest_force_rate_std and st.steady_force_rate_std):
            return
        implied = self._kinematics()[3][_SERVOS].T @ np.asarray(u)
        if self.manoeuvre or self._still_at is None or np.linalg.norm(implied - self._still_at) > self._rest_gate:
            self._still_at, self._still = implied, 0
        else:
            self._still += 1
        self.resting = self._still >= st.rest_samples

    def _correct_rest(self, columns: np.ndarray, acceleration: Sequence[float]) -> np.ndarray:
        """At rest the wrist does not accelerate: Jv a(q, v, u, f) = 0, a pseudo-measurement of noise
        rest_acceleration_std at the start of the period :meth:`predict` is taking (a the DAE's
        joint accelerations under the torques held, the force at its mid-period value, and their
        gradient the prediction's exact Jacobian, ``columns``: no more process-model calls). The
        Joseph update of P by its products of rank 3, as :meth:`_correct_servos`; returns the
        state's correction, which the caller propagates."""
        T = self.settings.sample_period
        Jv = self._kinematics()[1]
        H = self._H_rest
        H[:, :18] = Jv @ columns[:18, :9].T
        H[:, _F] = Jv @ columns[21:24, :9].T
        H[:, _R] = 0.5 * T * H[:, _F]
        P = self.P
        PHt = P @ H.T
        Sinv = _inverse3(H @ PHt + self._R_rest)
        K = PHt @ Sinv
        M = P - K @ (H @ P)
        P = M - (M @ H.T) @ K.T + self._R_rest[0, 0] * (K @ K.T)
        self.P = 0.5 * (P + P.T)
        return K @ -(Jv @ np.asarray(acceleration))

    def _law_manoeuvre(self, nis: float) -> None:
        """With law_manoeuvre (and two levels), in contact: when the sum of the contact law's last
        manoeuvre_samples normalised innovations exceeds its chi-square 0.999 quantile, the force has
        left the course its rate predicts (a ramp ending, which the law sees long before the servo
        angles do): the rate's covariance grows by force_ramp_std squared, its estimate kept (a change
        of rate, not an impact: the force walks at the steady level and the law stays applied; no
        window is filtered again, which would cost manoeuvre_samples cycles at each)."""
        st = self.settings
        if not (st.law_manoeuvre and st.steady_force_rate_std) or self._refilter or self.manoeuvre:
            return
        self._law_nis.append(nis)
        del self._law_nis[:-st.manoeuvre_samples]
        if len(self._law_nis) == st.manoeuvre_samples and sum(self._law_nis) > self._law_gate:
            self._law_nis.clear()
            self.P[_R, _R] += self._ramp
            self.rate_restarts += 1

    def _correct_row(self, h: np.ndarray, residual: float) -> None:
        """The Joseph update with one scalar measurement of gradient h (the contact law), its
        products of rank 1 as in :meth:`_correct_servos`."""
        P = self.P
        PHt = P @ h
        K = PHt / (h @ PHt + self._Rc)
        M = P - np.outer(K, h @ P)
        self._correct(M - np.outer(M @ h, K) + self._Rc * np.outer(K, K), K * residual)

    def _correct(self, P: np.ndarray, dx: np.ndarray) -> None:
        """The corrected covariance (symmetrised) and state, projected onto the loops."""
        self.P = 0.5 * (P + P.T)
        self.x += dx
        self.x[:18] = self._kernels.project(self.params, self.x[_Q], self.x[_V])


def _inverse3(m: np.ndarray) -> np.ndarray:
    """The inverse of a regular 3 x 3 matrix by its adjugate (a fraction of numpy.linalg's call cost)."""
    (a, b, c), (d, e, f), (g, h, i) = m.tolist()
    c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * c00 + b * c01 + c * c02
    return np.array([[c00, c * h - b * i, b * f - c * e],
                     [c01, a * i - c * g, c * d - a * f],
                     [c02, b * g - a * h, a * e - b * d]]) / det
