"""Exact partial derivatives of the delta robot's stabilised dynamics and of its outputs.

The plant of :mod:`.dynamics` is the ODE x' = [v; a] in x = [q; v] (18 states), the accelerations
a and the multipliers lam solving (lam eliminated)

    M(q) a - H(q)^T lam = Q,      Q = B u + Jv(q)^T f - C(q, v) - D v - G(q),
    H(q) a + gamma = 0,           gamma = Hd(q, v) v + 2 p H(q) v + p^2 h(q).

Differentiating both equations with respect to any variable theta of [q, v, u, f], the
sensitivities (da, dlam) solve a linear system with the same KKT matrix:

    [[M, -H^T], [H, 0]] [da; dlam] = [dQ - (dM) a + (dH)^T lam;  -dgamma - (dH) a],

where every d on the right-hand side differentiates with a and lam held fixed. Everything on
the right is closed form per arm, in plain floats like the dynamics kernels: the derivatives of
the arm's wrist point psi(q_i) up to the third order (Jv, H, the velocity part of gamma), of its
mass block and of the closed-form C(q, v) of :mod:`.dynamics`, and the Hessian of the potential.
One KKT solve with 24 right-hand sides gives every column (by the dynamics' Schur complement,
in plain floats: a kernel the code generator translates whole).

Columns ("knowns") are ordered [q (9), v (9), u (3), f (3)], the order of the DeltaRobot FMU's
states and inputs. No FMI here: the FMU's component hands these matrices to the runtime.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from .dynamics import (_arm_response, _as_list, _constants, _evaluate, _schur_factor, _schur_solve, _subtract_response,
                       _sym3_inv)
from .kinematics import ARM_COS_SIN
from .params import DeltaParams

__all__ = ["PlantJacobian", "plant_jacobian", "jacobian_values", "jacobian_from_values", "state_jacobian", "N_KNOWNS",
           "N_VALUES"]

ArrayLike = Sequence[float] | np.ndarray
F3 = tuple[float, float, float]
F9 = tuple[float, float, float, float, float, float, float, float, float]

#: columns of every matrix below: q (9), v (9), u (3), f (3)
N_KNOWNS = 24
#: where :func:`jacobian_values`' solved columns begin: after the accelerations, the multipliers
#: and three arms' 69
_SENSITIVITIES = 9 + 6 + 3 * 69
#: the floats of :func:`jacobian_values`: those, then per known [da; dlam] (15)
N_VALUES = _SENSITIVITIES + N_KNOWNS * 15


class PlantJacobian(NamedTuple):
    """Values and exact partial derivatives at one point; every ``d*`` has the 24 columns
    [q, v, u, f] (see the module docstring)."""

    vdot: np.ndarray  #: joint accelerations a (9,)
    lam: np.ndarray  #: constraint multipliers (6,)
    dx: np.ndarray  #: d[q'; v'] (18, 24): the state Jacobian [[0, I, 0, 0], [da]] and input matrix
    dlam: np.ndarray  #: d lam (6, 24)
    dz: np.ndarray  #: d z (3, 24), z the wrist position (mean of the arms' wrist points)
    dzd: np.ndarray  #: d zd (3, 24), zd = Jv v
    denergy: np.ndarray  #: d energy (24,), kinetic plus potential

    @property
    def A(self) -> np.ndarray:
        """d x' / d x (18, 18)."""
        return self.dx[:, :18]

    @property
    def B(self) -> np.ndarray:
        """d x' / d [u, f] (18, 6)."""
        return self.dx[:, 18:]


def _arm(consts: tuple[float, float, float, float, float], damping: float, pole: float, cr: float,
         sr: float, l1: float, l2: float, q1: float, q2: float, q3: float, v1: float, v2: float,
         v3: float, a1: float, a2: float, a3: float, wx: float, wy: float, wz: float) -> tuple[float, ...]:
    """One arm's share of the KKT system and of the output derivatives, as 69 plain floats.

    (w_x, w_y, w_z) is f / 3 + F_i, the world force on the arm's wrist (its share of the external
    force plus the constraint force). The result, 3x3 blocks row-major, in the order of
    :data:`_BLOCKS`: mass block, Ht (world wrist Jacobian), R1 q-block, R1 v-block,
    d kappa/dq and d kappa/dv (world), d(Ht v)/dq (world), energy gradient (q then v).
    """
    a, b, beta, g1, g2 = consts
    s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                              math.sin(q3), math.cos(q3))
    # local wrist Jacobian columns J_k and nonzero second / third derivatives of psi
    j1y, j1z = -l1 * s1, l1 * c1
    j2x, j2y, j2z = l2 * c2 * s3, -l2 * s2, l2 * c2 * c3
    j3x, j3z = l2 * s2 * c3, -l2 * s2 * s3
    p11y, p11z = -l1 * c1, -l1 * s1
    p22x, p22y, p22z = -l2 * s2 * s3, -l2 * c2, -l2 * s2 * c3
    p23x, p23z = l2 * c2 * c3, -l2 * c2 * s3
    p33x, p33z = p22x, p22z
    t111y, t111z = l1 * s1, -l1 * c1
    t222x, t222y, t222z = -l2 * c2 * s3, l2 * s2, -l2 * c2 * c3
    t223x, t223z = -l2 * s2 * c3, l2 * s2 * s3  # = t333
    t233x, t233z = -l2 * c2 * s3, -l2 * c2 * c3
    # local load R^T w
    lx, ly, lz = cr * wx + sr * wy, cr * wy - sr * wx, wz
    # mass block, its first derivatives d(m12), d(m13) (per joint) and d(m33)/dq2
    m12, m13, m33 = b * (s1 * s2 + c1 * c2 * c3), -b * c1 * s2 * s3, beta * s2 * s2
    d12 = (b * (c1 * s2 - s1 * c2 * c3), b * (s1 * c2 - c1 * s2 * c3), -b * c1 * c2 * s3)
    d13 = (b * s1 * s2 * s3, -b * c1 * c2 * s3, -b * c1 * s2 * c3)
    d33 = 2.0 * beta * s2 * c2
    cos2 = c2 * c2 - s2 * s2
    vv1, vv2, vv3, v23 = v1 * v1, v2 * v2, v3 * v3, v2 * v3
    # the Coriolis vector's derivatives (from its closed form in .dynamics)
    dc1q1 = b * ((c1 * c2 + s1 * s2 * c3) * vv2 + 2.0 * s1 * c2 * s3 * v23 + s1 * s2 * c3 * vv3)
    dc1q2 = b * (-(s1 * s2 + c1 * c2 * c3) * vv2 + 2.0 * c1 * s2 * s3 * v23 - c1 * c2 * c3 * vv3)
    dc1q3 = b * (c1 * s2 * s3 * vv2 - 2.0 * c1 * c2 * c3 * v23 + c1 * s2 * s3 * vv3)
    dc2q1 = -b * (s1 * s2 + c1 * c2 * c3) * vv1
    dc2q2 = b * (c1 * c2 + s1 * s2 * c3) * vv1 - beta * cos2 * vv3
    dc2q3 = b * s1 * c2 * s3 * vv1
    dc3q1 = b * c1 * s2 * s3 * vv1
    dc3q2 = b * s1 * c2 * s3 * vv1 + 2.0 * beta * cos2 * v23
    dc3q3 = b * s1 * s2 * c3 * vv1
    dc1v2 = 2.0 * b * ((s1 * c2 - c1 * s2 * c3) * v2 - c1 * c2 * s3 * v3)
    dc1v3 = -2.0 * b * (c1 * c2 * s3 * v2 + c1 * s2 * c3 * v3)
    dc2v1 = 2.0 * b * (c1 * s2 - s1 * c2 * c3) * v1
    dc2v3 = -d33 * v3
    dc3v1 = 2.0 * b * s1 * s2 * s3 * v1
    dc3v2, dc3v3 = d33 * v3, d33 * v2
    # R1 q-block: (d2psi/dq dq_k)^T R^T w - dc/dq - d2V/dq2 - (dm/dq_k) a
    L11 = ly * p11y + lz * p11z
    L22 = lx * p22x + ly * p22y + lz * p22z
    L23 = lx * p23x + lz * p23z
    L33 = lx * p33x + lz * p33z
    kg23 = -g2 * c2 * s3
    r1q = (L11 - dc1q1 + g1 * s1 - (d12[0] * a2 + d13[0] * a3),
           -dc1q2 - (d12[1] * a2 + d13[1] * a3),
           -dc1q3 - (d12[2] * a2 + d13[2] * a3),
           -dc2q1 - d12[0] * a1,
           L22 - dc2q2 + g2 * s2 * c3 - d12[1] * a1,
           L23 - dc2q3 - kg23 - d12[2] * a1,
           -dc3q1 - d13[0] * a1,
           L23 - dc3q2 - kg23 - d13[1] * a1 - d33 * a3,
           L33 - dc3q3 + g2 * s2 * c3 - d13[2] * a1)
    r1v = (-damping, -dc1v2, -dc1v3,
           -dc2v1, -damping, -dc2v3,
           -dc3v1, -dc3v2, -damping - dc3v3)
    # d kappa / d q_k (local): P2[:, :, k] (a + 2p v) + P3[:, :, :, k] v v + p^2 J_k
    tp, pp = 2.0 * pole, pole * pole
    w1, w2, w3 = a1 + tp * v1, a2 + tp * v2, a3 + tp * v3
    kq = ((0.0, p11y * w1 + t111y * vv1 + pp * j1y, p11z * w1 + t111z * vv1 + pp * j1z),
          (p22x * w2 + p23x * w3 + t222x * vv2 + 2.0 * t223x * v23 + t233x * vv3 + pp * j2x,
           p22y * w2 + t222y * vv2 + pp * j2y,
           p22z * w2 + p23z * w3 + t222z * vv2 + 2.0 * t223z * v23 + t233z * vv3 + pp * j2z),
          (p23x * w2 + p33x * w3 + t223x * vv2 + 2.0 * t233x * v23 + t223x * vv3 + pp * j3x,
           0.0,
           p23z * w2 + p33z * w3 + t223z * vv2 + 2.0 * t233z * v23 + t223z * vv3 + pp * j3z))
    # d kappa / d v_k (local): 2 P2[:, k, :] v + 2p J_k ; and P2 v (for dzd/dq)
    pv = ((0.0, p11y * v1, p11z * v1),
          (p22x * v2 + p23x * v3, p22y * v2, p22z * v2 + p23z * v3),
          (p23x * v2 + p33x * v3, 0.0, p23z * v2 + p33z * v3))
    jl = ((0.0, j1y, j1z), (j2x, j2y, j2z), (j3x, 0.0, j3z))
    kv = (_twice_plus(pv[0], tp, jl[0]), _twice_plus(pv[1], tp, jl[1]), _twice_plus(pv[2], tp, jl[2]))
    # energy gradient: v^T dm_k v / 2 + G_k, and m v
    eq = (d12[0] * v1 * v2 + d13[0] * v1 * v3 + g1 * c1,
          d12[1] * v1 * v2 + d13[1] * v1 * v3 + 0.5 * d33 * vv3 + g2 * c2 * c3,
          d12[2] * v1 * v2 + d13[2] * v1 * v3 - g2 * s2 * s3)
    ev = (a * v1 + m12 * v2 + m13 * v3, m12 * v1 + beta * v2, m13 * v1 + m33 * v3)
    return ((a, m12, m13, m12, beta, 0.0, m13, 0.0, m33) + _rotate_columns(cr, sr, jl) + r1q + r1v
            + _rotate_columns(cr, sr, kq) + _rotate_columns(cr, sr, kv) + _rotate_columns(cr, sr, pv)
            + eq + ev)

def _twice_plus(x: F3, k: float, y: F3) -> F3:
    """2 x + k y for 3-vectors."""
    return 2.0 * x[0] + k * y[0], 2.0 * x[1] + k * y[1], 2.0 * x[2] + k * y[2]


def _rotate_columns(cr: float, sr: float, columns: tuple[F3, F3, F3]) -> F9:
    """Three local 3-vectors (the columns of a 3x3 matrix) rotated about z; row-major result."""
    x0, y0, z0 = columns[0]
    x1, y1, z1 = columns[1]
    x2, y2, z2 = columns[2]
    return (cr * x0 - sr * y0, cr * x1 - sr * y1, cr * x2 - sr * y2,
            sr * x0 + cr * y0, sr * x1 + cr * y1, sr * x2 + cr * y2,
            z0, z1, z2)


def plant_jacobian(p: DeltaParams, q: ArrayLike, v: ArrayLike, u: ArrayLike, f: ArrayLike,
                   pole: float = 5.0) -> PlantJacobian:
    """Exact partial derivatives of the plant's state derivative and outputs at (q, v, u, f).

    Args:
        p: robot parameters.
        q, v: joint angles (rad) and rates (rad/s), shape (9,), arm-major.
        u: servo torques (N m), shape (3,).
        f: external force on the wrist (N, world frame), shape (3,).
        pole: Baumgarte pole p (1/s).

    Returns:
        A :class:`PlantJacobian`; its columns are [q, v, u, f].

    Raises:
        ArithmeticError: H or the KKT matrix lost rank (a direct-kinematic or gimbal singularity).
    """
    return jacobian_from_values(np.array(jacobian_values(p, q, v, u, f, pole)))


def jacobian_values(p: DeltaParams, q: ArrayLike, v: ArrayLike, u: ArrayLike, f: ArrayLike,
                    pole: float) -> list[float]:
    """The float part of :func:`plant_jacobian`, :data:`N_VALUES` plain floats: the accelerations
    (9), the multipliers (6), each arm's share of the KKT system (see :func:`_arm`) and the KKT
    system solved (:func:`_sensitivities`). A kernel: the DeltaRobot FMU runs it as C generated
    from this source (deltafmi/builder/codegen)."""
    ql, vl, fl = _as_list(q), _as_list(v), _as_list(f)
    vdot, lam, _ = _evaluate(p, ql, vl, u, fl, pole)
    la0, la1, la2, lb0, lb1, lb2 = lam
    forces = ((la0 + lb0, la1 + lb1, la2 + lb2), (-la0, -la1, -la2), (-lb0, -lb1, -lb2))
    consts, pole, l1, l2, damping = _constants(p), float(pole), p.l1, p.l2, p.damping
    fx, fy, fz = fl[0] / 3.0, fl[1] / 3.0, fl[2] / 3.0
    (cA, sA), (cB, sB), (cC, sC) = ARM_COS_SIN
    wA, wB, wC = forces
    arm1 = _arm(consts, damping, pole, cA, sA, l1, l2, ql[0], ql[1], ql[2], vl[0], vl[1], vl[2],
                vdot[0], vdot[1], vdot[2], fx + wA[0], fy + wA[1], fz + wA[2])
    arm2 = _arm(consts, damping, pole, cB, sB, l1, l2, ql[3], ql[4], ql[5], vl[3], vl[4], vl[5],
                vdot[3], vdot[4], vdot[5], fx + wB[0], fy + wB[1], fz + wB[2])
    arm3 = _arm(consts, damping, pole, cC, sC, l1, l2, ql[6], ql[7], ql[8], vl[6], vl[7], vl[8],
                vdot[6], vdot[7], vdot[8], fx + wC[0], fy + wC[1], fz + wC[2])
    return vdot + list(lam) + list(arm1) + list(arm2) + list(arm3) + _sensitivities(arm1, arm2, arm3)


def _arm_blocks(arm: Sequence[float]) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """An arm's inverse mass block (6 unique entries), W = Ht m^-1 Ht^T (6) and Y = m^-1 Ht^T (9)
    from its :func:`_arm` values."""
    minv = _sym3_inv(arm[0], arm[1], arm[2], arm[4], arm[5], arm[8])
    W, Y = _arm_response(minv[0], minv[1], minv[2], minv[3], minv[4], minv[5], arm[9], arm[10], arm[11],
                         arm[12], arm[13], arm[14], arm[15], arm[16], arm[17])
    return minv, W, Y


def _mass_solve(m: Sequence[float], r1: float, r2: float, r3: float) -> F3:
    """m^-1 r for an arm's inverse mass block (6 unique entries)."""
    return (m[0] * r1 + m[1] * r2 + m[2] * r3, m[1] * r1 + m[3] * r2 + m[4] * r3, m[2] * r1 + m[4] * r2 + m[5] * r3)


def _ht_times(arm: Sequence[float], y: F3) -> F3:
    """Ht y: an arm's world wrist Jacobian (its values 9..17, row-major) times joint rates."""
    return (arm[9] * y[0] + arm[10] * y[1] + arm[11] * y[2], arm[12] * y[0] + arm[13] * y[1] + arm[14] * y[2],
            arm[15] * y[0] + arm[16] * y[1] + arm[17] * y[2])


def _sensitivities(arm1: Sequence[float], arm2: Sequence[float], arm3: Sequence[float]) -> list[float]:
    """The KKT solve of the module docstring from the arms' :func:`_arm` values: per known
    [q (9), v (9), u (3), f (3)] its column [da (9); dlam (6)], 24 x 15 floats.

    Solved as the dynamics solve theirs (closed-form 3x3 algebra, no dense factorization): with
    x = M^-1 R1 and the Schur complement S = H M^-1 H^T of :mod:`.dynamics`,
    S dlam = R2 - H x and da = x + M^-1 H^T dlam. Equal to a dense LU solve up to rounding.

    Raises:
        ArithmeticError: H or a mass block lost rank (a direct-kinematic or gimbal singularity).
    """
    arms = (arm1, arm2, arm3)
    minv1, W1, Y1 = _arm_blocks(arm1)
    minv2, W2, Y2 = _arm_blocks(arm2)
    minv3, W3, Y3 = _arm_blocks(arm3)
    minv = (minv1, minv2, minv3)
    factors = _schur_factor(W1, W2, W3)
    out = []
    for j in range(24):
        # R1 (9) and R2 (6) of column j, from the scatter of jacobian_from_values' template
        r1 = []
        r2 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        for i in range(3):
            arm = arms[i]
            if j < 18:
                block, col, kappa = 18, j - 3 * i, 36  # r1q, kq
                if j >= 9:
                    block, col, kappa = 27, j - 9 - 3 * i, 45  # r1v, kv
                if col >= 0 and col < 3:
                    r1 += [arm[block + col], arm[block + 3 + col], arm[block + 6 + col]]
                    k1, k2, k3 = arm[kappa + col], arm[kappa + 3 + col], arm[kappa + 6 + col]
                    # -sign * kappa in the rows of arm i's constraints (arm 1: both, +; arms 2, 3: -)
                    if i == 0:
                        r2 = [-k1, -k2, -k3, -k1, -k2, -k3]
                    elif i == 1:
                        r2 = [k1, k2, k3, 0.0, 0.0, 0.0]
                    else:
                        r2 = [0.0, 0.0, 0.0, k1, k2, k3]
                else:
                    r1 += [0.0, 0.0, 0.0]
            elif j < 21:
                r1 += [1.0, 0.0, 0.0] if j - 18 == i else [0.0, 0.0, 0.0]  # B u: the servo's joint
            else:
                r = j - 21  # Jv^T f: the arm's world wrist Jacobian's row r, over 3
                r1 += [arm[9 + 3 * r] / 3.0, arm[10 + 3 * r] / 3.0, arm[11 + 3 * r] / 3.0]
        x1 = _mass_solve(minv[0], r1[0], r1[1], r1[2])
        x2 = _mass_solve(minv[1], r1[3], r1[4], r1[5])
        x3 = _mass_solve(minv[2], r1[6], r1[7], r1[8])
        g1, g2, g3 = _ht_times(arm1, x1), _ht_times(arm2, x2), _ht_times(arm3, x3)
        # R2 - H x, H = [Ht1, -Ht2, 0; Ht1, 0, -Ht3]
        la1, la2, la3, lb1, lb2, lb3 = _schur_solve(factors, (
            r2[0] - (g1[0] - g2[0]), r2[1] - (g1[1] - g2[1]), r2[2] - (g1[2] - g2[2]),
            r2[3] - (g1[0] - g3[0]), r2[4] - (g1[1] - g3[1]), r2[5] - (g1[2] - g3[2])))
        da = _subtract_response([x1[0], x1[1], x1[2], x2[0], x2[1], x2[2], x3[0], x3[1], x3[2]], Y1, Y2, Y3,
                                (-la1, -la2, -la3, -lb1, -lb2, -lb3))
        out += da + [la1, la2, la3, lb1, lb2, lb3]
    return out


def state_jacobian(p: DeltaParams, x: ArrayLike, u: ArrayLike, f: ArrayLike, pole: float) -> list[float]:
    """d [q'; v'] / d [q; v] at the 18-vector x = [q; v], column-major (18 x 18, column j the
    derivatives with respect to x_j): what an implicit integrator's Newton matrix needs, the
    state block of :func:`plant_jacobian` bit for bit. A kernel (the DeltaRobot FMU's
    Co-Simulation CVODE calls it as generated C).

    Raises:
        ArithmeticError: H or a mass block lost rank (a direct-kinematic or gimbal singularity).
    """
    xl = _as_list(x)
    values = jacobian_values(p, xl[:9], xl[9:], u, f, pole)
    out = []
    for j in range(18):  # d / d x_j: q' = v on top, then da / d x_j
        out += [1.0 if r + 9 == j else 0.0 for r in range(9)]
        out += [values[_SENSITIVITIES + 15 * j + r] for r in range(9)]
    return out


def jacobian_from_values(values: np.ndarray) -> PlantJacobian:
    """:func:`plant_jacobian` from :func:`jacobian_values`' floats: their scatter into the
    matrices (numpy); the KKT system comes solved."""
    flat = values[15:_SENSITIVITIES]
    sens = values[_SENSITIVITIES:].reshape(N_KNOWNS, 15).T
    dx = _DX_TEMPLATE.copy()  # q' = v on top
    dx[9:] = sens[:9]
    out = np.zeros((7, N_KNOWNS))  # dz, dzd, denergy
    out.flat[_OUTPUT_INDEX] = flat[_OUTPUT_SOURCE] * _OUTPUT_SCALE
    return PlantJacobian(values[:9].copy(), values[9:15].copy(), dx, sens[9:].copy(), out[:3], out[3:6], out[6])


#: offsets of the blocks in one arm's 69 kernel values (see :func:`_arm`)
_BLOCKS = dict(mass=0, Ht=9, r1q=18, r1v=27, kq=36, kv=45, pv=54, grad=63)
_ARM_VALUES = 69


def _scatter_layout() -> tuple:
    """Where each kernel value goes in the output derivatives: (flat target index, source index,
    scale) arrays."""
    output: list[tuple[int, int, float]] = []

    def put(target: list, row: int, col: int, ncols: int, arm: int, block: str, entry: int,
            scale: float) -> None:
        target.append((row * ncols + col, _ARM_VALUES * arm + _BLOCKS[block] + entry, scale))

    for i in range(3):
        for r in range(3):
            for c in range(3):
                e = 3 * r + c
                put(output, r, 3 * i + c, N_KNOWNS, i, "Ht", e, 1.0 / 3.0)  # dz/dq = Jv
                put(output, 3 + r, 3 * i + c, N_KNOWNS, i, "pv", e, 1.0 / 3.0)  # dzd/dq
                put(output, 3 + r, 9 + 3 * i + c, N_KNOWNS, i, "Ht", e, 1.0 / 3.0)  # dzd/dv = Jv
        for c in range(3):
            put(output, 6, 3 * i + c, N_KNOWNS, i, "grad", c, 1.0)
            put(output, 6, 9 + 3 * i + c, N_KNOWNS, i, "grad", 3 + c, 1.0)
    index, source, scale = zip(*output)
    return np.array(index), np.array(source), np.array(scale)


_OUTPUT_INDEX, _OUTPUT_SOURCE, _OUTPUT_SCALE = _scatter_layout()
_DX_TEMPLATE = np.hstack([np.zeros((18, 9)), np.vstack([np.eye(9), np.zeros((9, 9))]), np.zeros((18, 6))])
