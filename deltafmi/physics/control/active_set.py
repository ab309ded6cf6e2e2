"""A dense QP in OSQP's form solved by DAQP, a dual active-set solver, set up once and warm-started.

The problem is OSQP's, min 1/2 x'P x + q'x s.t. l <= A x <= u, with P given as its upper triangle
(what :class:`.mpc.LinearMPC` builds for OSQP). Rows of A with a single nonzero are simple bounds
on their variable (DAQP treats those apart from the general rows, at no factorization cost); the
other rows stay general constraints. :meth:`DenseActiveSetQP.update` changes q, l and u only: the
Hessian's Cholesky factor and the constraints' transformation computed at set-up are kept, and
every solve starts from the active set the last one ended with (the warm start of a receding
horizon).

Why DAQP here: a condensed MPC of a hundred-odd variables is small and dense, where an active-set
method finishes in a few iterations from the previous active set, each one a rank-one update of a
factorization, and returns the exact solution of the final active set's equality QP (rounding
only): what decides it is the active set, not an iteration count or a tolerance met on the way.
ADMM (OSQP) needs tens to hundreds of iterations on the same problem, each a sparse triangular
solve, and a polish step to reach the same point. DAQP is MIT-licensed, has no dependencies, and
its solve takes no wall-clock limit (``time_limit`` 0). Source: Arnstrom, Bemporad, Axehill, "A
dual active-set solver for embedded quadratic programming using recursive LDL' updates", IEEE
TAC 67(8), 2022.
"""
from __future__ import annotations

from typing import NamedTuple, Optional

import daqp
import numpy as np
import scipy.sparse as sp

__all__ = ["ActiveSetResult", "DenseActiveSetQP"]

#: DAQP's exit flags (https://darnstrom.github.io/daqp/parameters)
_STATUS = {1: "solved", 2: "solved (soft constraints relaxed)", -1: "primal infeasible", -2: "cycling",
           -3: "unbounded", -4: "iteration limit reached", -5: "nonconvex", -6: "initial active set overdetermined"}


class ActiveSetResult(NamedTuple):
    """What one solve returned."""

    x: Optional[np.ndarray]  #: the solution (None when DAQP failed)
    status: str
    iterations: int
    solved: bool             #: DAQP reported an optimal active set


class DenseActiveSetQP:
    """DAQP over the QP ``P`` (upper triangle or full), ``A``, with the first ``q``, ``l``, ``u``.

    Args:
        P: the Hessian, sparse or dense (n, n); only its upper triangle is read.
        q, A, l, u: OSQP's cost vector and constraints l <= A x <= u (+-inf: none).
        max_iter: DAQP's iteration limit per solve.
        primal_tol: DAQP's primal feasibility tolerance.
    """

    def __init__(self, P, q: np.ndarray, A, l: np.ndarray, u: np.ndarray, max_iter: int = 1000,
                 primal_tol: float = 1e-6) -> None:
        upper = np.triu(P.toarray() if sp.issparse(P) else np.asarray(P, float))
        H = upper + upper.T - np.diag(np.diag(upper))
        A = sp.csr_matrix(A)
        n = H.shape[0]
        counts = np.diff(A.indptr)
        single = np.flatnonzero(counts == 1)
        self._bound_rows = single
        self._bound_vars = A.indices[A.indptr[single]]
        self._bound_scale = A.data[A.indptr[single]]
        if np.any(self._bound_scale == 0.0):
            raise ValueError("a constraint row with one explicit zero: no bound")
        self._general = np.flatnonzero(counts != 1)
        self.n, self._m = n, n + self._general.size
        self.active = np.zeros(self._m, dtype=np.int32)  #: DAQP's sense flags of the last active set
        self._model = daqp.Model()
        bu, bl = self._limits(l, u)
        flag, _ = self._model.setup(H, np.asarray(q, float), A[self._general].toarray(), bu, bl)
        if flag < 0:
            raise ValueError(f"DAQP could not set the QP up: {_STATUS.get(flag, flag)} (is P positive definite?)")
        self._model.settings = {"iter_limit": int(max_iter), "primal_tol": float(primal_tol), "time_limit": 0.0}

    def _limits(self, l: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """DAQP's (bupper, blower): a bound per variable (intersected over its rows), then the general rows."""
        l, u = np.asarray(l, float), np.asarray(u, float)
        lo, hi = np.full(self.n, -np.inf), np.full(self.n, np.inf)
        s = self._bound_scale
        row_lo = np.where(s > 0, l[self._bound_rows], u[self._bound_rows]) / s
        row_hi = np.where(s > 0, u[self._bound_rows], l[self._bound_rows]) / s
        np.maximum.at(lo, self._bound_vars, row_lo)
        np.minimum.at(hi, self._bound_vars, row_hi)
        return np.concatenate([hi, u[self._general]]), np.concatenate([lo, l[self._general]])

    def update(self, q: np.ndarray, l: np.ndarray, u: np.ndarray) -> None:
        """New cost vector and limits; the factorization and the active set stay."""
        bu, bl = self._limits(l, u)
        flag = self._model.update(f=np.asarray(q, float), bupper=bu, blower=bl)
        if flag < 0:
            raise ValueError(f"DAQP refused the update: {_STATUS.get(flag, flag)}")

    def start_from(self, active: np.ndarray) -> None:
        """Start the next solve from this active set (DAQP sense flags, :attr:`active` of a QP with
        the same constraints: another mode's solver)."""
        self._model.update(sense=np.asarray(active, dtype=np.int32))

    def solve(self) -> ActiveSetResult:
        """Solve from the last active set (failing that, from none)."""
        x, _fval, flag, info = self._model.solve()
        iterations = int(info["iterations"])
        if int(flag) <= 0:  # from the empty active set once more (a stale one can cycle)
            self._model.update(sense=np.zeros(self._m, dtype=np.int32))
            x, _fval, flag, info = self._model.solve()
            iterations += int(info["iterations"])
        flag = int(flag)
        ok = flag > 0
        if ok:  # DAQP's flags: 1 active (at the upper bound), + 2 at the lower one (a negative multiplier)
            lam = np.asarray(info["lam"], float)
            self.active = np.where(lam > 0.0, 1, np.where(lam < 0.0, 3, 0)).astype(np.int32)
        return ActiveSetResult(np.array(x, dtype=float) if ok else None, _STATUS.get(flag, f"exit flag {flag}"),
                               iterations, ok)
