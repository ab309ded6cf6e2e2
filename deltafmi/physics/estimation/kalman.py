"""Extended-Kalman-filter algebra shared by the estimators: discretisation and the Joseph update.

Continuous model x' = F(x, w) with white process noise; over a sample period T the transition
matrix is Phi = exp(A T) with A = dF/dx at the start of the period (a Taylor series through
(A T)^4 / 24: with |A| T << 1 the first neglected term, (A T)^5 / 120, is below round-off for a
1 kHz robot),
and the covariance propagates as P <- Phi P Phi^T + Qd. A measurement z = h(x) + r, r ~ N(0, R)
updates (Joseph form, which keeps P symmetric positive semi-definite whatever the gain):

    S = H P H^T + R,  K = P H^T S^-1,  x <- x + K (z - h(x)),
    P <- (I - K H) P (I - K H)^T + K R K^T.

Source: Simon, "Optimal State Estimation" (Wiley 2006), eqs. 5.19 (Joseph form) and 13.47-13.49
(the continuous-discrete extended Kalman filter).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["transition_matrix", "joseph_update", "white_acceleration_noise", "chi_square_quantile", "MANOEUVRE_Z"]

#: the standard normal quantile of a manoeuvre detector's chi-square gate (probability 0.999)
MANOEUVRE_Z = 3.090


def transition_matrix(A: np.ndarray, T: float, order: int = 4) -> np.ndarray:
    """exp(A T) by its Taylor series up to (A T)^order / order! (A square)."""
    AT = np.asarray(A, dtype=float) * T
    term = np.eye(AT.shape[0])
    Phi = term.copy()
    for k in range(1, order + 1):
        term = term @ AT / k
        Phi += term
    return Phi


def joseph_update(P: np.ndarray, H: np.ndarray, residual: np.ndarray, R: np.ndarray,
                  updated: slice | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The state correction K (z - h(x)) and the updated covariance for one measurement batch.

    With ``updated``, only those states are corrected and the others are "considered" (the
    Schmidt-Kalman filter: the rows of K outside ``updated`` are zero; their uncertainty still
    enters S, and the Joseph form stays the exact covariance for this suboptimal gain; Simon 2006,
    section 7.4).

    Args:
        P: prior covariance (n, n).
        H: measurement Jacobian dh/dx (m, n).
        residual: z - h(x) (m,).
        R: measurement noise covariance (m, m).
        updated: the states the batch corrects (None: all).

    Returns:
        (dx (n,), P (n, n)) with P symmetrised.
    """
    PHt = P @ H.T
    S = H @ PHt + R
    K = np.linalg.solve(S, PHt.T).T
    if updated is not None:
        keep = np.zeros(P.shape[0], dtype=bool)
        keep[updated] = True
        K[~keep] = 0.0
    IKH = np.eye(P.shape[0]) - K @ H
    P = IKH @ P @ IKH.T + K @ R @ K.T
    return K @ residual, 0.5 * (P + P.T)


def white_acceleration_noise(T: float) -> np.ndarray:
    """Position/velocity covariance after T of unit white acceleration noise (unit PSD):
    [[T^3/3, T^2/2], [T^2/2, T]] (Bar-Shalom et al., "Estimation with Applications to Tracking and
    Navigation", 2001, eq. 6.2.2-12)."""
    return np.array([[T ** 3 / 3.0, T ** 2 / 2.0], [T ** 2 / 2.0, T]])


def chi_square_quantile(dof: int, z: float) -> float:
    """The chi-square quantile with dof degrees of freedom at the standard normal quantile z
    (Wilson-Hilferty: dof (1 - 2 / (9 dof) + z sqrt(2 / (9 dof)))^3; relative error below 2e-3 for
    dof >= 30 at z = 3.09)."""
    a = 2.0 / (9.0 * dof)
    return dof * (1.0 - a + z * math.sqrt(a)) ** 3
