"""Finite-horizon discrete LQR by the backward Riccati recursion (the unconstrained MPC's law)."""
from __future__ import annotations

import numpy as np

__all__ = ["finite_horizon_lqr"]


def finite_horizon_lqr(A: np.ndarray, B: np.ndarray, Qx: np.ndarray, S: np.ndarray, Ru: np.ndarray,
                       P_N: np.ndarray, N: int) -> list[np.ndarray]:
    """Gains K_0 .. K_(N-1) of u_k = -K_k x_k minimising

        1/2 x_N' P_N x_N + 1/2 sum_k (x_k' Qx x_k + 2 x_k' S u_k + u_k' Ru u_k),  x_(k+1) = A x_k + B u_k.

    Backward recursion (e.g. Anderson & Moore, Optimal Control, ch. 2, with the cross term S):
    K = (Ru + B' P B)^-1 (S' + B' P A),  P <- Qx + A' P A - (S + A' P B) K, from P = P_N.
    """
    if N < 1:
        raise ValueError(f"horizon N must be >= 1, got {N}")
    P = np.asarray(P_N, dtype=float)
    gains = []
    for _ in range(N):
        K = np.linalg.solve(Ru + B.T @ P @ B, S.T + B.T @ P @ A)
        P = Qx + A.T @ P @ A - (S + A.T @ P @ B) @ K
        P = 0.5 * (P + P.T)
        gains.append(K)
    return gains[::-1]
