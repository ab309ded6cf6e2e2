"""A state-space realization of a sampled system from its Markov parameters (Ho-Kalman / ERA).

A Co-Simulation FMU keeps its state to itself: FMI lets an importer save and restore it
(fmi2GetFMUstate), not read or set it. Its linearization around an operating point is still
known from outside: the Markov parameters h_0 = D, h_k = C F^(k-1) G, i.e. the outputs after
steps 1, 2, ... in answer to an input pulse in step 0. The eigensystem realization algorithm
turns them into a minimal (F, G, C, D) in a balanced basis: the SVD of the block Hankel matrix
[h_(i+j+1)] gives the order (its numerical rank) and the observability/controllability factors,
and the shifted Hankel matrix gives F. Modes that no input excites or no output shows are not in
it: they do not take part in the loop either.

Convention, as a co-simulation step has it: s[k+1] = F s[k] + G w[k], y[k+1] = C s[k] + D w[k]
(the output after a step depends on the state before it and on the step's input).
"""
from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

__all__ = ["era"]


class Realization(NamedTuple):
    """s[k+1] = F s + G w, y[k+1] = C s + D w; ``singular_values`` of the Hankel matrix."""

    F: np.ndarray
    G: np.ndarray
    C: np.ndarray
    D: np.ndarray
    singular_values: np.ndarray


def era(markov: Sequence[np.ndarray], rank_tolerance: float = 1e-7) -> Realization:
    """Minimal realization of the Markov parameters ``markov`` = [h_0, h_1, ..., h_(2m)].

    Each h_k is (ny, nu). The Hankel matrices use m blocks each way, so the order found is at
    most min(m ny, m nu). Singular values below ``rank_tolerance`` times the largest count as
    zero (the finite-difference noise of the Markov parameters sits far below the default).
    """
    h = [np.atleast_2d(np.asarray(k, dtype=float)) for k in markov]
    ny, nu = h[0].shape
    m = (len(h) - 1) // 2
    if m < 1:
        raise ValueError("need at least h_0, h_1 and h_2 for a realization")
    H0 = np.block([[h[i + j + 1] for j in range(m)] for i in range(m)])
    H1 = np.block([[h[i + j + 2] for j in range(m)] for i in range(m)])
    U, sigma, Vt = np.linalg.svd(H0)
    if sigma.size == 0 or sigma[0] == 0.0:
        return Realization(np.zeros((0, 0)), np.zeros((0, nu)), np.zeros((ny, 0)), h[0], sigma)
    order = int(np.sum(sigma > rank_tolerance * sigma[0]))
    root = np.sqrt(sigma[:order])
    Ur, Vr = U[:, :order], Vt[:order, :].T
    F = (Ur / root).T @ H1 @ (Vr / root)
    G = (root[:, None] * Vr.T)[:, :nu]
    C = (Ur * root)[:ny, :]
    return Realization(F, G, C, h[0], sigma)
