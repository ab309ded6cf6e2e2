"""The spherical wrist's dynamics as float kernels: what the 6-DOF plant FMUs compile to C.

The same mechanics as :mod:`.kinematics` and :mod:`.dynamics` (numpy), written in the float subset
of deltafmi/builder/codegen/translate.py (floats, fixed tuples, ``math``; no numpy): the numbers
agree with the numpy module to rounding (same formulas, other order of operations). The wrist is
read from :class:`WristConstants`, a flat dataclass of floats built once per parameter set by
:func:`wrist_constants` (numpy allowed there: it is not a kernel).

Conventions: 3x3 matrices are 9 floats row-major (``F9``); a symmetric 3x3 matrix is its 6 unique
entries (xx, xy, xz, yy, yz, zz) (``F6``, the order of delta.dynamics' 3x3 algebra). Joint angles
q = (q1, q2, q3), axes Z-X-Y through the wrist centre O (module :mod:`.kinematics`):

    R_1 = Rz(q1),  R_2 = R_1 Rx(q2),  R_3 = R_2 Ry(q3),  R_tool = R_3 Rx(pi)
    a_1 = e_z,  a_2 = R_1 e_x = (c1, s1, 0),  a_3 = R_2 e_y = (-s1 c2, c1 c2, s2)

Body i (link i with its rotor; body 3 carries the tool) has mass m_i, first moment
s_i = R_i (m_i c_i) and inertia about O I_i = R_i I_i^O R_i^T (world). With
omega_i = sum_{j <= i} a_j qd_j and e_i = sum_{j <= i} omega_{j-1} x a_j qd_j (body i's angular
acceleration at qdd = 0), the terms of M qdd + h + g + D qd = tau (Spong, Hutchinson &
Vidyasagar, Robot Modeling and Control, ch. 7; Euler's law about O projected on the axes):

    M_jk = a_j^T (sum_{i >= max(j,k)} I_i) a_k
    h_j  = a_j . sum_{i >= j} (I_i e_i + omega_i x I_i omega_i)                (C(q, qd) qd)
    g_j  = -a_j . sum_{i >= j} s_i x g_eff,  g_eff = (0, 0, -g) - (base acceleration)
    J_s  = [a_1 x S_1, a_2 x S_2, a_3 x S_3],  S_j = sum_{i >= j} s_i     (d/dt sum s_i = J_s qd)
    b_s  = sum_i e_i x s_i + omega_i x (omega_i x s_i)            (d^2/dt^2 sum s_i = J_s qdd + b_s)
    T = 1/2 sum_i omega_i . I_i omega_i,  V = g sum_i s_i,z  (about O, zero at O's height)

The tool tip p = R_tool (0, 0, tip) = -tip R_3 e_z (relative to O) moves with
p_dot = omega_3 x p = J_p qd, J_p's column j = a_j x p (every axis passes through O).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import NamedTuple

from .params import WristParams, link_inertias

__all__ = ["WristConstants", "wrist_constants", "WristFrame", "WristTerms", "F3", "F6", "F9",
           "link_rotations", "joint_axes", "tool_rotation", "tip_position", "tip_jacobian", "wrist_frame",
           "mass_matrix", "bias_torques", "gravity_torques", "first_moment_jacobian", "first_moment_bias",
           "wrist_terms", "kinetic_energy", "energy", "accelerations", "cross", "dot", "sym_apply", "sym_solve"]

F3 = tuple[float, float, float]
F6 = tuple[float, float, float, float, float, float]
F9 = tuple[float, float, float, float, float, float, float, float, float]


@dataclass(frozen=True)
class WristConstants:
    """The wrist's rigid bodies about O in their link frames, flat floats (what the kernels read).

    m_i: body mass (kg); s_i*: first moment m_i c_i in link frame i (kg m); i_i**: inertia about O
    in link frame i (kg m^2), the rotor's axial inertia and (body 3) the tool included; tip: O to
    the tool tip along the tool axis (m); g: gravity (m/s^2); damping: joint viscous friction
    (N m s/rad). Built by :func:`wrist_constants`.
    """

    m1: float
    m2: float
    m3: float
    s1x: float
    s1y: float
    s1z: float
    s2x: float
    s2y: float
    s2z: float
    s3x: float
    s3y: float
    s3z: float
    i1xx: float
    i1xy: float
    i1xz: float
    i1yy: float
    i1yz: float
    i1zz: float
    i2xx: float
    i2xy: float
    i2xz: float
    i2yy: float
    i2yz: float
    i2zz: float
    i3xx: float
    i3xy: float
    i3xz: float
    i3yy: float
    i3yz: float
    i3zz: float
    tip: float
    g: float
    damping: float


def wrist_constants(p: WristParams) -> WristConstants:
    """:class:`WristConstants` of a parameter set (from :func:`.params.link_inertias`)."""
    masses, moments, inertias = link_inertias(p)
    values: list[float] = [float(m) for m in masses] + [float(s) for s in moments.ravel()]
    for inertia in inertias:
        values += [float(inertia[0, 0]), float(inertia[0, 1]), float(inertia[0, 2]), float(inertia[1, 1]),
                   float(inertia[1, 2]), float(inertia[2, 2])]
    values += [float(p.tool.tip), float(p.g), float(p.damping)]
    return WristConstants(**{f.name: v for f, v in zip(fields(WristConstants), values)})


class WristFrame(NamedTuple):
    """World-frame geometry of the wrist at one q (see the module docstring)."""

    a1: F3  #: joint axes (columns of J_w)
    a2: F3
    a3: F3
    s1: F3  #: first moments of the bodies, world (kg m)
    s2: F3
    s3: F3
    i1: F6  #: inertias about O, world (kg m^2)
    i2: F6
    i3: F6
    r3: F9  #: R_3, link 3 -> world


class WristTerms(NamedTuple):
    """Everything the 6-DOF plant needs of the wrist at one (q, qd)."""

    frame: WristFrame
    mass: F6  #: M(q), symmetric (kg m^2)
    bias: F3  #: h = C(q, qd) qd (N m)
    js: F9  #: J_s, row-major (kg m/rad)
    bs: F3  #: b_s (kg m/s^2)
    omega: F3  #: angular velocity of body 3 (the tool), world (rad/s)
    kinetic: float  #: T (J)


# -------------------------------------------------------------------------------- 3-vector algebra

def cross(a: F3, b: F3) -> F3:
    """a x b."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a: F3, b: F3) -> float:
    """a . b."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def sym_apply(m: F6, v: F3) -> F3:
    """M v for a symmetric M given as (xx, xy, xz, yy, yz, zz)."""
    return (m[0] * v[0] + m[1] * v[1] + m[2] * v[2], m[1] * v[0] + m[3] * v[1] + m[4] * v[2],
            m[2] * v[0] + m[4] * v[1] + m[5] * v[2])


def _add(a: F3, b: F3) -> F3:
    return a[0] + b[0], a[1] + b[1], a[2] + b[2]


def _scaled(a: F3, k: float) -> F3:
    return a[0] * k, a[1] * k, a[2] * k


def _sym_add(a: F6, b: F6) -> F6:
    return a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3], a[4] + b[4], a[5] + b[5]


def _rotate(r: F9, v: F3) -> F3:
    return (r[0] * v[0] + r[1] * v[1] + r[2] * v[2], r[3] * v[0] + r[4] * v[1] + r[5] * v[2],
            r[6] * v[0] + r[7] * v[1] + r[8] * v[2])


def _rotate_sym(r: F9, m: F6) -> F6:
    """R M R^T for a symmetric M (6 unique entries in and out)."""
    c0 = sym_apply(m, (r[0], r[1], r[2]))  # M times row k of R: column k of M R^T
    c1 = sym_apply(m, (r[3], r[4], r[5]))
    c2 = sym_apply(m, (r[6], r[7], r[8]))
    return (r[0] * c0[0] + r[1] * c0[1] + r[2] * c0[2], r[0] * c1[0] + r[1] * c1[1] + r[2] * c1[2],
            r[0] * c2[0] + r[1] * c2[1] + r[2] * c2[2], r[3] * c1[0] + r[4] * c1[1] + r[5] * c1[2],
            r[3] * c2[0] + r[4] * c2[1] + r[5] * c2[2], r[6] * c2[0] + r[7] * c2[1] + r[8] * c2[2])


# ------------------------------------------------------------------------------------- kinematics

def link_rotations(q: F3) -> tuple[F9, F9, F9]:
    """(R_1, R_2, R_3), world <- link i, row-major."""
    s1, c1, s2, c2, s3, c3 = (math.sin(q[0]), math.cos(q[0]), math.sin(q[1]), math.cos(q[1]),
                              math.sin(q[2]), math.cos(q[2]))
    r1 = (c1, -s1, 0.0, s1, c1, 0.0, 0.0, 0.0, 1.0)
    # R_1 Rx(q2), then times Ry(q3): a row (x, y, z) becomes (x c3 - z s3, y, x s3 + z c3)
    r2 = (c1, -s1 * c2, s1 * s2, s1, c1 * c2, -c1 * s2, 0.0, s2, c2)
    r3 = (c1 * c3 - s1 * s2 * s3, -s1 * c2, c1 * s3 + s1 * s2 * c3,
          s1 * c3 + c1 * s2 * s3, c1 * c2, s1 * s3 - c1 * s2 * c3,
          -c2 * s3, s2, c2 * c3)
    return r1, r2, r3


def joint_axes(q: F3) -> tuple[F3, F3, F3]:
    """(a_1, a_2, a_3), the joint axes in the world: the columns of J_w."""
    s1, c1, s2, c2 = math.sin(q[0]), math.cos(q[0]), math.sin(q[1]), math.cos(q[1])
    return (0.0, 0.0, 1.0), (c1, s1, 0.0), (-s1 * c2, c1 * c2, s2)


def tool_rotation(q: F3) -> F9:
    """R_tool = R_3 Rx(pi) (world <- tool frame, row-major): R_3 with its y and z columns negated;
    the third column is the tool (approach) axis."""
    r = link_rotations(q)[2]
    return r[0], -r[1], -r[2], r[3], -r[4], -r[5], r[6], -r[7], -r[8]


def tip_position(w: WristConstants, q: F3) -> F3:
    """Tool tip relative to O, world (m): tip times the tool axis, -tip R_3 e_z."""
    r = link_rotations(q)[2]
    return -w.tip * r[2], -w.tip * r[5], -w.tip * r[8]


def tip_jacobian(w: WristConstants, q: F3) -> F9:
    """J_p (row-major, m/rad): the tip's velocity relative to O is J_p qd, column j = a_j x p."""
    a1, a2, a3 = joint_axes(q)
    p = tip_position(w, q)
    c1, c2, c3 = cross(a1, p), cross(a2, p), cross(a3, p)
    return c1[0], c2[0], c3[0], c1[1], c2[1], c3[1], c1[2], c2[2], c3[2]


def wrist_frame(w: WristConstants, q: F3) -> WristFrame:
    """Joint axes, first moments and inertias about O of the three bodies, world frame."""
    r1, r2, r3 = link_rotations(q)
    a1, a2, a3 = joint_axes(q)
    return WristFrame(a1, a2, a3,
                      _rotate(r1, (w.s1x, w.s1y, w.s1z)), _rotate(r2, (w.s2x, w.s2y, w.s2z)),
                      _rotate(r3, (w.s3x, w.s3y, w.s3z)),
                      _rotate_sym(r1, (w.i1xx, w.i1xy, w.i1xz, w.i1yy, w.i1yz, w.i1zz)),
                      _rotate_sym(r2, (w.i2xx, w.i2xy, w.i2xz, w.i2yy, w.i2yz, w.i2zz)),
                      _rotate_sym(r3, (w.i3xx, w.i3xy, w.i3xz, w.i3yy, w.i3yz, w.i3zz)), r3)


# --------------------------------------------------------------------------------------- dynamics

def _frame_mass(fr: WristFrame) -> F6:
    """M from the composite inertias C_k = sum_{i >= k} I_i: M_jk = a_j . C_max(j,k) a_k."""
    c3 = fr.i3
    c2 = _sym_add(fr.i2, c3)
    c1 = _sym_add(fr.i1, c2)
    c1a1, c2a2, c3a3 = sym_apply(c1, fr.a1), sym_apply(c2, fr.a2), sym_apply(c3, fr.a3)
    return (dot(fr.a1, c1a1), dot(fr.a1, c2a2), dot(fr.a1, c3a3), dot(fr.a2, c2a2), dot(fr.a2, c3a3),
            dot(fr.a3, c3a3))


def mass_matrix(w: WristConstants, q: F3) -> F6:
    """M(q) (kg m^2), symmetric positive definite for positive rotor inertias."""
    return _frame_mass(wrist_frame(w, q))


def _rates(fr: WristFrame, qd: F3) -> tuple[F3, F3, F3, F3, F3]:
    """(omega_1, omega_2, omega_3, e_2, e_3): body rates and their velocity products (e_1 = 0)."""
    w1 = _scaled(fr.a1, qd[0])
    d2 = _scaled(fr.a2, qd[1])
    d3 = _scaled(fr.a3, qd[2])
    w2 = _add(w1, d2)
    w3 = _add(w2, d3)
    e2 = cross(w1, d2)
    e3 = _add(e2, cross(w2, d3))
    return w1, w2, w3, e2, e3


def _frame_bias(fr: WristFrame, qd: F3) -> tuple[F3, F3, F3, float]:
    """(h, b_s, omega_3, T) at the rates qd."""
    w1, w2, w3, e2, e3 = _rates(fr, qd)
    l1, l2, l3 = sym_apply(fr.i1, w1), sym_apply(fr.i2, w2), sym_apply(fr.i3, w3)
    t1 = cross(w1, l1)  # e_1 = 0
    t2 = _add(sym_apply(fr.i2, e2), cross(w2, l2))
    t3 = _add(sym_apply(fr.i3, e3), cross(w3, l3))
    tail2 = _add(t2, t3)
    h = (dot(fr.a1, _add(t1, tail2)), dot(fr.a2, tail2), dot(fr.a3, t3))
    bs = _add(_add(cross(w1, cross(w1, fr.s1)), _add(cross(e2, fr.s2), cross(w2, cross(w2, fr.s2)))),
              _add(cross(e3, fr.s3), cross(w3, cross(w3, fr.s3))))
    kinetic = 0.5 * (dot(w1, l1) + dot(w2, l2) + dot(w3, l3))
    return h, bs, w3, kinetic


def bias_torques(w: WristConstants, q: F3, qd: F3) -> F3:
    """h = C(q, qd) qd, centripetal and Coriolis torques (N m)."""
    return _frame_bias(wrist_frame(w, q), qd)[0]


def _frame_gravity(fr: WristFrame, g_eff: F3) -> F3:
    n3 = cross(fr.s3, g_eff)
    n23 = _add(cross(fr.s2, g_eff), n3)
    return -dot(fr.a1, _add(cross(fr.s1, g_eff), n23)), -dot(fr.a2, n23), -dot(fr.a3, n3)


def gravity_torques(w: WristConstants, q: F3, g_eff: F3) -> F3:
    """g(q) = -J_s^T g_eff (N m) for an effective gravity g_eff = (0, 0, -g) - base acceleration."""
    return _frame_gravity(wrist_frame(w, q), g_eff)


def _frame_js(fr: WristFrame) -> F9:
    tail3 = fr.s3
    tail2 = _add(fr.s2, tail3)
    tail1 = _add(fr.s1, tail2)
    c1, c2, c3 = cross(fr.a1, tail1), cross(fr.a2, tail2), cross(fr.a3, tail3)
    return c1[0], c2[0], c3[0], c1[1], c2[1], c3[1], c1[2], c2[2], c3[2]


def first_moment_jacobian(w: WristConstants, q: F3) -> F9:
    """J_s (row-major, kg m/rad): d/dt sum_i s_i = J_s qd."""
    return _frame_js(wrist_frame(w, q))


def first_moment_bias(w: WristConstants, q: F3, qd: F3) -> F3:
    """b_s (kg m/s^2): d^2/dt^2 sum_i s_i = J_s qdd + b_s."""
    return _frame_bias(wrist_frame(w, q), qd)[1]


def wrist_terms(w: WristConstants, q: F3, qd: F3) -> WristTerms:
    """M, h, J_s, b_s, the tool's angular velocity and T from one evaluation of the frame."""
    fr = wrist_frame(w, q)
    h, bs, omega, kinetic = _frame_bias(fr, qd)
    return WristTerms(fr, _frame_mass(fr), h, _frame_js(fr), bs, omega, kinetic)


def kinetic_energy(w: WristConstants, q: F3, qd: F3) -> float:
    """T = 1/2 sum_i omega_i . I_i omega_i (J), base at rest."""
    return _frame_bias(wrist_frame(w, q), qd)[3]


def energy(w: WristConstants, q: F3, qd: F3) -> float:
    """T + V (J), base at rest, V = g sum_i s_i,z (zero with every centre of mass at O's height)."""
    fr = wrist_frame(w, q)
    return _frame_bias(fr, qd)[3] + w.g * (fr.s1[2] + fr.s2[2] + fr.s3[2])


def sym_solve(m: F6, r: F3) -> F3:
    """M^-1 r for a symmetric positive definite M (6 unique entries), by its adjugate."""
    c11 = m[3] * m[5] - m[4] * m[4]
    c12 = m[2] * m[4] - m[1] * m[5]
    c13 = m[1] * m[4] - m[2] * m[3]
    det = m[0] * c11 + m[1] * c12 + m[2] * c13
    inv = (c11 / det, c12 / det, c13 / det, (m[0] * m[5] - m[2] * m[2]) / det,
           (m[1] * m[2] - m[0] * m[4]) / det, (m[0] * m[3] - m[1] * m[1]) / det)
    return sym_apply(inv, r)


def accelerations(w: WristConstants, q: F3, qd: F3, tau: F3, base_accel: F3) -> F3:
    """qdd = M^-1 (tau - h - D qd + J_s^T g_eff), g_eff = (0, 0, -g) - base_accel (rad/s^2)."""
    fr = wrist_frame(w, q)
    h = _frame_bias(fr, qd)[0]
    grav = _frame_gravity(fr, (-base_accel[0], -base_accel[1], -w.g - base_accel[2]))
    d = w.damping
    return sym_solve(_frame_mass(fr), (tau[0] - h[0] - grav[0] - d * qd[0], tau[1] - h[1] - grav[1] - d * qd[1],
                                       tau[2] - h[2] - grav[2] - d * qd[2]))
