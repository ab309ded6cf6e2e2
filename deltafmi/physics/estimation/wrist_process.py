"""The 6-DOF delta + wrist plant as an estimator's process model, in its six independent coordinates.

Why not the plant's 24 joint states (as :mod:`.delta_process` keeps the delta's 18): the 6-DOF
plant has no exact Jacobian in the repo, so its columns come from differences, and in the reduced
state s = [z (plate centre, 3), qw (wrist joints, 3), zd (3), vw (3)] there are 12 of them instead
of 24, with no closed loops to keep the covariance on: every s is a state of the plant on its
loops, q = IK(z) (closed form) and v = T(q) zd with T = dq/dz (:func:`.delta_process.tangent_basis`).
The accelerations are the plant's own (:func:`deltafmi.physics.delta_wrist.dynamics.state_derivative`
at that state; on the loops the Baumgarte terms vanish and its 24-state solution stays there):

    s' = [zd, vw, zdd, qddw],   zdd = Jv vdot + D v   (plate acceleration, D = dJv/dt),

with the servo torques u, wrist torques tau, and the contact wrench W = [F (at the tool tip),
M (about the tip)] (world frame) as inputs. The accelerations are affine in W, so the columns
d s'/dW are exact differences a(W + e_i) - a(W) (Jacobian "by linearity"); the state columns are
forward differences (step sizes in :data:`STEPS`, relative error ~ step x curvature, below 1e-5).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..delta.kinematics import inverse_kinematics
from ..delta.params import DeltaParams
from ..delta_wrist.dynamics import state_derivative
from ..delta_wrist.params import WristMount
from ..wrist.kernels import WristConstants, cross, joint_axes, tip_position, tool_rotation
from .delta_process import tangent_basis, wrist_jacobians

__all__ = ["N_REDUCED", "STEPS", "full_state", "tool_pose", "derivative", "propagate", "process_jacobian"]

N_REDUCED = 12
#: forward-difference steps of the reduced state's columns: m, rad, m/s, rad/s
STEPS = np.array([1e-7] * 6 + [1e-6] * 6)

ArrayLike = Sequence[float] | np.ndarray


def full_state(p: DeltaParams, s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(x (24), T = dq/dz (9, 3)): the plant's state [q, qw, v, vw] on its loops for the reduced s."""
    s = np.asarray(s, float)
    q = inverse_kinematics(p, s[0:3])
    T = tangent_basis(p, q)
    return np.concatenate([q, s[3:6], T @ s[6:9], s[9:12]]), T


def tool_pose(w: WristConstants, m: WristMount, s: ArrayLike) -> tuple[tuple, tuple, tuple, tuple]:
    """(tip, R row-major, tip velocity, omega), world, as deltafmi.physics.peg.plant.tool_pose
    computes them from the full state: O = z + mount, tip = O + p(qw), omega = J_w vw,
    v_tip = zd + omega x p(qw)."""
    s = [float(c) for c in s]
    qw = (s[3], s[4], s[5])
    rel = tip_position(w, qw)
    a1, a2, a3 = joint_axes(qw)
    vw = s[9:12]
    omega = tuple(a1[i] * vw[0] + a2[i] * vw[1] + a3[i] * vw[2] for i in range(3))
    spin = cross(omega, rel)
    tip = (s[0] + m.x + rel[0], s[1] + m.y + rel[1], s[2] + m.z + rel[2])
    return tip, tool_rotation(qw), (s[6] + spin[0], s[7] + spin[1], s[8] + spin[2]), omega


def _accelerations(p: DeltaParams, w: WristConstants, m: WristMount, x: np.ndarray, u: list, tau: list,
                   W: np.ndarray, pole: float) -> np.ndarray:
    """[zdd, qddw] of the plant at its full state x on the loops under (u, tau, W)."""
    xdot = np.array(state_derivative(p, w, m, x, u, tau, list(W[:3]), list(W[3:]), pole))
    Jv, D = wrist_jacobians(p, x[:9], x[12:21])
    return np.concatenate([Jv @ xdot[12:21] + D @ x[12:21], xdot[21:24]])


def derivative(p: DeltaParams, w: WristConstants, m: WristMount, s: ArrayLike, u: ArrayLike, tau: ArrayLike,
               W: ArrayLike, pole: float = 5.0) -> np.ndarray:
    """s' (12) of the module docstring under servo torques u, wrist torques tau (N m) and the
    contact wrench W (6: force at the tip N, moment about it N m, world)."""
    s = np.asarray(s, float)
    x, _ = full_state(p, s)
    acc = _accelerations(p, w, m, x, list(map(float, u)), list(map(float, tau)), np.asarray(W, float), pole)
    return np.concatenate([s[6:12], acc])


def propagate(p: DeltaParams, w: WristConstants, m: WristMount, s: ArrayLike, u: ArrayLike, tau: ArrayLike,
              W: ArrayLike, T: float, pole: float = 5.0, substeps: int = 1) -> np.ndarray:
    """s after T with u, tau and W held: classical Runge-Kutta, substeps steps of T / substeps."""
    s = np.asarray(s, float)
    h = T / substeps
    for _ in range(substeps):
        k1 = derivative(p, w, m, s, u, tau, W, pole)
        k2 = derivative(p, w, m, s + 0.5 * h * k1, u, tau, W, pole)
        k3 = derivative(p, w, m, s + 0.5 * h * k2, u, tau, W, pole)
        k4 = derivative(p, w, m, s + h * k3, u, tau, W, pole)
        s = s + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return s


def process_jacobian(p: DeltaParams, w: WristConstants, m: WristMount, s: ArrayLike, u: ArrayLike,
                     tau: ArrayLike, W: ArrayLike, pole: float = 5.0, columns: Sequence[int] | None = None,
                     out: np.ndarray | None = None) -> np.ndarray:
    """d s'/d[s, W] (12, 18): state columns by forward differences (positions through the inverse
    kinematics, rates through v = T zd at fixed q), wrench columns exact by linearity. With
    ``columns`` only those are evaluated, into ``out`` (the other columns keep its values)."""
    s, W = np.asarray(s, float), np.asarray(W, float)
    ul, tl = list(map(float, u)), list(map(float, tau))
    x0, T = full_state(p, s)
    a0 = _accelerations(p, w, m, x0, ul, tl, W, pole)
    J = np.zeros((N_REDUCED, 18)) if out is None else out
    J[0:6, 6:12] = np.eye(6)
    for k in range(18) if columns is None else columns:
        if k >= N_REDUCED:
            J[6:12, k] = _accelerations(p, w, m, x0, ul, tl, W + np.eye(6)[k - N_REDUCED], pole) - a0
            continue
        h = STEPS[k]
        if k < 3:
            ds = s.copy()
            ds[k] += h
            x, _ = full_state(p, ds)
        else:
            x = x0.copy()
            if k < 6:
                x[6 + k] += h  # qw
            elif k < 9:
                x[12:21] += h * T[:, k - 6]  # zd through v = T zd
            else:
                x[12 + k] += h  # vw
        J[6:12, k] = (_accelerations(p, w, m, x, ul, tl, W, pole) - a0) / h
    return J
