"""A sampled closed loop's linearization made into a small MPC prediction model.

``deltafmi linearize SCENARIO`` gives a closed loop as the discrete map over one communication
step h: x[j+1] = Phi x[j] + Gamma w[j], y[j] = C x[j] (every unit's states: the plant's joint
states with their Baumgarte modes, the sampled controller's realization, held values). An MPC
sampled at n h that drives it through a reference polynomial, and measures only y, needs
three steps:

1. :func:`lift`: the map over n steps when w[j] = T(j h) v is a known linear function of the
   MPC's move v held over the sample (the reference r + rd t + rdd t^2 / 2 and its rates):
   x[k+1] = Phi^n x[k] + (sum_j Phi^(n-1-j) Gamma T(j h)) v[k] (exact);
2. :func:`balanced_truncation`: the square-root method (Laub, Heath, Paige & Ward, IEEE TAC 32,
   1987): with the Gramians P = Cholesky factors Lc Lc', Lo Lo', the SVD Lo' Lc = U S V' gives
   the balancing projections; keeping the r largest Hankel singular values s_i leaves an error
   ||G - G_r||_inf <= 2 sum_(i>r) s_i (Enns 1984; Glover 1984). Modes that no input reaches or
   no output shows (the loop closures' Baumgarte poles) have s_i at round-off level;
3. :func:`output_coordinates`: with as many kept states as outputs, the state change z = C_r x
   makes the state the outputs themselves, so the MPC's state is measured, no observer.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.linalg

__all__ = ["balanced_truncation", "lift", "output_coordinates"]


def lift(Phi: np.ndarray, Gamma: np.ndarray, n: int, shaping: Callable[[int], np.ndarray]
         ) -> tuple[np.ndarray, np.ndarray]:
    """(Phi^n, sum_(j<n) Phi^(n-1-j) Gamma shaping(j)): the map over n steps when the input at
    step j is shaping(j) @ v for a v held over the n steps."""
    if n < 1:
        raise ValueError(f"n must be >= 1 step, got {n}")
    A = np.eye(Phi.shape[0])
    B = np.zeros((Phi.shape[0], shaping(0).shape[1]))
    for j in range(n):
        B = Phi @ B + Gamma @ shaping(j)
        A = Phi @ A
    return A, B


def _cholesky_factor(W: np.ndarray) -> np.ndarray:
    """L with L L' = W for a symmetric positive semidefinite W (eigen-decomposition: a Gramian of
    a non-minimal system is singular, where Cholesky fails)."""
    w, V = np.linalg.eigh(0.5 * (W + W.T))
    return V * np.sqrt(np.clip(w, 0.0, None))


def balanced_truncation(A: np.ndarray, B: np.ndarray, C: np.ndarray, order: int
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(A_r, B_r, C_r, hsv) of the stable discrete system (A, B, C) truncated to ``order`` balanced
    states, and every Hankel singular value (descending)."""
    if np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
        raise ValueError("balanced truncation needs a stable (discrete) system: a pole has |z| >= 1")
    Wc = scipy.linalg.solve_discrete_lyapunov(A, B @ B.T)
    Wo = scipy.linalg.solve_discrete_lyapunov(A.T, C.T @ C)
    Lc, Lo = _cholesky_factor(Wc), _cholesky_factor(Wo)
    U, s, Vt = np.linalg.svd(Lo.T @ Lc)
    if not 0 < order <= int(np.sum(s > 0.0)):
        raise ValueError(f"order must be in 1..{int(np.sum(s > 0.0))} (the nonzero Hankel singular values), "
                         f"got {order}")
    scale = 1.0 / np.sqrt(s[:order])
    T = Lc @ Vt[:order].T * scale           # x = T x_r
    Ti = (U[:, :order] * scale).T @ Lo.T    # x_r = Ti x (Ti T = 1)
    return Ti @ A @ T, Ti @ B, C @ T, s


def output_coordinates(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(C A C^-1, C B): the same system in the coordinates z = C x (C square, invertible)."""
    if C.shape[0] != C.shape[1]:
        raise ValueError(f"output coordinates need as many outputs as states, got C {C.shape}")
    if np.linalg.cond(C) > 1e10:
        raise ValueError("the outputs do not determine the kept states (C is singular)")
    return C @ A @ np.linalg.inv(C), C @ B
