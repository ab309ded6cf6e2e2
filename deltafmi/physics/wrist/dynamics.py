"""Spherical-wrist dynamics in joint coordinates, base fixed (or translating, see base_accel).

The three bodies (link i + its direct-drive rotor, the tool on link 3; see
:func:`.params.link_inertias`) all turn about the fixed centre O, so with body i's inertia
about O in the world I_i = R_i I_i^O R_i^T, its first moment s_i = R_i m_i c_i and
omega_i = J_i qd, J_i = [a_1 .. a_i 0 ..]:

    T = 1/2 sum_i omega_i^T I_i omega_i = 1/2 qd^T M(q) qd,   V = -sum_i s_i . g_eff
    M_jk = a_j^T (sum_{i >= max(j,k)} I_i) a_k                (composite inertias about O)
    M(q) qdd + C(q, qd) qd + g(q) + D qd = tau

with g_eff = (0, 0, -g) - base_accel: a translating base (the delta's plate) acts on the wrist
as a change of gravity. Two routes to the velocity terms, which the tests compare:

- coriolis(): Euler's law about O projected on the axes (Newton-Euler),
  h_j = a_j . sum_{i >= j} (I_i Jd_i qd + omega_i x I_i omega_i),  Jd_i qd = sum_{j<=i} (omega_{j-1} x a_j) qd_j;
- coriolis_matrix(): Christoffel symbols of M,
  C_ij = sum_k 1/2 (dM_ij/dq_k + dM_ik/dq_j - dM_jk/dq_i) qd_k, so that Mdot - 2C is skew
  (Spong, Hutchinson & Vidyasagar, Robot Modeling and Control, sec. 7.3), with
  dR_i/dq_k = [a_k]x R_i (k <= i) and da_j/dq_k = a_k x a_j (k < j).

Gravity: g_j = -a_j . sum_{i >= j} s_i x g_eff = -(J_s^T g_eff)_j, J_s = sum_i -[s_i]x J_i the
Jacobian of the total first moment (mass times centre of mass).

The wrench on the base (base_wrench) is the reaction of Newton's and Euler's laws for the whole
wrist: force m g_eff - sum_i s_i'' and torque about O -(sum_i dL_i/dt - s_i x g_eff). With the
base's orientation held (the delta's plate only translates) the total angular momentum about O,
L = sum_i I_i omega_i, is conserved only along a_1 (tau_1 = 0); its other components change by
the bearing torque, which vanishes when the links and rotors are massless (a free tool).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .kinematics import axes_of, link_rotations, skew
from .params import WristParams, link_inertias

__all__ = ["WristState", "wrist_state", "mass_matrix", "mass_matrix_derivatives", "coriolis",
           "coriolis_matrix", "gravity", "accelerations", "state_derivative", "kinetic_energy",
           "potential_energy", "energy", "angular_momentum", "first_moment_jacobian", "base_wrench"]

ArrayLike = Sequence[float] | np.ndarray


class WristState:
    """World-frame quantities of the three bodies at one (q, qd), shared by the functions below.

    Attributes: axes (3, 3) columns a_j; inertias (3, 3, 3) I_i about O; moments (3, 3) rows
    s_i = m_i R_i c_i; omegas (3, 3) rows omega_i; masses (3,); composite (3, 3, 3) sum_{i>=k} I_i.
    """

    __slots__ = ("axes", "inertias", "moments", "omegas", "masses", "composite")

    def __init__(self, p: WristParams, q: ArrayLike, qd: ArrayLike) -> None:
        masses, moments, inertias = link_inertias(p)
        rotations = link_rotations(q)
        self.axes = axes_of(rotations)
        self.masses = masses
        self.inertias = np.array([R @ I @ R.T for R, I in zip(rotations, inertias)])
        self.moments = np.array([R @ s for R, s in zip(rotations, moments)])
        self.omegas = np.cumsum(self.axes * np.asarray(qd, dtype=float), axis=1).T
        self.composite = np.cumsum(self.inertias[::-1], axis=0)[::-1]


def wrist_state(p: WristParams, q: ArrayLike, qd: ArrayLike | None = None) -> WristState:
    """The shared world-frame quantities at (q, qd) (qd defaults to rest)."""
    return WristState(p, q, np.zeros(3) if qd is None else qd)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross(a, b)`` of vectors along the last axis (3), broadcast: the same products and
    differences in the same order, so the same bits, without np.cross's axis handling, which costs
    several times the arithmetic on arrays this small."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=-1)


def _g_eff(p: WristParams, base_accel: ArrayLike | None) -> np.ndarray:
    g = np.array([0.0, 0.0, -p.g])
    return g if base_accel is None else g - np.asarray(base_accel, dtype=float)


def _mass_matrix(st: WristState) -> np.ndarray:
    a = st.axes
    M = np.empty((3, 3))
    for j in range(3):
        for k in range(j, 3):
            M[j, k] = M[k, j] = a[:, j] @ st.composite[k] @ a[:, k]
    return M


def mass_matrix(p: WristParams, q: ArrayLike) -> np.ndarray:
    """M(q), (3, 3) symmetric positive definite for positive rotor inertias (kg m^2)."""
    return _mass_matrix(wrist_state(p, q))


def mass_matrix_derivatives(p: WristParams, q: ArrayLike) -> np.ndarray:
    """dM/dq_k stacked on k, (3, 3, 3) (kg m^2/rad), from dR_i/dq_k = [a_k]x R_i (k <= i)."""
    st = wrist_state(p, q)
    a = st.axes
    dM = np.zeros((3, 3, 3))
    for k in range(3):
        ak = skew(a[:, k])
        for i in range(k, 3):  # bodies moved by joint k
            J = np.zeros((3, 3))
            J[:, :i + 1] = a[:, :i + 1]
            dJ = np.zeros((3, 3))
            dJ[:, k + 1:i + 1] = ak @ a[:, k + 1:i + 1]
            dI = ak @ st.inertias[i] - st.inertias[i] @ ak
            term = dJ.T @ st.inertias[i] @ J
            dM[k] += term + term.T + J.T @ dI @ J
    return dM


def _velocity_product(st: WristState) -> np.ndarray:
    """Rows Jd_i qd = sum_{j<=i} omega_{j-1} x a_j qd_j: body i's angular acceleration at qdd = 0."""
    out = np.zeros((3, 3))
    for i in range(1, 3):
        out[i] = out[i - 1] + _cross(st.omegas[i - 1], st.omegas[i] - st.omegas[i - 1])
    return out


def _bias_torques(st: WristState) -> np.ndarray:
    """Per body, Euler's law about O at qdd = 0: I_i Jd_i qd + omega_i x I_i omega_i, rows."""
    spin = np.einsum("ijk,ik->ij", st.inertias, st.omegas)
    return np.einsum("ijk,ik->ij", st.inertias, _velocity_product(st)) + _cross(st.omegas, spin)


def _project(axes: np.ndarray, per_body: np.ndarray) -> np.ndarray:
    """tau_j = a_j . sum_{i >= j} per_body_i (the torque joint j transmits to the bodies beyond)."""
    tail = np.cumsum(per_body[::-1], axis=0)[::-1]
    return np.einsum("ij,ji->i", tail, axes)


def coriolis(p: WristParams, q: ArrayLike, qd: ArrayLike) -> np.ndarray:
    """Centripetal and Coriolis torques C(q, qd) qd (N m) by Euler's law about O."""
    st = WristState(p, q, qd)
    return _project(st.axes, _bias_torques(st))


def coriolis_matrix(p: WristParams, q: ArrayLike, qd: ArrayLike) -> np.ndarray:
    """C(q, qd) from the Christoffel symbols of M (Mdot - 2C skew-symmetric), (3, 3)."""
    dM = mass_matrix_derivatives(p, q)
    v = np.asarray(qd, dtype=float)
    # Gamma_ijk = 1/2 (dM[k][i,j] + dM[j][i,k] - dM[i][j,k])
    gamma = 0.5 * (np.transpose(dM, (1, 2, 0)) + np.transpose(dM, (1, 0, 2)) - dM)
    return gamma @ v


def _gravity(st: WristState, g_eff: np.ndarray) -> np.ndarray:
    return -_project(st.axes, _cross(st.moments, g_eff))


def gravity(p: WristParams, q: ArrayLike, base_accel: ArrayLike | None = None) -> np.ndarray:
    """g(q) = dV/dq (N m), V = -sum_i s_i . g_eff, g_eff = (0, 0, -g) - base_accel."""
    return _gravity(wrist_state(p, q), _g_eff(p, base_accel))


def _free_torques(p: WristParams, st: WristState, qd: ArrayLike, tau: ArrayLike) -> np.ndarray:
    """tau - C qd - D qd: the joint torques left for inertia and gravity."""
    return (np.asarray(tau, dtype=float) - _project(st.axes, _bias_torques(st))
            - p.damping * np.asarray(qd, dtype=float))


def _moment_acceleration(st: WristState, omegad: np.ndarray) -> np.ndarray:
    """sum_i s_i'' = sum_i omegad_i x s_i + omega_i x (omega_i x s_i) for body rates omegad (rows)."""
    return (_cross(omegad, st.moments) + _cross(st.omegas, _cross(st.omegas, st.moments))).sum(axis=0)


def _accelerations(p: WristParams, st: WristState, qd: ArrayLike, tau: ArrayLike,
                   g_eff: np.ndarray) -> np.ndarray:
    return np.linalg.solve(_mass_matrix(st), _free_torques(p, st, qd, tau) - _gravity(st, g_eff))


def accelerations(p: WristParams, q: ArrayLike, qd: ArrayLike, tau: ArrayLike,
                  base_accel: ArrayLike | None = None) -> np.ndarray:
    """qdd = M^-1 (tau - C qd - g - D qd) (rad/s^2); base_accel: the base's acceleration (m/s^2)."""
    return _accelerations(p, WristState(p, q, qd), qd, tau, _g_eff(p, base_accel))


def state_derivative(p: WristParams, x: ArrayLike, tau: ArrayLike,
                     base_accel: ArrayLike | None = None) -> np.ndarray:
    """d/dt [q; qd] = [qd; qdd] for the 6-vector x = [q; qd]."""
    x = np.asarray(x, dtype=float)
    return np.concatenate((x[3:], accelerations(p, x[:3], x[3:], tau, base_accel)))


def kinetic_energy(p: WristParams, q: ArrayLike, qd: ArrayLike) -> float:
    """T = 1/2 sum_i omega_i^T I_i omega_i (J)."""
    st = WristState(p, q, qd)
    return 0.5 * float(np.einsum("ij,ijk,ik->", st.omegas, st.inertias, st.omegas))


def potential_energy(p: WristParams, q: ArrayLike) -> float:
    """V = g sum_i m_i z_i (J), zero when every centre of mass is at the height of O."""
    return p.g * float(np.sum(wrist_state(p, q).moments[:, 2]))


def energy(p: WristParams, q: ArrayLike, qd: ArrayLike) -> float:
    """T + V (J)."""
    return kinetic_energy(p, q, qd) + potential_energy(p, q)


def angular_momentum(p: WristParams, q: ArrayLike, qd: ArrayLike) -> np.ndarray:
    """Total angular momentum about O, world frame: L = sum_i I_i omega_i (kg m^2/s).

    L . a_1 = dT/dqd_1, the momentum conjugate to q1."""
    st = WristState(p, q, qd)
    return np.einsum("ijk,ik->j", st.inertias, st.omegas)


def first_moment_jacobian(p: WristParams, q: ArrayLike) -> np.ndarray:
    """J_s with d/dt sum_i m_i c_i = J_s qd (kg m/rad): column j is a_j x sum_{i >= j} s_i."""
    st = wrist_state(p, q)
    tail = np.cumsum(st.moments[::-1], axis=0)[::-1]
    return _cross(st.axes.T, tail).T


def base_wrench(p: WristParams, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike,
                base_accel: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Force (N) and torque about O (N m) that the wrist exerts on its base, world frame.

    force = sum_i m_i g_eff - sum_i s_i'', s_i'' = omegad_i x s_i + omega_i x (omega_i x s_i);
    torque = -sum_i (I_i omegad_i + omega_i x I_i omega_i - s_i x g_eff), whose a_1 component is
    -tau_1 (the motor's reaction) and the rest the bearing's. Gravity and the base acceleration
    enter through g_eff = (0, 0, -g) - base_accel; qdd must be the wrist's actual accelerations.
    """
    st = WristState(p, q, qd)
    g_eff = _g_eff(p, base_accel)
    # omega_i' = J_i qdd + Jd_i qd
    omegad = np.cumsum(st.axes * np.asarray(qdd, dtype=float), axis=1).T + _velocity_product(st)
    force = st.masses.sum() * g_eff - _moment_acceleration(st, omegad)
    spin = np.einsum("ijk,ik->ij", st.inertias, st.omegas)
    dL = np.einsum("ijk,ik->ij", st.inertias, omegad) + _cross(st.omegas, spin)
    torque = -(dL - _cross(st.moments, g_eff)).sum(axis=0)
    return force, torque
