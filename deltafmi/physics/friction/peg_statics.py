"""Quasi-static outcome of a peg in two-point contact, by linear programming over the contact
forces: the independent formulation checking :mod:`.peg`'s closed forms.

Unknowns ``N1, T1, N2, T2`` (forces on the peg, :func:`.peg.contacts` frames); equilibrium
``F + sum_i (N_i n_i + T_i t_i) = 0`` and ``M + sum_i p_i x (N_i n_i + T_i t_i) = 0``;
Coulomb ``|T_i| <= mu N_i``, ``N_i >= 0``. Outcome:

* ``"wedged"``: a self-balanced solution with ``N1 + N2 = 1`` exists for a zero wrench;
* ``"jammed"``: a solution exists for the applied wrench (the peg cannot move);
* ``"moves"``: none exists; the unbalanced wrench accelerates the peg (pushed with ``F_z < 0``
  and inside Whitney's parallelogram, it slides in).
"""
from __future__ import annotations

import numpy as np

from .peg import contacts

__all__ = ["peg_outcome"]


def _balance_matrix(l: float, d: float, D: float) -> np.ndarray:
    """Columns: the wrench ``(f_x, f_z, m)`` of a unit N1, T1, N2, T2."""
    geo = contacts(l, d, D)
    cols = []
    for p, n, t in zip(geo.points, geo.normals, geo.tangents):
        for f in (n, t):
            cols.append([f[0], f[1], p[0] * f[1] - p[1] * f[0]])
    return np.array(cols).T


def _feasible(A_eq: np.ndarray, b_eq: np.ndarray, mu: float) -> bool:
    from scipy.optimize import linprog  # scipy only where the study runs, never in an FMU

    cone = np.array([[-mu, 1.0, 0.0, 0.0], [-mu, -1.0, 0.0, 0.0],
                     [0.0, 0.0, -mu, 1.0], [0.0, 0.0, -mu, -1.0]])
    bounds = [(0.0, None), (None, None), (0.0, None), (None, None)]
    res = linprog(np.zeros(4), A_ub=cone, b_ub=np.zeros(4), A_eq=A_eq, b_eq=b_eq, bounds=bounds,
                  method="highs", options={"primal_feasibility_tolerance": 1e-10,
                                           "dual_feasibility_tolerance": 1e-10})
    return res.status == 0


def peg_outcome(wrench: tuple[float, float, float], l: float, d: float, D: float, mu: float) -> str:
    """``"wedged"``, ``"jammed"`` or ``"moves"`` for the applied ``(F_x, F_z, M)`` (module docstring)."""
    B = _balance_matrix(l, d, D)
    wedge = np.vstack([B, [1.0, 0.0, 1.0, 0.0]])
    if _feasible(wedge, np.array([0.0, 0.0, 0.0, 1.0]), mu):
        return "wedged"
    return "jammed" if _feasible(B, -np.asarray(wrench, float), mu) else "moves"
