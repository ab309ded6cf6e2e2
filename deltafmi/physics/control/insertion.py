"""MPC of a peg insertion that plans the reference of an impedance-controlled robot.

The plant the MPC predicts is the closed loop "impedance controller + robot", linearized by
``deltafmi linearize`` of a scenario (the controller following external references r, rd, rdd;
outputs the tool tip and its velocity): a discrete map over the communication step h with some
thirty states. Feedback linearization makes that loop linear and decoupled per axis of the
nominal hole frame, M e'' + D e' + K e = F (e = tip - r, F the contact force), so two states per
axis carry all of it. The MPC moves at every sample (period n h) by choosing the reference
acceleration rdd, held for the sample; r and rd follow it exactly (r + rd t + rdd t^2 / 2). From
the linearization (:mod:`.reduction`): lifted to the MPC's sample through that polynomial,
balanced and truncated to six states, expressed in the measured coordinates (tip, tip velocity).
Its state: X = (tip - tip0, tip velocity, r - r0, rd); stage: X+ = A X + B rdd.

Limits, per stage (soft, exact penalty, every row in newtons):

- axial push: with the tip blocked (a wedged peg, the hole's bottom), the impedance's static
  force along the hole is F_ax = K_ax a.(r - tip) + D_ax a.(rd - tip velocity) (a: into the
  hole), linear in X; F_ax <= force_limit. In free motion, with rd and rdd fed forward, it is
  ~0 (no limit);
- the reference's speed into the hole, by the depth its stage is predicted at (the previous
  plan's tip; hybrid stages, as contact_mpc's modes): speed_limit above the contact zone,
  contact_speed from contact_zone[0] above the nominal hole top to contact_zone[1] below it
  (where the chamfer meets the peg: the impact grows with the speed), bore_speed deeper, and
  bottom_speed from contact_zone[0] above the bore's bottom (a flat face meeting the peg's:
  stiffer than the chamfer's edge, so slower); the rows are scaled by D_ax
  (N per m/s);
- |rd| <= speed_limit per axis, |rdd| <= acceleration_limit (the input box).

Hybrid stages: while the force/torque sensor measures the peg pushed back along the hole by
at least contact_force (the bottom, a wedge, the chamfer's edge), every stage is BLOCKED: the
tip's motion along the hole is frozen (its rows of the free stage projected off the axis, its
axial position kept, its axial velocity zero), so F_ax is the push on the obstacle, and the
reference's speed is held to contact_speed (the push grows by at most K_ax contact_speed per
second); otherwise
every stage is FREE (the linearized loop). At rest against an obstacle F_ax is the impedance's
static force K_ax lead exactly. (Modes by the previous plan's predicted depth, blocked from
the nominal bottom on, chattered: the nominal bottom is not the true one, and a plan that
thinks the tip stopped short of it stops pushing.)

Cost: the reference at the goal (goal_depth below the nominal hole top on its axis) and the
tip's depth at the goal's (not its lateral position: the chamfer and the bore centre it on the
true hole, and a cost would make the reference push sideways against them), their rates at
zero, a small cost on rdd. The QP (:class:`.mpc.LinearMPC`, condensed: 90 inputs, 60 slacks) is
solved by DAQP, a dual active-set method (:mod:`.active_set`), one solver per mode (free,
blocked) set up when the planner is made, each solve starting from the last active set: the plan
is the active set's exact solution, decided by the active set and not by where iterations
stopped, so it is the same on any machine to rounding. ``solver="osqp"`` keeps ADMM (polished).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional, Sequence

import numpy as np

from .contact_mpc import pick
from .model_file import LinearModelFile
from .models import AffineStage
from .mpc import LinearMPC, MpcSolution
from .reduction import balanced_truncation, lift, output_coordinates

__all__ = ["BALANCING_SCALE", "InsertionMpc", "InsertionTask", "polynomial_shaping"]

#: input scale for balancing (m, m/s, m/s^2: the sizes of a reference move), so that the
#: Hankel singular values rank states by what a realistic reference excites
BALANCING_SCALE = (1e-2, 1e-1, 1.0)


@dataclass
class InsertionTask:
    """What the MPC knows of the insertion (SI units; world frame)."""

    hole_top: Sequence[float]        #: nominal hole top centre
    hole_axis: Sequence[float]       #: nominal hole axis, out of the hole
    goal_depth: float                #: depth below the top where the tip should go
    axial_stiffness: float           #: K_ax of the impedance (N/m)
    axial_damping: float             #: D_ax (N s/m)
    force_limit: float               #: N, bound on F_ax
    speed_limit: float               #: m/s, |rd| per axis and the speed into the hole above the zone
    contact_speed: float             #: m/s, into the hole inside the contact zone
    bore_speed: float                #: m/s, into the hole below the zone
    contact_zone: Sequence[float]    #: (above, below) the nominal top, m
    acceleration_limit: float        #: m/s^2, |rdd| per axis
    sample_period: float             #: s, a multiple of the linearization's step
    horizon: int                     #: samples
    bottom_depth: float = math.inf   #: nominal depth of the bore's bottom (m; inf: none)
    bottom_speed: float = 0.003      #: m/s, into the hole near the bottom
    contact_force: float = 2.0       #: N, measured push-back above which the stages are blocked
    position_weight: float = 1e4     #: 1/m^2, tip and reference against the goal
    velocity_weight: float = 10.0    #: (s/m)^2, their rates
    acceleration_weight: float = 1e-3  #: (s^2/m)^2, on rdd
    limit_penalty: float = 10.0      #: cost per N of planned excess (exact penalty)
    tolerance: float = 1e-5          #: DAQP's primal tolerance; OSQP's absolute and relative one
    max_iterations: int = 4000       #: the QP solver's iteration limit per sample
    polish: bool = True              #: solve the active set's equality QP after ADMM (.mpc)
    relaxation: float = 1.0          #: OSQP's alpha (1: no over-relaxation; measured, fewer iterations
                                     #: at the worst samples than OSQP's 1.6 on this QP)
    modes: int = 8                   #: stage sequences whose QP solvers are kept (.mpc)
    solver: str = "daqp"             #: "daqp" (dual active set, .active_set) or "osqp" (ADMM; tolerance,
                                     #: max_iterations, polish and relaxation are its settings)

    def validate(self) -> None:
        """Raise ValueError naming the first value out of range."""
        for name in ("axial_stiffness", "axial_damping", "force_limit", "speed_limit", "contact_speed", "bore_speed",
                     "bottom_speed", "acceleration_limit", "sample_period"):
            value = getattr(self, name)
            if not (value > 0.0 and math.isfinite(value)):
                raise ValueError(f"{name} must be a finite number > 0, got {value}")
        if self.horizon < 1:
            raise ValueError(f"horizon must be >= 1 sample, got {self.horizon}")
        if len(self.contact_zone) != 2 or min(self.contact_zone) < 0.0:
            raise ValueError(f"contact_zone must be two distances >= 0 (above, below the top), got "
                             f"{list(self.contact_zone)}")
        if self.solver not in ("daqp", "osqp"):
            raise ValueError(f"solver must be 'daqp' or 'osqp', got {self.solver!r}")
        if not np.linalg.norm(np.asarray(self.hole_axis, float)) > 0.0:
            raise ValueError(f"hole_axis must be a nonzero vector, got {list(self.hole_axis)}")


def polynomial_shaping(Ts: float, lag: int) -> Callable[[int], np.ndarray]:
    """T(j): the loop's inputs (r, rd, rdd deviations) at step j of a sample as a linear map of
    (r_k, rd_k, rdd_k): r + rd t + rdd t^2 / 2, rd + rdd t, rdd at t = (j + lag) Ts (lag 1: the
    controller reads the reference the MPC set for the end of the step, as Gauss-Seidel does when
    the MPC steps first)."""
    I3, Z = np.eye(3), np.zeros((3, 3))

    def shaping(j: int) -> np.ndarray:
        t = (j + lag) * Ts
        return np.block([[I3, t * I3, 0.5 * t * t * I3], [Z, I3, t * I3], [Z, Z, I3]])
    return shaping


class InsertionMpc:
    """The MPC of the module docstring for one loop linearization and task."""

    def __init__(self, model: LinearModelFile, task: InsertionTask,
                 reference: Sequence[str] = ("controller.r", "controller.rd", "controller.rdd"),
                 measured: Sequence[str] = ("plant.tip", "plant.tip_velocity"), lag: int = 1) -> None:
        task.validate()
        if model.sample_time is None:
            raise ValueError("the insertion MPC needs a closed loop's discrete linearization (deltafmi linearize "
                             "SCENARIO), not a continuous one of an FMU")
        ir = [pick(model.inputs, [name], "input") for name in reference]
        im = pick(model.outputs, measured, "output")
        if [len(i) for i in ir] != [3, 3, 3] or len(im) != 6:
            raise ValueError(f"the loop model needs 3-vector inputs {', '.join(reference)} and outputs "
                             f"{', '.join(measured)} (has inputs {model.inputs}, outputs {model.outputs})")
        h = model.sample_time
        n = int(round(task.sample_period / h))
        if n < 1 or abs(n * h - task.sample_period) > 1e-9 * task.sample_period:
            raise ValueError(f"sample_period {task.sample_period:g} s must be a multiple of the linearization's "
                             f"step {h:g} s")
        Ts = task.sample_period
        Al, Bl = lift(model.A, model.B[:, ir[0] + ir[1] + ir[2]], n, polynomial_shaping(h, lag))
        scale = np.repeat(BALANCING_SCALE, 3)
        Ar, Br, Cr, self.hankel = balanced_truncation(Al, Bl * scale, model.C[im], 6)
        Az, Bz = output_coordinates(Ar, Br / scale, Cr)
        I3, Z = np.eye(3), np.zeros((3, 3))
        A = np.zeros((12, 12))
        A[:6, :6], A[:6, 6:12] = Az, Bz[:, :6]
        A[6:, 6:] = np.block([[I3, Ts * I3], [Z, I3]])
        B = np.vstack([Bz[:, 6:], 0.5 * Ts * Ts * I3, Ts * I3])
        self.stage = AffineStage(A, B, np.zeros(12))
        self.task, self.n_steps = task, n
        self.tip0, self.r0 = model.y0[im[:3]], model.u0[ir[0]]
        axis = np.asarray(task.hole_axis, float)
        self.into = -axis / np.linalg.norm(axis)   # a: into the hole
        self.blocked = self._blocked(self.stage, self.into)
        self.top = np.asarray(task.hole_top, float)
        K, D = task.axial_stiffness, task.axial_damping
        a = self.into
        H = np.zeros((2, 12))
        H[0] = np.concatenate([-K * a, -D * a, K * a, D * a])     # F_ax
        H[1, 9:] = D * a                                           # D_ax x speed into the hole
        self.h = np.array([K * a @ (self.r0 - self.tip0), 0.0])
        self.hi_free = np.array([task.force_limit, D * task.speed_limit])
        self.lo = np.array([-np.inf, -D * task.speed_limit])
        goal = self.top + task.goal_depth * a
        self.target = np.concatenate([goal - self.tip0, np.zeros(3), goal - self.r0, np.zeros(3)])
        wp, wv = task.position_weight, task.velocity_weight
        # the tip's position costs only along the hole: sideways the chamfer and the bore put it
        # where the true hole is, and a cost there would make the reference push against them
        Q = np.diag([0.0] * 3 + [wv] * 3 + [wp] * 3 + [wv] * 3)
        Q[:3, :3] = wp * np.outer(a, a)
        amax = task.acceleration_limit
        self.mpc = LinearMPC(self.stage, np.eye(12), np.zeros((12, 3)), np.zeros(12), Q,
                             task.acceleration_weight * np.eye(3), task.horizon, u_min=np.full(3, -amax),
                             u_max=np.full(3, amax), H=H, h=self.h, lo=self.lo, hi=self.hi_free,
                             rho_l=task.limit_penalty, rho_q=0.01 * task.limit_penalty, eps=task.tolerance,
                             polish=task.polish, max_iter=task.max_iterations, modes=task.modes,
                             alpha=task.relaxation, solver=task.solver)
        if task.modes > 1:  # both modes' solvers set up before the first sample
            self.mpc.prepare([self.blocked] * task.horizon)
        self.H = H
        self._plan: Optional[MpcSolution] = None

    @staticmethod
    def _blocked(free: AffineStage, a: np.ndarray) -> AffineStage:
        """The free stage with the tip's motion along ``a`` frozen (hybrid BLOCKED stage)."""
        P = np.eye(3) - np.outer(a, a)
        A, B = free.A.copy(), free.B.copy()
        A[:3], A[3:6], B[:3], B[3:6] = P @ A[:3], P @ A[3:6], P @ B[:3], P @ B[3:6]
        A[:3, :3] += np.outer(a, a)
        return AffineStage(A, B, free.e)

    def state(self, tip: Sequence[float], tip_velocity: Sequence[float], r: Sequence[float],
              rd: Sequence[float]) -> np.ndarray:
        """X from the measured tip and its velocity and the reference the MPC holds (absolute)."""
        return np.concatenate([np.asarray(tip, float) - self.tip0, np.asarray(tip_velocity, float),
                               np.asarray(r, float) - self.r0, np.asarray(rd, float)])

    def depth(self, X: np.ndarray) -> np.ndarray:
        """The tip's depth below the nominal hole top, for state(s) X (rows)."""
        return (np.atleast_2d(X)[:, :3] + self.tip0 - self.top) @ self.into

    def axial_force(self, X: np.ndarray) -> float:
        """F_ax of state X: the impedance's push if the tip were blocked (N)."""
        return float(self.H[0] @ X + self.h[0])

    def planned_force(self, plan: MpcSolution) -> float:
        """The largest F_ax the plan predicts at stages 1..N: what force_limit bounds (N)."""
        return float(np.max(plan.x[1:] @ self.H[0]) + self.h[0])

    def speed_limits(self, depths: np.ndarray) -> np.ndarray:
        """The speed into the hole allowed at each depth (m/s)."""
        t = self.task
        above, below = t.contact_zone
        bore = np.where(depths < t.bottom_depth - above, t.bore_speed, t.bottom_speed)
        return np.where(depths < -above, t.speed_limit, np.where(depths < below, t.contact_speed, bore))

    def step(self, tip: Sequence[float], tip_velocity: Sequence[float], r: Sequence[float],
             rd: Sequence[float], push_back: float = 0.0) -> tuple[np.ndarray, MpcSolution]:
        """One sample: the reference acceleration to hold, and the plan. ``push_back``: the measured
        contact force on the peg along the hole, outwards (N)."""
        X = self.state(tip, tip_velocity, r, rd)
        N = self.task.horizon
        # stage k's depth: the previous plan's prediction for it (none yet: today's depth)
        predicted = np.vstack([self._plan.x[2:], self._plan.x[-1:]]) if self._plan is not None \
            else np.repeat(X[None, :], N, axis=0)
        depths = self.depth(predicted)
        hi = np.repeat(self.hi_free[None, :], N, axis=0)
        hi[:, 1] = self.task.axial_damping * self.speed_limits(depths)
        blocked = push_back >= self.task.contact_force
        if blocked:  # the tip is not moving: the speed bound paces only the push's growth
            hi[:, 1] = self.task.axial_damping * self.task.contact_speed
        plan = self.mpc.solve(X, self.target, hi=hi, stages=[self.blocked if blocked else self.stage] * N)
        self._plan = plan
        amax = self.task.acceleration_limit
        return np.clip(plan.u0, -amax, amax), plan
