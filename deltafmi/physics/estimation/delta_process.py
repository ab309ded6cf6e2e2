"""The delta robot's DAE as an estimator's process model, in the joint coordinates with the loops.

Why joint coordinates (18 states [q; v]) and not the 3-DOF task space: the repo has the exact
partial derivatives of the Baumgarte-stabilised DAE in these coordinates
(:func:`deltafmi.physics.delta.jacobian.plant_jacobian`), the measured servo angles are three of
the states (a linear measurement), and the contact force enters as the DAE's wrist force f, whose
column of the Jacobian is exact too. A task-space model would need third derivatives of the
arms' kinematics that the repo does not have. The price is redundancy: the state lives on the
6-dimensional manifold h(q) = 0, H(q) v = 0. The filter keeps its covariance on the manifold's
tangent space (every noise enters through the tangent basis dq/dz of :func:`tangent_basis`; the
linearised flow of the DAE maps tangent vectors to tangent vectors, and the off-manifold modes,
never excited, decay at the Baumgarte pole) and projects its state back onto the manifold after
every step and update (:func:`deltafmi.physics.delta.project_to_constraints`).

Continuous model, inputs held over the sample period T (the controller's zero-order hold):

    q' = v,   v' = a(q, v, u, f)   (accelerations of deltafmi.physics.delta.dynamics),

with the wrist force f a state of the estimator (constant over a period).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..delta.dynamics import project_to_constraints, state_derivative
from ..delta.jacobian import plant_jacobian
from ..delta.kinematics import arm_jacobian
from ..delta.params import ARM_ROTATIONS, DeltaParams

__all__ = ["arm_jacobian_rate", "arm_jacobians", "wrist_jacobians", "tangent_basis", "propagate", "process_jacobian",
           "process_linearization"]

ArrayLike = Sequence[float] | np.ndarray


def arm_jacobian_rate(p: DeltaParams, qi: ArrayLike, vi: ArrayLike) -> np.ndarray:
    """d/dt dpsi/dq_i = sum_j d(dpsi/dq_i)/dq_ij v_ij of one arm (3, 3), in the arm's frame.

    Differentiating :func:`~deltafmi.physics.delta.kinematics.arm_jacobian` entry by entry;
    its product with v_i is arm_bias. By the symmetry of second derivatives it is also
    d(J_i(q_i) v_i)/dq_i, the derivative of the arm's wrist velocity with the angles.
    """
    q1, q2, q3 = (float(x) for x in qi)
    v1, v2, v3 = (float(x) for x in vi)
    s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                              math.sin(q3), math.cos(q3))
    l1, l2 = p.l1, p.l2
    return np.array([
        [0.0, l2 * (c2 * c3 * v3 - s2 * s3 * v2), l2 * (c2 * c3 * v2 - s2 * s3 * v3)],
        [-l1 * c1 * v1, -l2 * c2 * v2, 0.0],
        [-l1 * s1 * v1, -l2 * (s2 * c3 * v2 + c2 * s3 * v3), -l2 * (c2 * s3 * v2 + s2 * c3 * v3)],
    ])


def arm_jacobians(p: DeltaParams, q: ArrayLike) -> np.ndarray:
    """R_i dpsi/dq(q_i) of the three arms (3, 3, 3): each arm's wrist point against its angles,
    world frame (what :func:`wrist_jacobians` and :func:`tangent_basis` are made of)."""
    q = np.asarray(q, float)
    return np.stack([rot @ arm_jacobian(p, q[3 * i:3 * i + 3]) for i, rot in enumerate(ARM_ROTATIONS)])


def wrist_jacobians(p: DeltaParams, q: ArrayLike, v: ArrayLike,
                    arms: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Jv = dz/dq and D = d(Jv v)/dq = dJv/dt (both (3, 9)), z the wrist (the mean of the arms'
    wrist points), from the arms' Jacobians (``arms``: :func:`arm_jacobians` at q, when the caller
    has them) and their rates (:func:`arm_jacobian_rate`)."""
    q, v = np.asarray(q, float), np.asarray(v, float)
    arms = arm_jacobians(p, q) if arms is None else arms
    Jv, D = np.empty((3, 9)), np.empty((3, 9))
    for i, rot in enumerate(ARM_ROTATIONS):
        arm = slice(3 * i, 3 * i + 3)
        Jv[:, arm] = arms[i] / 3.0
        D[:, arm] = rot @ arm_jacobian_rate(p, q[arm], v[arm]) / 3.0
    return Jv, D


def tangent_basis(p: DeltaParams, q: ArrayLike, arms: np.ndarray | None = None) -> np.ndarray:
    """dq/dz (9, 3): the joint motion that moves every arm's wrist point, hence the closed loop,
    by dz (arm i: (R_i dpsi/dq(q_i))^-1; ``arms``: :func:`arm_jacobians` at q, when the caller
    has them). Also dv/dzd at fixed q."""
    return np.linalg.inv(arm_jacobians(p, q) if arms is None else arms).reshape(9, 3)


def propagate(p: DeltaParams, q: ArrayLike, v: ArrayLike, u: ArrayLike, f: ArrayLike, T: float,
              pole: float = 5.0, substeps: int = 1, rate: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(q, v) after T under held u and f: classical Runge-Kutta (substeps steps of T / substeps)
    of the DAE, then projected onto the closed loops. ``rate``: the state derivative at (q, v),
    when the caller has it (:func:`process_linearization`), as the first stage."""
    x = np.concatenate([np.asarray(q, float), np.asarray(v, float)])
    u, f = list(map(float, u)), list(map(float, f))
    h = T / substeps
    for step in range(substeps):
        k1 = np.asarray(rate, float) if step == 0 and rate is not None else np.array(state_derivative(p, x, u, f, pole))
        k2 = np.array(state_derivative(p, x + 0.5 * h * k1, u, f, pole))
        k3 = np.array(state_derivative(p, x + 0.5 * h * k2, u, f, pole))
        k4 = np.array(state_derivative(p, x + h * k3, u, f, pole))
        x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return project_to_constraints(p, x[:9], x[9:])


def process_jacobian(p: DeltaParams, q: ArrayLike, v: ArrayLike, u: ArrayLike, f: ArrayLike,
                     pole: float = 5.0) -> np.ndarray:
    """d[q'; v'; f']/d[q; v; f] (21, 21), exact: [[A, B_f], [0, 0]] from plant_jacobian (the
    wrist force a random walk, f' = 0 but for noise)."""
    return process_linearization(p, q, v, u, f, pole)[0]


def process_linearization(p: DeltaParams, q: ArrayLike, v: ArrayLike, u: ArrayLike, f: ArrayLike,
                          pole: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """:func:`process_jacobian` and the state derivative [v; a] at the same point (18,), from one
    plant_jacobian (its accelerations are state_derivative's, to the bit)."""
    jac = plant_jacobian(p, q, v, u, f, pole)
    A = np.zeros((21, 21))
    A[:18, :18] = jac.A
    A[:18, 18:] = jac.dx[:, 21:24]
    return A, np.concatenate([np.asarray(v, float), jac.vdot])
