"""Linear MPC over affine, possibly time-varying stages, with input bounds and soft output limits, by OSQP
or DAQP.

Problem at each sample, for the measured state x̂ (horizon N):

    min  sum_(k<N) 1/2 |C x_k + D u_k + g - r_k|^2_(Q_k) + 1/2 |u_k - ur_k|^2_R
         + 1/2 |C x_N + g - r_N|^2_(Q_N) + sum_k (rho_l 1's_k + 1/2 rho_q |s_k|^2)
    s.t. x_0 = x̂,  x_(k+1) = A_k x_k + B_k u_k + e_k,  u_min <= u_k <= u_max,
         lo - s_k <= H x_k + h <= hi + s_k,  s_k >= 0   (k = 1..N; soft output limits)

Formulation: condensed. The states are eliminated, x_k = Phi_k x̂ + G_k U + c_k (products of
the stages' A_k, B_k, e_k), leaving the N nu inputs and the slacks as OSQP's variables. Why: on the
delta robot's model sampled at 2 ms, B is 1e-6 (positions) to 1e-3 (rates) per N m, so the sparse
(uncondensed) form's dynamics rows are badly scaled; measured, it took OSQP 325-525 ADMM
iterations per sample at 1e-5 (9 ms), where the condensed Hessian's condition number is about 70.
(Both were measured with rho_l = 1e5; the penalty turned out to matter as much, see rho_l; the
sparse form was not measured again with the smaller one.) With 3 inputs and N = 25 the dense QP
is small (75 inputs). Each stage sequence (a contact mode along the horizon) has its own OSQP
solver, set up (condensed and factorized) the first time the sequence is met and kept (up to
``modes`` of them, the least recently used dropped): a mode switch costs a solve, not a new
factorization; a new state, reference or disturbance changes only vectors.

What decides a solve: iterations and tolerances only, never the clock (no time limit; rho
adapted every ``adaptive_rho_interval`` iterations, not at a fraction of the setup time as
OSQP's interval 0 does). With ``polish`` the returned point is the solution of the equality QP
on the active set ADMM found (when polishing succeeds, ``MpcSolution.polished``): it does not
depend on the path of the iterations, so a rounding difference (another BLAS, another CPU) that
changes the iteration path does not change the answer beyond rounding.
The slacks make every problem feasible (the state at k = 0 is given, the limits start at k = 1);
rho_l above the largest multiplier makes the penalty exact: the limits hold whenever they can
(Kerrigan & Maciejowski, "Soft constraints and exact penalty functions in MPC", UKACC 2000).
Warm start: the previous solution, primal and dual, shifted by one sample.

``solver="daqp"`` solves the same condensed QP by a dual active-set method (:mod:`.active_set`):
each mode's solver keeps its factorization, every solve starts from the last active set (after
a mode switch, the other mode's: the rows are the same), and the result is the exact solution of
the active set it ends on (``MpcSolution.polished``), decided by the active set, not by an
iteration count or a tolerance met on the way.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
import osqp
import scipy.sparse as sp

from .active_set import DenseActiveSetQP
from .models import AffineStage

__all__ = ["LinearMPC", "MpcSolution"]


@dataclass
class MpcSolution:
    """The first move, the predicted trajectory and what OSQP said."""

    u0: np.ndarray
    x: np.ndarray           # (N + 1, nx) predicted states
    u: np.ndarray           # (N, nu) planned inputs
    slack: float            # largest soft-limit violation planned
    status: str
    iterations: int
    solve_time: float       # s, wall clock of update + solve
    polished: bool = False  # the active set's equality QP was solved (polish succeeded)


class _Pattern:
    """A sparse matrix assembled from named blocks whose pattern never changes (explicit zeros kept):
    every mode's solver has the same KKT pattern."""

    def __init__(self, shape: tuple[int, int]) -> None:
        self.shape = shape
        self._rows: list[np.ndarray] = []
        self._cols: list[np.ndarray] = []
        self._masks: list[Optional[np.ndarray]] = []
        self._order: list[tuple[object, str]] = []
        self._perm: Optional[np.ndarray] = None

    def add(self, key: object, r0: int, c0: int, nr: int, nc: int, kind: str = "dense") -> None:
        """Block ``key`` at (r0, c0): ``dense``, ``upper`` (upper triangle of a square block) or ``diag``."""
        if kind == "diag":
            i = np.arange(nr)
            rows, cols, mask = r0 + i, c0 + i, None
        else:
            rr, cc = np.meshgrid(np.arange(nr), np.arange(nc), indexing="ij")
            mask = (rr <= cc).ravel() if kind == "upper" else None
            rows, cols = (r0 + rr).ravel(), (c0 + cc).ravel()
            if mask is not None:
                rows, cols = rows[mask], cols[mask]
        self._rows.append(rows)
        self._cols.append(cols)
        self._masks.append(mask)
        self._order.append((key, kind))

    def data(self, blocks: dict) -> np.ndarray:
        """The CSC data array for the block values ``blocks`` (key -> array; a diag takes a vector)."""
        parts = []
        for (key, _kind), mask in zip(self._order, self._masks):
            flat = np.ravel(np.asarray(blocks[key], dtype=np.float64))
            parts.append(flat[mask] if mask is not None else flat)
        values = np.concatenate(parts)
        return values[self._perm]

    def matrix(self, blocks: dict) -> sp.csc_matrix:
        rows, cols = np.concatenate(self._rows), np.concatenate(self._cols)
        index = sp.coo_matrix((np.arange(1, rows.size + 1, dtype=float), (rows, cols)), shape=self.shape).tocsc()
        index.sort_indices()
        self._perm = index.data.astype(int) - 1
        out = sp.csc_matrix((np.zeros(rows.size), index.indices.copy(), index.indptr.copy()), shape=self.shape)
        out.data[:] = self.data(blocks)
        return out


class LinearMPC:
    """Constrained linear MPC (see the module docstring for the problem), solved by OSQP.

    Args:
        stage: the model used at every stage until :meth:`solve` is given others.
        C, D, g: the cost outputs z = C x + D u + g (ny of them).
        Q, R: output and input weights (symmetric, Q >= 0, R > 0); Q_N: terminal output weight
            (default Q).
        N: horizon (samples).
        u_min, u_max: input bounds (None or +-inf: unbounded).
        H, h, lo, hi: limits lo <= H x + h <= hi on the states at k = 1..N (None: none).
        rho_l, rho_q: linear and quadratic penalties of the limits' slacks (rho_l, in cost per unit
            of the limited output, must exceed the hard limit's multiplier for an exact penalty;
            scaled far above the rest of the cost it slows OSQP down: on the delta robot's press,
            median 675 ADMM iterations with 1e5, 25 with 10); ``soft`` False: hard limits, no
            slacks (for problems known feasible: at a 1e-9 tolerance OSQP solved one in 100
            iterations that with slacks stalled at 20000).
        eps: OSQP's absolute and relative tolerance; ``polish`` refines the active set's solution;
            ``check_termination``: iterations between OSQP's convergence checks (5: a warm-started
            problem that converges at once stops after 5, not 25).
        modes: stage sequences whose solvers are kept (module docstring; 1: every new sequence
            condenses and factorizes again).
        solver: ``"osqp"`` (ADMM) or ``"daqp"`` (a dual active-set method on the same dense QP,
            :mod:`.active_set`: the exact solution of the active set it ends on; ``max_iter`` its
            iteration limit, ``eps`` its primal tolerance, the OSQP-only options unused).
    """

    #: the condensed arrays of one stage sequence (what a cached mode restores)
    _CONDENSED = ("_stages", "_weights", "_Phi", "_G", "_c", "_M", "_S", "_Zx", "_zc", "_Zd", "_W", "_Puu", "_HG",
                  "_HPhi", "_Hc", "_Hd")

    def __init__(self, stage: AffineStage, C: np.ndarray, D: np.ndarray, g: np.ndarray, Q: np.ndarray,
                 R: np.ndarray, N: int, Q_N: Optional[np.ndarray] = None, u_min: Optional[np.ndarray] = None,
                 u_max: Optional[np.ndarray] = None, H: Optional[np.ndarray] = None,
                 h: Optional[np.ndarray] = None, lo: Optional[np.ndarray] = None, hi: Optional[np.ndarray] = None,
                 rho_l: float = 1e3, rho_q: float = 10.0, eps: float = 1e-6, polish: bool = True,
                 max_iter: int = 4000, check_termination: int = 5, soft: bool = True, modes: int = 8,
                 alpha: float = 1.6, solver: str = "osqp") -> None:
        if N < 1:
            raise ValueError(f"horizon N must be >= 1, got {N}")
        nx, nu = stage.B.shape
        ny = C.shape[0]
        if stage.A.shape != (nx, nx) or C.shape != (ny, nx) or D.shape != (ny, nu):
            raise ValueError(f"shapes do not agree: A {stage.A.shape}, B {stage.B.shape}, C {C.shape}, D {D.shape}")
        self.nx, self.nu, self.ny, self.N = nx, nu, ny, N
        self.C, self.D, self.g = np.asarray(C, float), np.asarray(D, float), np.asarray(g, float).reshape(ny)
        self.Q = np.asarray(Q, float)
        self.Q_N = self.Q if Q_N is None else np.asarray(Q_N, float)
        self.R = np.asarray(R, float)
        self.u_min = np.full(nu, -np.inf) if u_min is None else np.asarray(u_min, float).reshape(nu)
        self.u_max = np.full(nu, np.inf) if u_max is None else np.asarray(u_max, float).reshape(nu)
        if np.any(self.u_min > self.u_max):
            raise ValueError(f"input bounds cross: u_min {self.u_min} > u_max {self.u_max}")
        if H is None:
            H = np.zeros((0, nx))
        self.H = np.atleast_2d(np.asarray(H, float))
        nc = self.nc = self.H.shape[0]
        self.ns = nc if soft else 0  # slacks per stage
        self.h = np.zeros(nc) if h is None else np.asarray(h, float).reshape(nc)
        self.lo = np.full(nc, -np.inf) if lo is None else np.asarray(lo, float).reshape(nc)
        self.hi = np.full(nc, np.inf) if hi is None else np.asarray(hi, float).reshape(nc)
        self.rho_l, self.rho_q = float(rho_l), float(rho_q)
        self._stages = [stage] * N
        self._weights = [self.Q] * N + [self.Q_N]
        self._previous: Optional[tuple[np.ndarray, np.ndarray]] = None
        self._active: Optional[np.ndarray] = None  # DAQP: the active set of the last solve (where the next starts)
        if modes < 1:
            raise ValueError(f"modes must be >= 1, got {modes}")
        if solver not in ("osqp", "daqp"):
            raise ValueError(f"solver must be 'osqp' or 'daqp', got {solver!r}")
        self.solver = solver
        self.max_modes = int(modes)
        self._modes: dict = {}   # mode key -> (condensed arrays, solver), least recently used first
        self._condense()
        self._build(eps, polish, max_iter, check_termination, alpha)
        self._modes[self._key()] = (self._condensed(), self._solver)

    def _condense(self) -> None:
        """Phi (N+1 nx, nx), G (N+1 nx, N nu), c (N+1 nx) of x = Phi x0 + G U + c; then the
        stacked cost outputs Z = S U + Zx x0 + zc and the dense QP blocks."""
        nx, nu, N = self.nx, self.nu, self.N
        Phi = np.zeros(((N + 1) * nx, nx))
        G = np.zeros(((N + 1) * nx, N * nu))
        c = np.zeros((N + 1) * nx)
        M = np.zeros(((N + 1) * nx, nx))  # response to a constant d added to every e_k
        Phi[:nx] = np.eye(nx)
        for k, stage in enumerate(self._stages):
            now, nxt = slice(k * nx, (k + 1) * nx), slice((k + 1) * nx, (k + 2) * nx)
            Phi[nxt] = stage.A @ Phi[now]
            G[nxt] = stage.A @ G[now]
            G[nxt, k * nu:(k + 1) * nu] = stage.B
            c[nxt] = stage.A @ c[now] + stage.e
            M[nxt] = stage.A @ M[now] + np.eye(nx)
        self._Phi, self._G, self._c, self._M = Phi, G, c, M
        blocks_C = np.kron(np.eye(N + 1), self.C)
        D_bar = np.vstack([np.kron(np.eye(N), self.D), np.zeros((self.ny, N * nu))])
        self._S = blocks_C @ G + D_bar
        self._Zx, self._zc, self._Zd = blocks_C @ Phi, blocks_C @ c + np.tile(self.g, N + 1), blocks_C @ M
        W = np.zeros(((N + 1) * self.ny,) * 2)
        for k, Qk in enumerate(self._weights):
            W[k * self.ny:(k + 1) * self.ny, k * self.ny:(k + 1) * self.ny] = Qk
        self._W = W
        self._Puu = self._S.T @ W @ self._S + np.kron(np.eye(N), self.R)
        H_bar = np.kron(np.eye(N), self.H)  # limits on x_1 .. x_N
        self._HG, self._HPhi, self._Hc = H_bar @ G[nx:], H_bar @ Phi[nx:], H_bar @ c[nx:] + np.tile(self.h, N)
        self._Hd = H_bar @ M[nx:]

    def _build(self, eps: float, polish: bool, max_iter: int, check_termination: int, alpha: float) -> None:
        nu, N = self.nu, self.N
        nU, nC, nS = N * nu, N * self.nc, N * self.ns
        P = _Pattern((nU + nS, nU + nS))
        P.add("uu", 0, 0, nU, nU, "upper")
        if nS:
            P.add("ss", nU, nU, nS, nS, "diag")
        A = _Pattern((nU + 2 * nC + nS, nU + nS))
        A.add("box", 0, 0, nU, nU, "diag")
        for name, row in (("hi", nU), ("lo", nU + nC)) if nC else ():
            A.add(name, row, 0, nC, nU)
            if nS:
                A.add(name + "s", row, nU, nS, nS, "diag")
        if nS:
            A.add("slack", nU + 2 * nC, nU, nS, nS, "diag")
        self._P, self._A = P, A
        # iteration counts and tolerances decide a solve (module docstring): no time limit (OSQP 1.x
        # takes none below 1e10 s, 0 is refused), rho adapted on an iteration count
        self._options = dict(eps_abs=eps, eps_rel=eps, polishing=polish, max_iter=max_iter, verbose=False,
                             warm_starting=True, check_termination=check_termination, adaptive_rho=True, alpha=alpha,
                             adaptive_rho_interval=25, time_limit=1e10)
        self._solver = self._new_solver()

    def _new_solver(self, history: object = None) -> "osqp.OSQP | DenseActiveSetQP":
        """The QP solver set up with the current matrices (the bounds and q are set before every
        solve), continuing ``history`` (from :meth:`_history`; None: a new one)."""
        n = self.N * (self.nu + self.ns)
        if self.solver == "daqp":
            return DenseActiveSetQP(self._P.matrix(self._p_blocks()), np.zeros(n), self._A.matrix(self._a_blocks()),
                                    *self._bounds(np.zeros(self.nx), np.zeros(self.nx)),
                                    max_iter=self._options["max_iter"], primal_tol=self._options["eps_abs"])
        solver = osqp.OSQP()
        options = self._options if history is None else {**self._options, "rho": float(history)}
        solver.setup(self._P.matrix(self._p_blocks()), np.zeros(n), self._A.matrix(self._a_blocks()),
                     *self._bounds(np.zeros(self.nx), np.zeros(self.nx)), **options)
        return solver

    def _history(self, solver: "osqp.OSQP | DenseActiveSetQP") -> object:
        """What a solver carries from one solve to the next, beyond the matrices and the warm start
        given before each solve: OSQP's step size rho (adapted during the solves, set up with the
        matrices: a new factorization); nothing of DAQP's, every solve of which starts from the
        active set given (:attr:`_active`)."""
        if self.solver == "daqp":
            return None
        # the C solver's rho: the Python side's settings keep the one it was set up with
        return float(solver._solver.get_settings().rho)  # noqa: SLF001

    # an FMU's state (fmi2GetFMUstate) is a deep copy of its component: a solver is no Python value,
    # so a copy sets up its own for every kept mode from the same matrices and what that solver
    # carries from solve to solve (:meth:`_history`), and warm-starts from the same plan: it
    # continues as the original does, to the bit; the modes are keyed by the stages' identities,
    # which a copy keeps among its own objects (copy and pickle keep shared references shared), so
    # the keys are made anew
    def __getstate__(self) -> dict:
        state = {key: value for key, value in self.__dict__.items() if key not in ("_solver", "_modes")}
        state["_kept"] = [condensed for condensed, _solver in self._modes.values()]
        state["_histories"] = [self._history(solver) for _condensed, solver in self._modes.values()]
        return state

    def __setstate__(self, state: dict) -> None:
        kept = state.pop("_kept", [])
        histories = state.pop("_histories", None) or [None] * len(kept)  # a state from before: none
        state.setdefault("_active", None)
        self.__dict__.update(state)
        current = self._key()
        self._modes = {}
        for condensed, history in zip(kept, histories):  # least recently used first, as they were
            self.__dict__.update(condensed)
            self._modes[self._key()] = (condensed, self._new_solver(history))
        if current not in self._modes:
            self.__dict__.update(state)
            self._modes[current] = (self._condensed(), self._new_solver())
        condensed, self._solver = self._modes.pop(current)
        self.__dict__.update(condensed)
        self._modes[current] = (condensed, self._solver)

    def _key(self) -> tuple:
        return tuple(id(s) for s in self._stages) + tuple(id(w) for w in self._weights)

    def _condensed(self) -> dict:
        return {name: getattr(self, name) for name in self._CONDENSED}

    def _switch(self, stages: list, weights: list) -> None:
        """Make the solver of this stage sequence current: a cached one, or condensed and set up
        now (the cache keeps the stages and weights alive, so their ids stay theirs)."""
        self._stages, self._weights = stages, weights
        key = self._key()
        mode = self._modes.pop(key, None)
        if mode is None:
            self._condense()
            self._solver = self._new_solver()
            mode = (self._condensed(), self._solver)
            while len(self._modes) >= self.max_modes:
                self._modes.pop(next(iter(self._modes)))
        else:
            self.__dict__.update(mode[0])
            self._solver = mode[1]
        self._modes[key] = mode

    def prepare(self, stages: Sequence[AffineStage], weights: Optional[Sequence[np.ndarray]] = None) -> None:
        """Condense and set up the solver of this stage sequence now (a mode the controller will
        meet), so that its first solve costs a solve; the current sequence stays current."""
        if len(stages) != self.N or (weights is not None and len(weights) != self.N + 1):
            raise ValueError(f"expected {self.N} stages and {self.N + 1} weights")
        current = (self._stages, self._weights)
        self._switch(list(stages), list(self._weights if weights is None else weights))
        self._switch(*current)

    def _p_blocks(self) -> dict:
        return {"uu": self._Puu, "ss": np.full(self.N * self.ns, self.rho_q)}

    def _a_blocks(self) -> dict:
        nS = self.N * self.ns
        return {"box": np.ones(self.N * self.nu), "hi": self._HG, "his": -np.ones(nS), "lo": self._HG,
                "los": np.ones(nS), "slack": np.ones(nS)}

    def _bounds(self, x0: np.ndarray, d: np.ndarray, lo: Optional[np.ndarray] = None,
                hi: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray]:
        N, nC, nS = self.N, self.N * self.nc, self.N * self.ns
        free = self._HPhi @ x0 + self._Hc + self._Hd @ d  # the limited outputs with U = 0
        inf = np.full(nC, np.inf)
        lo = np.tile(self.lo, N) if lo is None else self._per_stage(lo, "lo")
        hi = np.tile(self.hi, N) if hi is None else self._per_stage(hi, "hi")
        lower = np.concatenate([np.tile(self.u_min, N), -inf, lo - free, np.zeros(nS)])
        upper = np.concatenate([np.tile(self.u_max, N), hi - free, inf, np.full(nS, np.inf)])
        return lower, upper

    def _per_stage(self, limit: np.ndarray, name: str) -> np.ndarray:
        limit = np.asarray(limit, float)
        if limit.shape != (self.N, self.nc):
            raise ValueError(f"{name}: expected per-stage limits of shape {(self.N, self.nc)}, got {limit.shape}")
        return limit.ravel()

    # --- solving ------------------------------------------------------------------------------
    def solve(self, x0: np.ndarray, r: np.ndarray, ur: Optional[np.ndarray] = None,
              stages: Optional[Sequence[AffineStage]] = None,
              weights: Optional[Sequence[np.ndarray]] = None,
              disturbance: Optional[np.ndarray] = None, lo: Optional[np.ndarray] = None,
              hi: Optional[np.ndarray] = None) -> MpcSolution:
        """The optimal plan from state ``x0``.

        ``r``: output reference, (ny,) for all stages or (N + 1, ny); ``ur``: input reference, (nu,)
        or (N, nu) (default 0); ``stages``: N stage models replacing the current ones; ``weights``:
        N + 1 output weights replacing the current Q_0 .. Q_(N-1), Q_N; ``disturbance``: a constant
        d added to every stage's e (an estimated disturbance: offset-free tracking; default 0);
        ``lo``, ``hi``: (N, nc) limits of stages 1..N for this solve only (default: the constructor's,
        at every stage).
        """
        start = time.perf_counter()
        N = self.N
        r = np.broadcast_to(np.asarray(r, float), (N + 1, self.ny)).ravel()
        ur = np.zeros(N * self.nu) if ur is None else np.broadcast_to(np.asarray(ur, float), (N, self.nu)).ravel()
        new_stages, new_weights = self._stages, self._weights
        if stages is not None:
            if len(stages) != N:
                raise ValueError(f"expected {N} stages, got {len(stages)}")
            new_stages = list(stages)
        if weights is not None:
            if len(weights) != N + 1:
                raise ValueError(f"expected {N + 1} output weights (stages and terminal), got {len(weights)}")
            new_weights = list(weights)
        if any(a is not b for a, b in zip(new_stages, self._stages)) or \
                any(a is not b for a, b in zip(new_weights, self._weights)):
            self._switch(new_stages, new_weights)
        x0 = np.asarray(x0, float).reshape(self.nx)
        d = np.zeros(self.nx) if disturbance is None else np.asarray(disturbance, float).reshape(self.nx)
        z_free = self._Zx @ x0 + self._zc + self._Zd @ d
        q_u = self._S.T @ (self._W @ (z_free - r)) - (ur.reshape(N, self.nu) @ self.R.T).ravel()
        q = np.concatenate([q_u, np.full(N * self.ns, self.rho_l)])
        lower, upper = self._bounds(x0, d, lo, hi)
        self._solver.update(q=q, l=lower, u=upper)
        if self.solver == "daqp":
            # from the last solve's active set (another mode's after a switch: the rows are the same),
            # given every time: left alone, DAQP goes on from its workspace's factorization, built in
            # the order of the last solve's iterations, which an FMU state could not hold
            if self._active is not None:
                self._solver.start_from(self._active)
            found = self._solver.solve()
            if found.solved:
                self._active = self._solver.active.copy()
            v, status, iterations, polished = found.x, found.status, found.iterations, found.solved
        else:
            if self._previous is not None:
                self._solver.warm_start(x=self._shift(self._previous[0], (self.nu, self.ns)),
                                        y=self._shift(self._previous[1], (self.nu, self.nc, self.nc, self.ns)))
            result = self._solver.solve(raise_error=False)
            status, v = str(result.info.status), result.x
            iterations, polished = int(result.info.iter), int(result.info.status_polish) == 1
        if v is None or not np.all(np.isfinite(v)):
            raise RuntimeError(f"{self.solver.upper()} found no solution: {status}")
        if self.solver == "osqp":
            self._previous = (v.copy(), result.y.copy())
        U = v[:N * self.nu]
        xs = (self._Phi @ x0 + self._G @ U + self._c + self._M @ d).reshape(N + 1, self.nx)
        slack = float(np.max(v[N * self.nu:])) if self.ns else 0.0
        return MpcSolution(U[:self.nu].copy(), xs, U.reshape(N, self.nu), max(slack, 0.0), status,
                           iterations, time.perf_counter() - start, polished)

    def _shift(self, v: np.ndarray, sizes: tuple[int, ...]) -> np.ndarray:
        """A vector of per-stage blocks (N blocks of each size in turn) one sample on: every block
        moved up a stage, the last one repeated (the warm start)."""
        out, start = v.copy(), 0
        for size in sizes:
            if size:
                block = v[start:start + size * self.N].reshape(self.N, size)
                out[start:start + size * self.N] = np.vstack([block[1:], block[-1:]]).ravel()
            start += size * self.N
        return out
