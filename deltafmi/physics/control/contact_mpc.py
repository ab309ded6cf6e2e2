"""A hybrid linear MPC of a mechanical system whose tool presses on a plane (free and contact modes).

Built from one continuous linearization (``deltafmi linearize -o``, a
:class:`~deltafmi.master.linearize.linear_model.LinearModel`) taken in free space near the contact
point, with inputs: the actuator efforts (``control``) and an external force on the tool
(``force``), and outputs: measurements that determine the state (``measured``), the tool's position
and velocity (``position``, ``velocity``). From it:

- the controllable subspace of (A, [B_u B_f]) (:func:`.models.controllable_subspace`): the motion
  on the constraint manifold of a DAE linearized with its Baumgarte modes; its state x is the
  measurements' deviation mapped back, x = (C_m Q)^-1 (y_m - y_m0) (no observer needed);
- two modes (the talk's "DAE model is almost linear"): FREE x' = A x + B_u u, and CONTACT with
  the force input closed by the contact spring-damper, f = n fn, fn = -K gap - D n.v
  (:func:`.models.spring_contact`), an affine model; both discretised exactly (zero-order hold);
- each stage of the horizon takes the mode of its predicted state (gap < 0: CONTACT), from the
  previous sample's plan: a time-varying linear MPC along the predicted mode sequence;
- costs: the tool's position and velocity against the reference (previewed along rd), the
  contact force against the commanded force (CONTACT stages only), the efforts' deviation from
  the linearization's (holding) efforts; limits: the efforts' box and fn <= force_limit, soft, at
  every stage. In FREE stages fn is the force the state would meet if it were in contact, so the
  limit also caps the speed at which the tool may arrive (damping x speed <= force_limit);
- offset-free (``disturbance_gain`` > 0): a constant effort disturbance d (an unknown payload, a
  gravity-torque error) in every prediction, estimated from what the last one missed,
  d <- d + gain B^+ (x - x_predicted), with -d as the efforts' reference (the effort that holds it).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from .models import controllable_subspace, spring_contact, zoh
from .mpc import LinearMPC, MpcSolution

__all__ = ["PlaneContactMpc", "PressTask", "pick"]


def pick(names: Sequence[str], wanted: Sequence[str], what: str) -> list[int]:
    """Indices of ``wanted`` in ``names``; an array name (``u``) stands for its elements u[1], u[2], ..."""
    names = list(names)
    out: list[int] = []
    for name in wanted:
        if name in names:
            out.append(names.index(name))
            continue
        elements = [i for i, n in enumerate(names) if n.startswith(f"{name}[")]
        if not elements:
            raise ValueError(f"the linear model has no {what} '{name}' (its {what}s: {', '.join(names)})")
        out.extend(elements)
    return out


@dataclass
class PressTask:
    """What the MPC knows of the task: the plane, the tool, the contact law, costs and limits."""

    tool: Sequence[float]            # tool point relative to the position output (m)
    plane_point: Sequence[float]     # a point of the plane (m)
    normal: Sequence[float]          # plane normal, towards the robot
    stiffness: float                 # contact spring (N/m)
    damping: float                   # contact damper (N s/m)
    position_weight: float           # 1/m^2
    velocity_weight: float           # 1/(m/s)^2
    force_weight: float              # 1/N^2, CONTACT stages
    effort_weight: float             # 1/(effort unit)^2, on the deviation from the holding effort
    effort_min: Sequence[float]      # absolute effort bounds
    effort_max: Sequence[float]
    force_limit: float               # N, on fn
    sample_period: float             # s
    horizon: int                     # samples
    limit_penalty: float = 10.0      # cost per N of planned excess over force_limit (exact penalty)
    tolerance: float = 1e-4          # OSQP's absolute and relative tolerance
    disturbance_gain: float = 0.0    # per sample, of the input-disturbance estimate (0: none)
    max_iterations: int = 4000       # OSQP's iteration cap per sample (a real-time bound)


class PlaneContactMpc:
    """The hybrid MPC described in the module docstring, for one linearization and task."""

    def __init__(self, model, task: PressTask, control: str = "u", force: str = "f",
                 measured: Sequence[str] = ("y", "yd"), position: str = "z", velocity: str = "zd") -> None:
        if model.discrete:
            raise ValueError("the MPC needs a continuous linearization (deltafmi linearize of an FMU), "
                             f"not a discrete one (Ts = {model.sample_time:g} s)")
        iu, i_f = pick(model.inputs, [control], "input"), pick(model.inputs, [force], "input")
        im, ip = pick(model.outputs, measured, "output"), pick(model.outputs, [position], "output")
        iv = pick(model.outputs, [velocity], "output")
        if len(i_f) != len(ip) or len(iv) != len(ip):
            raise ValueError(f"'{force}', '{position}' and '{velocity}' must have the same size "
                             f"({len(i_f)}, {len(ip)}, {len(iv)})")
        A, B, C = np.asarray(model.A, float), np.asarray(model.B, float), np.asarray(model.C, float)
        basis = controllable_subspace(A, B[:, iu + i_f])
        self.basis = basis
        Ar, Bu, Bf = basis.T @ A @ basis, basis.T @ B[:, iu], basis.T @ B[:, i_f]
        Cm, Cp, Cv = C[im] @ basis, C[ip] @ basis, C[iv] @ basis
        if Cm.shape[0] != Cm.shape[1] or np.linalg.cond(Cm) > 1e8:
            raise ValueError(f"the measured outputs ({', '.join(measured)}: {Cm.shape[0]}) do not determine the "
                             f"{Cm.shape[1]} controllable states of the linear model")
        self.task = task
        n = np.asarray(task.normal, float)
        n = n / np.linalg.norm(n)
        self.normal = n
        p0 = np.asarray(model.y0, float)[ip]
        gap0 = float(n @ (p0 + np.asarray(task.tool, float) - np.asarray(task.plane_point, float)))
        Ac, ec, Hf, hf = spring_contact(Ar, Bf, n, Cp, Cv, gap0, task.stiffness, task.damping)
        Ts = task.sample_period
        self.free, self.contact = zoh(Ar, Bu, Ts), zoh(Ac, Bu, Ts, ec)
        self.measure = np.linalg.inv(Cm)
        self.y_m0 = np.asarray(model.y0, float)[im]
        self.u0 = np.asarray(model.u0, float)[iu]
        self.Cp, self.gap0, self.p0 = Cp, gap0, p0
        self.Hf, self.hf = Hf, hf
        dim = len(ip)
        C_cost = np.vstack([Cp, Cv, Hf[None, :]])
        g = np.concatenate([p0, np.zeros(dim), [hf]])
        base = np.concatenate([np.full(dim, task.position_weight), np.full(dim, task.velocity_weight)])
        self.Q_free, self.Q_contact = np.diag([*base, 0.0]), np.diag([*base, task.force_weight])
        lo, hi = np.asarray(task.effort_min, float) - self.u0, np.asarray(task.effort_max, float) - self.u0
        self.mpc = LinearMPC(self.free, C_cost, np.zeros((C_cost.shape[0], len(iu))), g, self.Q_free,
                             task.effort_weight * np.eye(len(iu)), task.horizon, u_min=lo, u_max=hi,
                             H=Hf[None, :], h=np.array([hf]), hi=np.array([task.force_limit]),
                             rho_l=task.limit_penalty,
                             rho_q=0.01 * task.limit_penalty, eps=task.tolerance, polish=False,
                             max_iter=task.max_iterations)
        self._plan: Optional[MpcSolution] = None
        self._B_pinv = np.linalg.pinv(self.free.B)
        self.effort_disturbance = np.zeros(len(iu))  # estimated, in effort units

    def state(self, measured: Sequence[float]) -> np.ndarray:
        """The model's state from the measurements (absolute values)."""
        return self.measure @ (np.asarray(measured, float) - self.y_m0)

    def gap(self, x: np.ndarray) -> np.ndarray:
        """Predicted gap(s) of the tool from the plane for state(s) x (rows)."""
        return np.atleast_2d(x) @ (self.Cp.T @ self.normal) + self.gap0

    def force(self, x: np.ndarray) -> float:
        """The contact law's force for state x (meaningful in contact)."""
        return float(self.Hf @ x + self.hf)

    def step(self, measured: Sequence[float], r: Sequence[float], rd: Sequence[float],
             force: float) -> tuple[np.ndarray, MpcSolution, bool]:
        """One sample: the efforts to apply (absolute), the plan, and whether the tool is in contact now."""
        x = self.state(measured)
        N, Ts = self.task.horizon, self.task.sample_period
        if self._plan is not None and self.task.disturbance_gain > 0.0:
            # the input disturbance that explains what the last prediction missed (least squares)
            self.effort_disturbance += self.task.disturbance_gain * (self._B_pinv @ (x - self._plan.x[1]))
        # the mode of stage k from the state the previous plan predicted for it (this sample's
        # state for stage 0; no plan yet: this sample's mode throughout)
        predicted = np.vstack([x, self._plan.x[2:], self._plan.x[-1:]]) if self._plan is not None \
            else np.repeat(x[None, :], N + 1, axis=0)
        touching = self.gap(predicted) < 0.0
        stages = [self.contact if c else self.free for c in touching[:N]]
        weights = [self.Q_contact if c else self.Q_free for c in touching]
        times = Ts * np.arange(N + 1)[:, None]
        ref = np.hstack([np.asarray(r, float) + times * np.asarray(rd, float),
                         np.broadcast_to(np.asarray(rd, float), (N + 1, len(rd))), np.full((N + 1, 1), force)])
        # the disturbance in every prediction, and the effort that cancels it as the efforts' reference
        plan = self.mpc.solve(x, ref, ur=-self.effort_disturbance, stages=stages, weights=weights,
                              disturbance=self.free.B @ self.effort_disturbance)
        self._plan = plan
        # the first move within the effort box: OSQP meets bounds to its tolerance, an actuator exactly
        u = np.clip(self.u0 + plan.u0, self.task.effort_min, self.task.effort_max)
        return u, plan, bool(touching[0])
