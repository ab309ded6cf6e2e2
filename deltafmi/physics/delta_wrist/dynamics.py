"""The 6-DOF plant: the delta robot carrying the spherical wrist, as float kernels (compiled to C).

State x = [q (9 delta joints, arm-major), qw (3 wrist joints), v (9), vw (3)], 24 floats. The
delta keeps its index-1 DAE (six loop closures h(q) = 0, multipliers lam, Baumgarte pole p:
hdd + 2 p hd + p^2 h = 0, :mod:`deltafmi.physics.delta.dynamics`); the wrist adds three
coordinates and no constraint. Its centre O = z + d moves with the plate (:mod:`.params`), so
O's acceleration is the plate's, zdd = Jv vdot + Jvd v (the mean of the arm ends' accelerations).

Inputs: servo torques u, wrist torques tau, a force f on the tool tip and a moment (couple) on the
tool, both world frame. A force f at the tip p (relative to O) is the force f at O plus the
moment p x f about O: on the wrist's joints it is the generalized force J_w^T (p x f) = J_p^T f
(J_p = -[p]x J_w), the moment adds J_w^T moment; the force at O passes through the three joints
(all axes meet there) to the plate, where it acts on the delta as f through Jv^T (as DeltaRobot's
input f); the moment's bearing reaction is held by the parallelograms and loads no servo. A force
at another point r of the tool is f at the tip plus the moment (r - O - p) x f.

Coupling (wrist/coupling.py). With the wrist's terms (wrist/kernels.py) M, h, J_s, b_s and
g_vec = (0, 0, -g), its joints obey M qddw + h + D vw + J_s^T zdd = tau_w + J_s^T g_vec
(tau_w = tau + J_p^T f + J_w^T moment), and it loads the plate with

    F = -Lambda zdd + f0,   Lambda = m 1 - J_s M^-1 J_s^T,
    f0 = Lambda g_vec - J_s M^-1 (tau_w - h - D vw) - b_s + f.

Lambda/3 joins each arm's end mass as the plate's (mp + payload)/3 does; f0 enters as the delta's
wrist force. Arm i's end then responds to a world force F_i (the loops' share) as

    Pdd_i = A_i + W_i (F_i - L Pdd_i)   =>   Pdd_i = K_i A_i + K_i W_i F_i,   K_i = (1 + W_i L)^-1,

with L = Lambda/3 and A_i, W_i = Ht_i m_i^-1 Ht_i^T the bare arm's (delta.dynamics._arm, with f0):
the arm's apparent mass m_i + Ht_i^T L Ht_i by the push-through identity, W_i' = K_i W_i symmetric
and regular through the stretched-arm singularity (W_i singular) since every eigenvalue of
W_i L is >= 0. The loop multipliers solve the delta's 6x6 Schur complement with W_i' and
b_i' = K_i A_i + 2p Pd_i + p^2 P_i, the joints take vdot_i = m_i^-1 (rhs_i + Ht_i^T (F_i - L Pdd_i)),
and then (no iteration: the same elimination run backwards)

    qddw = M^-1 (tau_w - h - D vw + J_s^T (g_vec - zdd)),   zdd = mean_i Pdd_i.

On the closed loops (h = 0, H v = 0) every arm end shares zdd and this is exact: it is the dense
12-coordinate Lagrange system with mass matrix [[M_d + m Jv^T Jv, Jv^T J_s], [J_s^T Jv, M]]
(tests/physics/test_delta_wrist_mechanics.py solves that KKT system). Off them (Baumgarte's drift) the
per-arm split differs from it by O(|h| + |hd|), like the plate's own split.

Energy (no damping, no inputs: conserved on the closed loops):
E = E_delta + 1/2 m |zd|^2 + zd . J_s vw + 1/2 vw^T M vw + g (m O_z + sum_i s_i,z), E_delta the
delta with its plate (delta.dynamics.energy), zero potential in the base plane z = 0.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple, Optional, Sequence

import numpy as np

from ..delta import dynamics as delta_dynamics
from ..delta.control_law import _inv3
from ..delta.dynamics import (F3, F6, F9, _arm, _arm_wrist, _arms_linearization, _as_list, _closure, _constants,
                              _loop_residuals, _schur_factor, _schur_solve, _sym3_inv, _wrist)
from ..delta.kinematics import ARM_COS_SIN, inverse_kinematics, joint_rates
from ..delta.params import DeltaParams
from ..wrist import kinematics as wrist_kinematics
from ..wrist.kernels import (WristConstants, WristTerms, cross, dot, gravity_torques, sym_apply, tip_position,
                             tool_rotation, wrist_terms)
from .params import WristMount

__all__ = ["WristLoad", "wrist_load", "state_derivative", "plant_outputs", "energy", "loop_residual",
           "project_to_constraints", "project_state", "start_state", "holding_torques", "N_STATES"]

ArrayLike = Sequence[float] | np.ndarray
N_STATES = 24
F24 = list[float]


class WristLoad(NamedTuple):
    """The wrist at one (qw, vw) with its inputs, eliminated onto the plate (module docstring)."""

    terms: WristTerms
    inverse_mass: F6  #: M^-1 (6 unique)
    apparent_mass: F6  #: Lambda (6 unique, kg)
    force: F3  #: f0 (N)
    free: F3  #: tau_w - h - D vw (N m)
    tip: F3  #: tool tip relative to O, world (m)


def wrist_load(w: WristConstants, qw: F3, vw: F3, tau: Sequence[float], f: Sequence[float],
               moment: Sequence[float]) -> WristLoad:
    """Lambda and f0 of the module docstring, with the wrist's terms and free joint torques."""
    t = wrist_terms(w, qw, vw)
    fr = t.frame
    tip = tip_position(w, qw)
    fl, ml, tl = _as_list(f), _as_list(moment), _as_list(tau)
    px_f = cross(tip, (fl[0], fl[1], fl[2]))
    couple = (px_f[0] + ml[0], px_f[1] + ml[1], px_f[2] + ml[2])  # J_p^T f + J_w^T moment = J_w^T couple
    d = w.damping
    free = (tl[0] + dot(fr.a1, couple) - t.bias[0] - d * vw[0], tl[1] + dot(fr.a2, couple) - t.bias[1] - d * vw[1],
            tl[2] + dot(fr.a3, couple) - t.bias[2] - d * vw[2])
    minv = _sym3_inv(t.mass[0], t.mass[1], t.mass[2], t.mass[3], t.mass[4], t.mass[5])
    js = t.js
    r0, r1, r2 = (js[0], js[1], js[2]), (js[3], js[4], js[5]), (js[6], js[7], js[8])  # rows of J_s
    y0, y1, y2 = sym_apply(minv, r0), sym_apply(minv, r1), sym_apply(minv, r2)  # M^-1 J_s^T, columns
    mass = w.m1 + w.m2 + w.m3
    lam = (mass - dot(r0, y0), -dot(r0, y1), -dot(r0, y2), mass - dot(r1, y1), -dot(r1, y2), mass - dot(r2, y2))
    a = sym_apply(minv, free)
    g = w.g
    f0 = (-g * lam[2] - dot(r0, a) - t.bs[0] + fl[0], -g * lam[4] - dot(r1, a) - t.bs[1] + fl[1],
          -g * lam[5] - dot(r2, a) - t.bs[2] + fl[2])
    return WristLoad(t, minv, lam, f0, free, tip)


def _loaded(W: F6, L: F6, A: F3) -> tuple[F6, F3]:
    """(W', K A) of an arm end carrying the apparent mass L: K = (1 + W L)^-1, W' = K W."""
    w11, w12, w13, w22, w23, w33 = W
    l11, l12, l13, l22, l23, l33 = L
    k = _inv3((1.0 + w11 * l11 + w12 * l12 + w13 * l13, w11 * l12 + w12 * l22 + w13 * l23,
               w11 * l13 + w12 * l23 + w13 * l33,
               w12 * l11 + w22 * l12 + w23 * l13, 1.0 + w12 * l12 + w22 * l22 + w23 * l23,
               w12 * l13 + w22 * l23 + w23 * l33,
               w13 * l11 + w23 * l12 + w33 * l13, w13 * l12 + w23 * l22 + w33 * l23,
               1.0 + w13 * l13 + w23 * l23 + w33 * l33))
    if k is None:
        raise ArithmeticError("the wrist's apparent mass made an arm's end response singular")
    kw = ((k[0] * w11 + k[1] * w12 + k[2] * w13, k[0] * w12 + k[1] * w22 + k[2] * w23,
           k[0] * w13 + k[1] * w23 + k[2] * w33),
          (k[3] * w11 + k[4] * w12 + k[5] * w13, k[3] * w12 + k[4] * w22 + k[5] * w23,
           k[3] * w13 + k[4] * w23 + k[5] * w33),
          (k[6] * w11 + k[7] * w12 + k[8] * w13, k[6] * w12 + k[7] * w22 + k[8] * w23,
           k[6] * w13 + k[7] * w23 + k[8] * w33))
    wp = (kw[0][0], 0.5 * (kw[0][1] + kw[1][0]), 0.5 * (kw[0][2] + kw[2][0]), kw[1][1],
          0.5 * (kw[1][2] + kw[2][1]), kw[2][2])
    ka = (k[0] * A[0] + k[1] * A[1] + k[2] * A[2], k[3] * A[0] + k[4] * A[1] + k[5] * A[2],
          k[6] * A[0] + k[7] * A[1] + k[8] * A[2])
    return wp, ka


def _third(m: F6) -> F6:
    return m[0] / 3.0, m[1] / 3.0, m[2] / 3.0, m[3] / 3.0, m[4] / 3.0, m[5] / 3.0


def _arm_load(arm: tuple, L: F6, pole: float) -> tuple[F3, F6, F3]:
    """(b', W', K A) of one arm (delta.dynamics._arm's result) carrying L at its end."""
    bb, W, P, Pd = arm[0], arm[1], arm[4], arm[5]
    tp, pp = 2.0 * pole, pole * pole
    c = (tp * Pd[0] + pp * P[0], tp * Pd[1] + pp * P[1], tp * Pd[2] + pp * P[2])
    wp, ka = _loaded(W, L, (bb[0] - c[0], bb[1] - c[1], bb[2] - c[2]))
    return (ka[0] + c[0], ka[1] + c[1], ka[2] + c[2]), wp, ka


def _arm_motion(arm: tuple, L: F6, wp: F6, ka: F3, F: F3) -> tuple[F3, F3]:
    """(vdot_i, Pdd_i) of one arm under the world force F at its end (module docstring)."""
    x, Y = arm[2], arm[3]
    pdd = _add3(ka, sym_apply(wp, F))
    lp = sym_apply(L, pdd)
    g = (F[0] - lp[0], F[1] - lp[1], F[2] - lp[2])
    return ((x[0] + Y[0] * g[0] + Y[1] * g[1] + Y[2] * g[2], x[1] + Y[3] * g[0] + Y[4] * g[1] + Y[5] * g[2],
             x[2] + Y[6] * g[0] + Y[7] * g[1] + Y[8] * g[2]), pdd)


def _add3(a: F3, b: F3) -> F3:
    return a[0] + b[0], a[1] + b[1], a[2] + b[2]


def _evaluate(p: DeltaParams, w: WristConstants, x: Sequence[float], u: Sequence[float], tau: Sequence[float],
              f: Sequence[float], moment: Sequence[float], pole: float) -> tuple[F24, F6, tuple, WristLoad]:
    """Solve the plant at one point: (xdot, lam, arms' (P, Pd, e), wrist load)."""
    xl = _as_list(x)
    ql, vl = xl[0:9], xl[12:21]
    qw, vw = (xl[9], xl[10], xl[11]), (xl[21], xl[22], xl[23])
    ul = _as_list(u)
    load = wrist_load(w, qw, vw, tau, f, moment)
    f0 = load.force
    L = _third(load.apparent_mass)
    consts = _constants(p)
    l0l3, l1, l2, dmp = p.l0 - p.l3, p.l1, p.l2, p.damping
    (cA, sA), (cB, sB), (cC, sC) = ARM_COS_SIN
    arm1 = _arm(consts, dmp, pole, cA, sA, l0l3, l1, l2, ql[0], ql[1], ql[2], vl[0], vl[1], vl[2], ul[0],
                f0[0], f0[1], f0[2])
    arm2 = _arm(consts, dmp, pole, cB, sB, l0l3, l1, l2, ql[3], ql[4], ql[5], vl[3], vl[4], vl[5], ul[1],
                f0[0], f0[1], f0[2])
    arm3 = _arm(consts, dmp, pole, cC, sC, l0l3, l1, l2, ql[6], ql[7], ql[8], vl[6], vl[7], vl[8], ul[2],
                f0[0], f0[1], f0[2])
    b1, W1, k1 = _arm_load(arm1, L, pole)
    b2, W2, k2 = _arm_load(arm2, L, pole)
    b3, W3, k3 = _arm_load(arm3, L, pole)
    lam = _schur_solve(_schur_factor(W1, W2, W3), (b2[0] - b1[0], b2[1] - b1[1], b2[2] - b1[2],
                                                   b3[0] - b1[0], b3[1] - b1[1], b3[2] - b1[2]))
    la0, la1, la2, lb0, lb1, lb2 = lam
    d1, a1 = _arm_motion(arm1, L, W1, k1, (la0 + lb0, la1 + lb1, la2 + lb2))
    d2, a2 = _arm_motion(arm2, L, W2, k2, (-la0, -la1, -la2))
    d3, a3 = _arm_motion(arm3, L, W3, k3, (-lb0, -lb1, -lb2))
    g_rel = (-(a1[0] + a2[0] + a3[0]) / 3.0, -(a1[1] + a2[1] + a3[1]) / 3.0,
             -w.g - (a1[2] + a2[2] + a3[2]) / 3.0)  # g_vec - zdd
    js, free = load.terms.js, load.free
    qddw = sym_apply(load.inverse_mass, (free[0] + js[0] * g_rel[0] + js[3] * g_rel[1] + js[6] * g_rel[2],
                                         free[1] + js[1] * g_rel[0] + js[4] * g_rel[1] + js[7] * g_rel[2],
                                         free[2] + js[2] * g_rel[0] + js[5] * g_rel[1] + js[8] * g_rel[2]))
    xdot = xl[12:24] + [d1[0], d1[1], d1[2], d2[0], d2[1], d2[2], d3[0], d3[1], d3[2], qddw[0], qddw[1], qddw[2]]
    arms = ((arm1[4], arm1[5], arm1[6]), (arm2[4], arm2[5], arm2[6]), (arm3[4], arm3[5], arm3[6]))
    return xdot, lam, arms, load


def state_derivative(p: DeltaParams, w: WristConstants, m: WristMount, x: Sequence[float], u: Sequence[float],
                     tau: Sequence[float], f: Sequence[float], moment: Sequence[float], pole: float) -> F24:
    """d/dt [q, qw, v, vw] (24 floats) with servo torques u (N m), wrist torques tau (N m), a force
    f on the tool tip (N) and a moment on the tool (N m), world frame; pole: Baumgarte's p (1/s).
    The mount m does not enter the dynamics (the plate only translates); it is an argument so the
    component's kernels share one signature."""
    return _evaluate(p, w, x, u, tau, f, moment, pole)[0]


def _wrist_energy(w: WristConstants, load: WristLoad, vw: F3, zd: F3, centre_z: float) -> float:
    """The wrist's kinetic and potential energy with O at height centre_z moving at zd (J)."""
    t = load.terms
    js, fr = t.js, t.frame
    jv = (js[0] * vw[0] + js[1] * vw[1] + js[2] * vw[2], js[3] * vw[0] + js[4] * vw[1] + js[5] * vw[2],
          js[6] * vw[0] + js[7] * vw[1] + js[8] * vw[2])
    mass = w.m1 + w.m2 + w.m3
    return (0.5 * mass * dot(zd, zd) + dot(zd, jv) + t.kinetic
            + w.g * (mass * centre_z + fr.s1[2] + fr.s2[2] + fr.s3[2]))


def plant_outputs(p: DeltaParams, w: WristConstants, m: WristMount, x: Sequence[float], u: Sequence[float],
                  tau: Sequence[float], f: Sequence[float], moment: Sequence[float],
                  pole: float) -> tuple[F3, F3, F3, F3, F3, F3, F3, F3, F9, F3, F3, F6, float, float, float]:
    """The DeltaWrist component's outputs from one evaluation, in its order: servo angles y and
    rates yd, wrist joints qw and rates qwd, plate centre z and velocity zd, tool tip position and
    velocity, tool rotation R (world <- tool, row-major), tool angular velocity omega, wrist centre
    O, loop multipliers lam (6, as DeltaRobot's), loop residual |h| (m), energy (J) and the gimbal
    distance |cos q2| (1 far from gimbal lock, 0 at it)."""
    xl = _as_list(x)
    _, lam, arms, load = _evaluate(p, w, xl, u, tau, f, moment, pole)
    z, zd, residual, e_delta = _wrist(arms)
    qw, vw = (xl[9], xl[10], xl[11]), (xl[21], xl[22], xl[23])
    centre = (z[0] + m.x, z[1] + m.y, z[2] + m.z)
    tip = load.tip
    omega = load.terms.omega
    spin = cross(omega, tip)
    return ((xl[0], xl[3], xl[6]), (xl[12], xl[15], xl[18]), qw, vw, z, zd, _add3(centre, tip), _add3(zd, spin),
            tool_rotation(qw), omega, centre, lam, residual, e_delta + _wrist_energy(w, load, vw, zd, centre[2]),
            abs(math.cos(qw[1])))


def energy(p: DeltaParams, w: WristConstants, m: WristMount, x: ArrayLike) -> float:
    """Kinetic plus potential energy of the plant (J), zero potential in the base plane z = 0."""
    zero = (0.0, 0.0, 0.0)
    return plant_outputs(p, w, m, _as_list(x), zero, zero, zero, zero, 0.0)[13]


def loop_residual(p: DeltaParams, x: ArrayLike) -> float:
    """|h(q)| of the delta's loops (m) for a plant state x."""
    return delta_dynamics.loop_residual(p, _as_list(x)[:9])


def _apparent_mass(w: WristConstants, qw: F3) -> tuple[F6, WristLoad]:
    zero = (0.0, 0.0, 0.0)
    load = wrist_load(w, qw, zero, zero, zero, zero)
    return load.apparent_mass, load


# -- the projection onto the closed loops as a float kernel (CVODE's, compiled into the FMU) --
# dynamics.project_to_constraints' algebra in the codegen's subset: its list updates in place
# become new tuples (C passes lists by value), J_s^T dzd a dot product (numpy's matmul may round
# differently), the stopping test sqrt(sum h^2) (math.hypot is CPython's own algorithm)

def _arm_corrected(values: Sequence[float], Y: tuple, L: tuple, wp: tuple, F: tuple, k: int) -> tuple:
    """Arm k's three values moved by the world correction force F: values - Y (F - L W' F)."""
    lp = sym_apply(L, sym_apply(wp, F))
    g = (F[0] - lp[0], F[1] - lp[1], F[2] - lp[2])
    return (values[3 * k] - (Y[0] * g[0] + Y[1] * g[1] + Y[2] * g[2]),
            values[3 * k + 1] - (Y[3] * g[0] + Y[4] * g[1] + Y[5] * g[2]),
            values[3 * k + 2] - (Y[6] * g[0] + Y[7] * g[1] + Y[8] * g[2]))


def _corrected(values: Sequence[float], Ys: tuple, L: tuple, wps: tuple, lam: tuple) -> list[float]:
    """values - M'^-1 H^T lam (arm forces la + lb, -la, -lb)."""
    la, lb = (lam[0], lam[1], lam[2]), (lam[3], lam[4], lam[5])
    return list(_arm_corrected(values, Ys[0], L, wps[0], (la[0] + lb[0], la[1] + lb[1], la[2] + lb[2]), 0)
            + _arm_corrected(values, Ys[1], L, wps[1], (-la[0], -la[1], -la[2]), 1)
            + _arm_corrected(values, Ys[2], L, wps[2], (-lb[0], -lb[1], -lb[2]), 2))


def _plate_velocity(l0l3: float, l1: float, l2: float, ql: Sequence[float], vl: Sequence[float]) -> tuple:
    """Jv v, the mean of the arm ends' velocities (m/s)."""
    (cA, sA), (cB, sB), (cC, sC) = ARM_COS_SIN
    e1 = _arm_wrist(cA, sA, l0l3, l1, l2, ql[0], ql[1], ql[2], vl[0], vl[1], vl[2])
    e2 = _arm_wrist(cB, sB, l0l3, l1, l2, ql[3], ql[4], ql[5], vl[3], vl[4], vl[5])
    e3 = _arm_wrist(cC, sC, l0l3, l1, l2, ql[6], ql[7], ql[8], vl[6], vl[7], vl[8])
    return ((0.0 + e1[3] + e2[3] + e3[3]) / 3.0, (0.0 + e1[4] + e2[4] + e3[4]) / 3.0,
            (0.0 + e1[5] + e2[5] + e3[5]) / 3.0)


def project_state(p: DeltaParams, w: WristConstants, x: Sequence[float]) -> list[float]:
    """The state (24 floats, in order) on the closed loops h(q) = 0, H v = 0 in the plant's mass
    metric: :func:`deltafmi.physics.delta_wrist.dynamics.project_to_constraints` (tol 1e-13 m,
    at most 8 Gauss-Newton steps; module docstring there) as a float kernel. The wrist's angles
    stay, its rates keep their joint momenta: vw -= M^-1 J_s^T dzd."""
    return _project(p, w, x, 1e-13, 8)


def _project(p: DeltaParams, w: WristConstants, x: Sequence[float], tol: float, max_iterations: int) -> list[float]:
    ql, vl, qw = list(x[0:9]), list(x[12:21]), (x[9], x[10], x[11])
    L3, load = _apparent_mass(w, qw)
    L = _third(L3)
    a, b, beta, _, _ = _constants(p)
    l0l3, l1, l2 = p.l0 - p.l3, p.l1, p.l2
    zd_before = _plate_velocity(l0l3, l1, l2, ql, vl)
    zero = (0.0, 0.0, 0.0)
    for _ in range(max_iterations):  # a C loop (a constant range is unrolled: no break)
        (w1, W1, Y1), (w2, W2, Y2), (w3, W3, Y3) = _arms_linearization(a, b, beta, l0l3, l1, l2, ql, vl)
        Ys = (Y1, Y2, Y3)
        wps = (_loaded(W1, L, zero)[0], _loaded(W2, L, zero)[0], _loaded(W3, L, zero)[0])
        h, Hv = _loop_residuals(w1, w2, w3)
        factors = _schur_factor(wps[0], wps[1], wps[2])
        ql = _corrected(ql, Ys, L, wps, _schur_solve(factors, h))
        vl = _corrected(vl, Ys, L, wps, _schur_solve(factors, Hv))
        h, Hv = _closure(l0l3, l1, l2, ql, vl)
        if math.sqrt(sum(t * t for t in h)) <= tol:
            break
    vl = _corrected(vl, Ys, L, wps, _schur_solve(factors, Hv))
    zd = _plate_velocity(l0l3, l1, l2, ql, vl)
    dzd = (zd[0] - zd_before[0], zd[1] - zd_before[1], zd[2] - zd_before[2])
    js = load.terms.js
    dvw = sym_apply(load.inverse_mass, (dot((js[0], js[3], js[6]), dzd), dot((js[1], js[4], js[7]), dzd),
                                        dot((js[2], js[5], js[8]), dzd)))
    return ql + list(qw) + vl + [x[21] - dvw[0], x[22] - dvw[1], x[23] - dvw[2]]


def project_to_constraints(p: DeltaParams, w: WristConstants, x: ArrayLike, *, tol: float = 1e-13,
                           max_iterations: int = 8) -> np.ndarray:
    """Nearest state on the closed loops (h(q) = 0, H v = 0) in the plant's mass metric (24 floats).

    delta.project_to_constraints' Gauss-Newton steps with the arms' apparent masses
    m_i + Ht_i^T (Lambda/3) Ht_i (the wrist's joints free): dq = -M'^-1 H^T S'^-1 h, the same
    for v with H v, S' = H M'^-1 H^T by the delta's 3x3 block algebra with W_i' (module
    docstring). The correction is an impulse on the loops only, so the wrist keeps its joint
    momenta M vw + J_s^T zd: vw changes by -M^-1 J_s^T dzd for the plate's velocity change dzd.
    The wrist's angles are left as they are. Raises ArithmeticError where H loses rank.
    """
    if max_iterations < 1:
        raise ValueError(f"max_iterations must be >= 1, got {max_iterations}")
    return np.array(_project(p, w, _as_list(np.asarray(x, dtype=float)), tol, max_iterations))


def start_state(p: DeltaParams, w: WristConstants, m: WristMount, tip: ArrayLike, orientation: ArrayLike,
                zd: Optional[ArrayLike] = None, qwd: Optional[ArrayLike] = None) -> np.ndarray:
    """The plant state (24) with the tool tip at ``tip`` (m, world) and the tool oriented by
    ``orientation``: wrist angles (3,) rad, or the tool rotation R_tool (3, 3) (world <- tool,
    wrist.inverse_kinematics' branch |q2| <= pi/2). The plate moves at ``zd`` (m/s, default rest;
    loops closed, H v = 0) and the wrist joints at ``qwd`` (rad/s, default rest).

    Inverse kinematics: qw from the orientation, the plate centre z = tip - p(qw) - d, the delta's
    joints from z (closed form, delta.inverse_kinematics).

    Raises:
        ValueError: the orientation has the wrong shape, or the plate centre the tip needs is out
            of the delta's reach (the message names the tip, that plate centre and the workspace).
    """
    o = np.asarray(orientation, dtype=float)
    if o.shape == (3, 3):
        qw = wrist_kinematics.inverse_kinematics(o)
    elif o.shape == (3,):
        qw = o
    else:
        raise ValueError(f"tool orientation: give 3 wrist angles or a 3x3 rotation, not an array of shape {o.shape}")
    tip_world = np.asarray(tip, dtype=float)
    z = tip_world - np.array(tip_position(w, (float(qw[0]), float(qw[1]), float(qw[2])))) - np.array([m.x, m.y, m.z])
    try:
        q = inverse_kinematics(p, z)
    except ValueError as exc:
        where = ", ".join(f"{t:.4f}" for t in tip_world)
        centre = ", ".join(f"{t:.4f}" for t in z)
        detail = str(exc).split("out of reach: ", 1)[-1]
        raise ValueError(f"tool tip ({where}) m is out of reach: it needs the plate centre at ({centre}) m, "
                         f"where {detail}") from None
    v = joint_rates(p, q, np.zeros(3) if zd is None else zd)
    rates = np.zeros(3) if qwd is None else np.asarray(qwd, dtype=float)
    return np.concatenate([q, qw, v, rates])


def holding_torques(p: DeltaParams, w: WristConstants, x: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Servo torques u (3,) and wrist torques tau (3,) (N m) that hold the plant still at x's pose.

    The wrist is held by its gravity torques tau = -J_s^T g_vec; it then loads the plate with its
    whole weight m g_vec (f0 of the module docstring at rest), which the delta carries as payload
    (delta.holding_torque with payload + m: the seed's static solve [B H^T] [u; lam] = G)."""
    xl = _as_list(np.asarray(x, dtype=float))
    tau = gravity_torques(w, (xl[9], xl[10], xl[11]), (0.0, 0.0, -w.g))
    u, _ = delta_dynamics.holding_torque(replace(p, payload=p.payload + w.m1 + w.m2 + w.m3), xl[:9])
    return u, np.array(tau)
