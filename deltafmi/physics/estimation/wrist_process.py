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

from ..delta.params import DeltaParams
from ..delta_wrist.params import WristMount
from ..wrist.kernels import WristConstants
from . import peg_kernels

__all__ = ["N_REDUCED", "STEPS", "full_state", "tool_pose", "derivative", "propagate", "process_jacobian"]

N_REDUCED = 12
#: forward-difference steps of the reduced state's columns: m, rad, m/s, rad/s
STEPS = np.array([peg_kernels.POSITION_STEP] * 6 + [peg_kernels.RATE_STEP] * 6)

ArrayLike = Sequence[float] | np.ndarray


def _floats(v: ArrayLike) -> list[float]:
    return [float(c) for c in v]


def full_state(p: DeltaParams, s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(x (24), T = dq/dz (9, 3)): the plant's state [q, qw, v, vw] on its loops for the reduced s."""
    x, T = peg_kernels.full_state(p, _floats(s))
    return np.array(x), np.array(T).reshape(9, 3)


def tool_pose(w: WristConstants, m: WristMount, s: ArrayLike) -> tuple[tuple, tuple, tuple, tuple]:
    """(tip, R row-major, tip velocity, omega), world, as deltafmi.physics.peg.plant.tool_pose
    computes them from the full state: O = z + mount, tip = O + p(qw), omega = J_w vw,
    v_tip = zd + omega x p(qw)."""
    return peg_kernels.tool_pose(w, m, _floats(s))


def derivative(p: DeltaParams, w: WristConstants, m: WristMount, s: ArrayLike, u: ArrayLike, tau: ArrayLike,
               W: ArrayLike, pole: float = 5.0) -> np.ndarray:
    """s' (12) of the module docstring under servo torques u, wrist torques tau (N m) and the
    contact wrench W (6: force at the tip N, moment about it N m, world)."""
    return np.array(peg_kernels.reduced_derivative(p, w, m, _floats(s), _floats(u), _floats(tau), _floats(W),
                                                   float(pole)))


def propagate(p: DeltaParams, w: WristConstants, m: WristMount, s: ArrayLike, u: ArrayLike, tau: ArrayLike,
              W: ArrayLike, T: float, pole: float = 5.0, substeps: int = 1) -> np.ndarray:
    """s after T with u, tau and W held: classical Runge-Kutta, substeps steps of T / substeps."""
    out = peg_kernels.prediction(p, w, m, _floats(s), _floats(u), _floats(tau), _floats(W), float(pole), float(T),
                                 int(substeps), 0, 0)
    return np.array(out[:N_REDUCED])


def process_jacobian(p: DeltaParams, w: WristConstants, m: WristMount, s: ArrayLike, u: ArrayLike,
                     tau: ArrayLike, W: ArrayLike, pole: float = 5.0, columns: Sequence[int] | None = None,
                     out: np.ndarray | None = None) -> np.ndarray:
    """d s'/d[s, W] (12, 18): state columns by forward differences (positions through the inverse
    kinematics, rates through v = T zd at fixed q), wrench columns exact by linearity. With
    ``columns`` only those are evaluated, into ``out`` (the other columns keep its values)."""
    args = (p, w, m, _floats(s), _floats(u), _floats(tau), _floats(W), float(pole))
    J = np.zeros((N_REDUCED, 18)) if out is None else out
    J[0:6, 6:12] = np.eye(6)
    if columns is None:
        J[6:12] = np.reshape(peg_kernels.process_columns(*args, 0, 18), (18, 6)).T
    for k in columns or ():
        J[6:12, k] = peg_kernels.process_columns(*args, int(k), 1)[6 * k:6 * k + 6]
    return J
