"""Discrete affine stage models from continuous linearizations.

A stage maps x_k to x_(k+1) = A x_k + B u_k + e (e: the affine term of a mode whose operating
point differs from the linearization's, e.g. a pressed contact spring). A linearization of a
constrained mechanical system (``deltafmi linearize`` of the delta robot: 18 joint states with 6
loop closures held by Baumgarte stabilization) has modes no input reaches; the MPC keeps only the
controllable subspace (:func:`controllable_subspace`), on which the motion stays on the manifold.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg

__all__ = ["AffineStage", "controllable_subspace", "spring_contact", "zoh"]


class AffineStage(NamedTuple):
    """x_(k+1) = A x_k + B u_k + e (discrete)."""

    A: np.ndarray
    B: np.ndarray
    e: np.ndarray


def zoh(A: np.ndarray, B: np.ndarray, Ts: float, e: np.ndarray | None = None) -> AffineStage:
    """Zero-order-hold discretisation of x' = A x + B u + e over Ts, exact for u held constant:

    expm([[A, B, e], [0, 0, 0]] Ts) = [[Ad, Bd, ed], [0, I, 0], [0, 0, 1]]  (Van Loan's block form).
    """
    if not Ts > 0.0:
        raise ValueError(f"sample period Ts must be > 0, got {Ts}")
    n, m = B.shape
    e = np.zeros(n) if e is None else np.asarray(e, dtype=float)
    M = np.zeros((n + m + 1, n + m + 1))
    M[:n, :n], M[:n, n:n + m], M[:n, n + m] = A, B, e
    E = scipy.linalg.expm(M * Ts)
    return AffineStage(E[:n, :n], E[:n, n:n + m], E[:n, n + m])


def controllable_subspace(A: np.ndarray, B: np.ndarray, tolerance: float = 1e-6) -> np.ndarray:
    """An orthonormal basis (n x r) of the controllable subspace of (A, B).

    The orthogonal staircase (Krylov) iteration: start from the range of B, add A times the newest
    directions, keep what is new (orthogonal to the basis) with norm above ``tolerance`` times the
    scale of that step. Unlike the rank of [B, AB, ..., A^(n-1) B] this never forms powers of A.
    """
    n = A.shape[0]
    scale_a = max(float(np.linalg.norm(A, 2)), 1e-300)
    basis = np.zeros((n, 0))
    new = np.asarray(B, dtype=float)
    scale = max(float(np.linalg.norm(new, 2)), 1e-300)
    while new.shape[1] and basis.shape[1] < n:
        new = new - basis @ (basis.T @ new)
        new = new - basis @ (basis.T @ new)  # twice: orthogonal to working precision
        U, s, _ = np.linalg.svd(new, full_matrices=False)
        keep = U[:, s > tolerance * scale]
        if not keep.shape[1]:
            break
        basis = np.hstack([basis, keep])
        new = A @ keep
        scale = scale_a
    return basis


def spring_contact(A: np.ndarray, B_force: np.ndarray, normal: np.ndarray, C_position: np.ndarray,
                   C_velocity: np.ndarray, gap0: float, stiffness: float, damping: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """A compliant contact closed around a linear model: the contact mode's (A, e) and its force.

    The model's force input f (columns ``B_force``, a vector in the frame of the position output)
    receives f = n fn, the normal force of a spring-damper on the gap
    g = n.p + gap0 (p = C_position x: the contact point's deviation; gap0 the gap at x = 0):
    fn = -stiffness g - damping n.(C_velocity x) = H x + h.
    Returns A + B_force n H, e = B_force n h, and H (row), h.
    """
    n = np.asarray(normal, dtype=float)
    H = -stiffness * (n @ C_position) - damping * (n @ C_velocity)
    h = -stiffness * gap0
    Bn = B_force @ n
    return A + np.outer(Bn, H), Bn * h, H, float(h)
