"""Delta robot dynamics: per-arm Lagrangian model and the stabilised index-1 DAE.

Each arm is an open chain with kinetic and potential energy (arm frame, derivation and symbolic
check in tools/derive_delta_dynamics.py):

- upper arm + gearbox-reflected rotor turning about the servo axis: J1 + Jm (J1 already taken
  about the servo axis), centre of mass at r1;
- forearm: a thin uniform rod of mass m2 and length l2 hanging from the elbow (at l1 from the
  servo axis) along [sin q2 sin q3, cos q2, sin q2 cos q3]. The two parallel bars translate with
  the same velocity field as one rod, and a thin rod has no spin inertia, so
  T = m2/2 (|E'|^2 + l2 E'.u' + l2^2/3 |u'|^2) exactly;
- one third of the plate + payload as a point mass at the arm end.

With mpa = (mp + payload)/3, a = J1 + Jm + (m2 + mpa) l1^2, b = (m2/2 + mpa) l1 l2,
beta = (m2/3 + mpa) l2^2 and s_k = sin q_k, c_k = cos q_k:

    m(q) = [[a,                     b (s1 s2 + c1 c2 c3),  -b c1 s2 s3  ],
            [b (s1 s2 + c1 c2 c3),  beta,                  0            ],
            [-b c1 s2 s3,           0,                     beta s2^2    ]]
    c(q,v) = [b ((s1 c2 - c1 s2 c3) v2^2 - 2 c1 c2 s3 v2 v3 - c1 s2 c3 v3^2),
              b (c1 s2 - s1 c2 c3) v1^2 - beta s2 c2 v3^2,
              b s1 s2 s3 v1^2 + 2 beta s2 c2 v2 v3]
    g(q) = [g (m1 r1 + (m2 + mpa) l1) c1,  g (m2/2 + mpa) l2 c2 c3,  -g (m2/2 + mpa) l2 s2 s3]

The robot: M vdot + C + D v + G = H^T lam + B u + Jv^T f with the Baumgarte-stabilised
constraint hdd + 2 p hd + p^2 h = 0 (double pole at -p).

Solve used by accelerations() (the FMU derivative function, hence hand-written float math):
M is block diagonal with SPD 3x3 arm blocks m_i, inverted in closed form (m23 = 0). Writing
Ht_i = R_i dpsi/dq(q_i) (arm i's wrist Jacobian in the world frame), each arm's wrist responds to
a world force F_i as Pdd_i = A_i + W_i F_i with W_i = Ht_i m_i^-1 Ht_i^T; with F_1 = la + lb,
F_2 = -la, F_3 = -lb the multipliers solve the 6x6 Schur complement H M^-1 H^T

    [[W1 + W2, W1], [W1, W1 + W3]] [la; lb] = [b2 - b1; b3 - b1],  b_i = A_i + 2p Pd_i + p^2 P_i,

by a 3x3 block Cholesky (SPD while H has full rank), and vdot_i = m_i^-1 (rhs_i + Ht_i^T F_i).
Everything is closed-form 3x3 algebra in plain floats (five symmetric 3x3 inverses in all)
instead of a dense 15x15 (or 24x24) KKT solve; at this size numpy call overhead, not flops,
would dominate (about 13 us per call against about 28 us for a list-based 6x6 Cholesky).
The cheaper 3x3 operational-space reduction (sum of W_i^-1) is NOT used: W_i is singular when
arm i is stretched, while the 6x6 complement stays regular there, so the model simulates
through the stretched-arm singularity.

project_to_constraints() (the projection onto the closed loops: the Co-Simulation solver's after
every step, the Model Exchange FMU's at its step events) uses the same algebra: its mass-weighted
corrections M^-1 H^T [la; lb] solve the same Schur complement.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from .kinematics import ARM_COS_SIN, constraint_jacobian
from .params import DeltaParams

__all__ = ["mass_matrix", "coriolis", "gravity", "accelerations", "state_derivative", "energy", "holding_torque",
           "PlantEvaluation", "evaluate_plant", "loop_residual", "project_to_constraints", "F3", "F6", "F9",
           "plant_outputs", "project_state"]

ArrayLike = Sequence[float] | np.ndarray
# Fixed-length float tuples: the kernels below are translated to C for the FMUs (see
# deltafmi/builder/codegen), which makes such tuples C structs and float locals doubles.
F3 = tuple[float, float, float]
F6 = tuple[float, float, float, float, float, float]
F9 = tuple[float, float, float, float, float, float, float, float, float]
F21 = tuple[float, float, float, float, float, float, float, float, float, float, float, float, float,
            float, float, float, float, float, float, float, float]


def _constants(p: DeltaParams) -> tuple[float, float, float, float, float]:
    """Lumped inertia/gravity constants (a, b, beta, g1, g2) shared by the three arms."""
    mpa = (p.mp + p.payload) / 3.0
    a = p.J1 + p.Jm + (p.m2 + mpa) * p.l1 * p.l1
    b = (0.5 * p.m2 + mpa) * p.l1 * p.l2
    beta = (p.m2 / 3.0 + mpa) * p.l2 * p.l2
    g1 = p.g * (p.m1 * p.r1 + (p.m2 + mpa) * p.l1)
    g2 = p.g * (0.5 * p.m2 + mpa) * p.l2
    return a, b, beta, g1, g2


def _as_list(x: ArrayLike) -> list[float]:
    return x.tolist() if isinstance(x, np.ndarray) else [float(t) for t in x]


def mass_matrix(p: DeltaParams, q: ArrayLike) -> np.ndarray:
    """M(q) = diag(m(q_1), m(q_2), m(q_3)), (9, 9) symmetric positive definite (kg m^2)."""
    a, b, beta, _, _ = _constants(p)
    ql = _as_list(q)
    M = np.zeros((9, 9))
    for i in range(3):
        q1, q2, q3 = ql[3 * i:3 * i + 3]
        s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                                  math.sin(q3), math.cos(q3))
        m12 = b * (s1 * s2 + c1 * c2 * c3)
        m13 = -b * c1 * s2 * s3
        M[3 * i:3 * i + 3, 3 * i:3 * i + 3] = [[a, m12, m13], [m12, beta, 0.0],
                                               [m13, 0.0, beta * s2 * s2]]
    return M


def coriolis(p: DeltaParams, q: ArrayLike, v: ArrayLike) -> np.ndarray:
    """Centripetal/Coriolis vector C(q, v), (9,) (N m)."""
    _, b, beta, _, _ = _constants(p)
    ql, vl = _as_list(q), _as_list(v)
    out = []
    for i in range(3):
        q1, q2, q3 = ql[3 * i:3 * i + 3]
        v1, v2, v3 = vl[3 * i:3 * i + 3]
        s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                                  math.sin(q3), math.cos(q3))
        out += [b * ((s1 * c2 - c1 * s2 * c3) * v2 * v2 - 2.0 * c1 * c2 * s3 * v2 * v3
                     - c1 * s2 * c3 * v3 * v3),
                b * (c1 * s2 - s1 * c2 * c3) * v1 * v1 - beta * s2 * c2 * v3 * v3,
                b * s1 * s2 * s3 * v1 * v1 + 2.0 * beta * s2 * c2 * v2 * v3]
    return np.array(out)


def gravity(p: DeltaParams, q: ArrayLike) -> np.ndarray:
    """Gravity vector G(q) = dV/dq, (9,) (N m)."""
    _, _, _, g1, g2 = _constants(p)
    ql = _as_list(q)
    out = []
    for i in range(3):
        q1, q2, q3 = ql[3 * i:3 * i + 3]
        s2 = math.sin(q2)
        out += [g1 * math.cos(q1), g2 * math.cos(q2) * math.cos(q3), -g2 * s2 * math.sin(q3)]
    return np.array(out)


def energy(p: DeltaParams, q: ArrayLike, v: ArrayLike) -> float:
    """Kinetic + potential energy (J); potential zero in the base plane z = 0."""
    mpa = (p.mp + p.payload) / 3.0
    ql, vl = _as_list(q), np.asarray(v, dtype=float)
    kinetic = 0.5 * float(vl @ mass_matrix(p, q) @ vl)
    potential = 0.0
    for i in range(3):
        q1, q2, q3 = ql[3 * i:3 * i + 3]
        s1 = math.sin(q1)
        drop = p.l2 * math.sin(q2) * math.cos(q3)  # forearm height change, elbow -> arm end
        potential += p.g * (p.m1 * p.r1 * s1 + p.m2 * (p.l1 * s1 + 0.5 * drop)
                            + mpa * (p.l1 * s1 + drop))
    return kinetic + potential


def holding_torque(p: DeltaParams, q: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Servo torques holding the robot still at q, the seed's 9x9 solve [B H^T][tau; lam] = G.

    Returns (tau (3,) N m, lam (6,) N).
    """
    A = np.zeros((9, 9))
    A[[0, 3, 6], [0, 1, 2]] = 1.0
    A[:, 3:] = constraint_jacobian(p, q).T
    sol = np.linalg.solve(A, gravity(p, q))
    return sol[:3], sol[3:]


def _arm_mass_inverse(a: float, b: float, beta: float, s1: float, c1: float, s2: float, c2: float,
                      s3: float, c3: float) -> F9:
    """Off-diagonal mass entries (m12, m13, m33) and the inverse (i11, i12, i13, i22, i23, i33)
    of one arm's mass block [[a, m12, m13], [m12, beta, 0], [m13, 0, m33]] (m23 = 0)."""
    m12 = b * (s1 * s2 + c1 * c2 * c3)
    m13 = -b * c1 * s2 * s3
    m33 = beta * s2 * s2
    i11 = beta * m33
    i12 = -m12 * m33
    i13 = -beta * m13
    i22 = a * m33 - m13 * m13
    i23 = m13 * m12
    i33 = a * beta - m12 * m12
    det = a * i11 + m12 * i12 + m13 * i13
    return m12, m13, m33, i11 / det, i12 / det, i13 / det, i22 / det, i23 / det, i33 / det


def _arm_response(i11: float, i12: float, i13: float, i22: float, i23: float, i33: float,
                  h00: float, h01: float, h02: float, h10: float, h11: float, h12: float,
                  h20: float, h21: float, h22: float) -> tuple[F6, F9]:
    """W = Ht m^-1 Ht^T (6 unique entries) and Y = m^-1 Ht^T (9, row-major) of one arm, from the
    inverse mass block (6 unique entries) and the world-frame wrist Jacobian Ht (row-major)."""
    y10 = i11 * h00 + i12 * h01 + i13 * h02
    y20 = i12 * h00 + i22 * h01 + i23 * h02
    y30 = i13 * h00 + i23 * h01 + i33 * h02
    y11 = i11 * h10 + i12 * h11 + i13 * h12
    y21 = i12 * h10 + i22 * h11 + i23 * h12
    y31 = i13 * h10 + i23 * h11 + i33 * h12
    y12 = i11 * h20 + i12 * h21 + i13 * h22
    y22 = i12 * h20 + i22 * h21 + i23 * h22
    y32 = i13 * h20 + i23 * h21 + i33 * h22
    W = (h00 * y10 + h01 * y20 + h02 * y30,
         h00 * y11 + h01 * y21 + h02 * y31,
         h00 * y12 + h01 * y22 + h02 * y32,
         h10 * y11 + h11 * y21 + h12 * y31,
         h10 * y12 + h11 * y22 + h12 * y32,
         h20 * y12 + h21 * y22 + h22 * y32)
    return W, (y10, y11, y12, y20, y21, y22, y30, y31, y32)


def _arm(consts: tuple[float, float, float, float, float], damping: float, pole: float, cr: float,
         sr: float, l0l3: float, l1: float, l2: float, q1: float, q2: float, q3: float, v1: float,
         v2: float, v3: float, u: float, fx: float, fy: float,
         fz: float) -> tuple[F3, F6, F3, F9, F3, F3, float]:
    """One arm's share of the DAE evaluation, as flat float tuples (b, W, x, Y, P, Pd, e).

    b = A + 2p Pd + p^2 P (world), W = Ht m^-1 Ht^T (6 unique), x = m^-1 rhs, Y = m^-1 Ht^T,
    P and Pd the arm's wrist point and velocity (world), e the arm's kinetic + potential energy.
    """
    a, b, beta, g1, g2 = consts
    s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                              math.sin(q3), math.cos(q3))
    # local wrist point, Jacobian rows and velocity-product term
    px, py, pz = l2 * s2 * s3, l0l3 + l1 * c1 + l2 * c2, l1 * s1 + l2 * s2 * c3
    j01, j02 = l2 * c2 * s3, l2 * s2 * c3
    j10, j11 = -l1 * s1, -l2 * s2
    j20, j21, j22 = l1 * c1, l2 * c2 * c3, -l2 * s2 * s3
    w23 = v2 * v2 + v3 * v3
    vv11 = v1 * v1
    v23 = 2.0 * v2 * v3
    ax = l2 * (-s2 * s3 * w23 + c2 * c3 * v23)
    ay = -l1 * c1 * vv11 - l2 * c2 * v2 * v2
    az = -l1 * s1 * vv11 - l2 * (s2 * c3 * w23 + c2 * s3 * v23)
    # rotate to the world: rows of Ht = R J (row 0 of J is [0, j01, j02], row 1 [j10, j11, 0])
    h00, h01, h02 = -sr * j10, cr * j01 - sr * j11, cr * j02
    h10, h11, h12 = cr * j10, sr * j01 + cr * j11, sr * j02
    h20, h21, h22 = j20, j21, j22
    # mass block and its inverse (m23 = 0)
    m12, m13, m33, i11, i12, i13, i22, i23, i33 = _arm_mass_inverse(a, b, beta, s1, c1, s2, c2, s3, c3)
    # generalized forces: B u + Jv^T f - C - D v - G  (Jv_i = Ht_i / 3)
    ft0, ft1, ft2 = fx / 3.0, fy / 3.0, fz / 3.0
    r1 = (u + h00 * ft0 + h10 * ft1 + h20 * ft2 - damping * v1 - g1 * c1
          - b * ((s1 * c2 - c1 * s2 * c3) * v2 * v2 - c1 * c2 * s3 * v23 - c1 * s2 * c3 * v3 * v3))
    r2 = (h01 * ft0 + h11 * ft1 + h21 * ft2 - damping * v2 - g2 * c2 * c3
          - b * (c1 * s2 - s1 * c2 * c3) * vv11 + beta * s2 * c2 * v3 * v3)
    r3 = (h02 * ft0 + h12 * ft1 + h22 * ft2 - damping * v3 + g2 * s2 * s3
          - b * s1 * s2 * s3 * vv11 - beta * s2 * c2 * v23)
    x1 = i11 * r1 + i12 * r2 + i13 * r3
    x2 = i12 * r1 + i22 * r2 + i23 * r3
    x3 = i13 * r1 + i23 * r2 + i33 * r3
    W, Y = _arm_response(i11, i12, i13, i22, i23, i33, h00, h01, h02, h10, h11, h12, h20, h21, h22)
    # world wrist point, velocity, free acceleration; b = A + 2p Pd + p^2 P
    Px, Py, Pz = cr * px - sr * py, sr * px + cr * py, pz
    dx = h00 * v1 + h01 * v2 + h02 * v3
    dy = h10 * v1 + h11 * v2 + h12 * v3
    dz = h20 * v1 + h21 * v2 + h22 * v3
    Ax = h00 * x1 + h01 * x2 + h02 * x3 + cr * ax - sr * ay
    Ay = h10 * x1 + h11 * x2 + h12 * x3 + sr * ax + cr * ay
    Az = h20 * x1 + h21 * x2 + h22 * x3 + az
    tp, pp = 2.0 * pole, pole * pole
    bb = (Ax + tp * dx + pp * Px, Ay + tp * dy + pp * Py, Az + tp * dz + pp * Pz)
    e = (0.5 * (a * vv11 + beta * v2 * v2 + m33 * v3 * v3) + v1 * (m12 * v2 + m13 * v3)
         + g1 * s1 + g2 * s2 * c3)
    return (bb, W, (x1, x2, x3), Y, (Px, Py, Pz),
            (dx, dy, dz), e)


def _sym3_inv(a11: float, a12: float, a13: float, a22: float, a23: float, a33: float) -> F6:
    """Inverse of a symmetric positive definite 3x3 matrix, 6 unique entries in, 6 out."""
    c11 = a22 * a33 - a23 * a23
    c12 = a13 * a23 - a12 * a33
    c13 = a12 * a23 - a13 * a22
    det = a11 * c11 + a12 * c12 + a13 * c13
    if not det > 0.0:
        raise ArithmeticError("constraint Jacobian lost rank: the delta robot is in a "
                              "direct-kinematic singularity (or a gimbal one, sin q_i2 = 0)")
    return (c11 / det, c12 / det, c13 / det, (a11 * a33 - a13 * a13) / det,
            (a12 * a13 - a11 * a23) / det, (a11 * a22 - a12 * a12) / det)


def _schur_factor(W1: F6, W2: F6, W3: F6) -> F21:
    """Factor [[W1 + W2, W1], [W1, W1 + W3]] (6 unique entries per W) by 3x3 block elimination.

    This is a block Cholesky of the SPD 6x6 complement H M^-1 H^T; its leading block P and the
    Schur complement Z of that block are SPD whenever the whole matrix is. Returns the 21 floats
    (P^-1 (6 unique), X = P^-1 W1 (9, row-major), Z^-1 (6 unique)) that _schur_solve takes.
    """
    a11, a12, a13, a22, a23, a33 = W1
    p11, p12, p13, p22, p23, p33 = _sym3_inv(a11 + W2[0], a12 + W2[1], a13 + W2[2],
                                             a22 + W2[3], a23 + W2[4], a33 + W2[5])
    # X = P^-1 W1 (3x3, row-major)
    x11 = p11 * a11 + p12 * a12 + p13 * a13
    x12 = p11 * a12 + p12 * a22 + p13 * a23
    x13 = p11 * a13 + p12 * a23 + p13 * a33
    x21 = p12 * a11 + p22 * a12 + p23 * a13
    x22 = p12 * a12 + p22 * a22 + p23 * a23
    x23 = p12 * a13 + p22 * a23 + p23 * a33
    x31 = p13 * a11 + p23 * a12 + p33 * a13
    x32 = p13 * a12 + p23 * a22 + p33 * a23
    x33 = p13 * a13 + p23 * a23 + p33 * a33
    # Z = (W1 + W3) - W1 X, symmetric
    z11, z12, z13, z22, z23, z33 = _sym3_inv(
        a11 + W3[0] - (a11 * x11 + a12 * x21 + a13 * x31),
        a12 + W3[1] - (a11 * x12 + a12 * x22 + a13 * x32),
        a13 + W3[2] - (a11 * x13 + a12 * x23 + a13 * x33),
        a22 + W3[3] - (a12 * x12 + a22 * x22 + a23 * x32),
        a23 + W3[4] - (a12 * x13 + a22 * x23 + a23 * x33),
        a33 + W3[5] - (a13 * x13 + a23 * x23 + a33 * x33))
    return (p11, p12, p13, p22, p23, p33, x11, x12, x13, x21, x22, x23, x31, x32, x33,
            z11, z12, z13, z22, z23, z33)


def _schur_solve(factors: F21, r: F6) -> F6:
    """Solve [[W1 + W2, W1], [W1, W1 + W3]] [la; lb] = r (6 floats) with _schur_factor's factors."""
    (p11, p12, p13, p22, p23, p33, x11, x12, x13, x21, x22, x23, x31, x32, x33,
     z11, z12, z13, z22, z23, z33) = factors
    s1, s2, s3, u1, u2, u3 = r
    t1 = u1 - (x11 * s1 + x21 * s2 + x31 * s3)
    t2 = u2 - (x12 * s1 + x22 * s2 + x32 * s3)
    t3 = u3 - (x13 * s1 + x23 * s2 + x33 * s3)
    lb1 = z11 * t1 + z12 * t2 + z13 * t3
    lb2 = z12 * t1 + z22 * t2 + z23 * t3
    lb3 = z13 * t1 + z23 * t2 + z33 * t3
    # la = P^-1 r1 - X lb
    la1 = p11 * s1 + p12 * s2 + p13 * s3 - (x11 * lb1 + x12 * lb2 + x13 * lb3)
    la2 = p12 * s1 + p22 * s2 + p23 * s3 - (x21 * lb1 + x22 * lb2 + x23 * lb3)
    la3 = p13 * s1 + p23 * s2 + p33 * s3 - (x31 * lb1 + x32 * lb2 + x33 * lb3)
    return la1, la2, la3, lb1, lb2, lb3


def _evaluate(p: DeltaParams, q: ArrayLike, v: ArrayLike, u: ArrayLike, f: ArrayLike,
              pole: float) -> tuple[list[float], F6, tuple[tuple[F3, F3, float], ...]]:
    """Solve the DAE at one point: (vdot list, lam tuple, per-arm (P, Pd, e) results)."""
    consts = _constants(p)
    ql, vl = _as_list(q), _as_list(v)
    u1, u2, u3 = _as_list(u)
    fx, fy, fz = _as_list(f)
    l0l3, l1, l2, dmp = p.l0 - p.l3, p.l1, p.l2, p.damping
    pole = float(pole)
    (cA, sA), (cB, sB), (cC, sC) = ARM_COS_SIN
    arm1 = _arm(consts, dmp, pole, cA, sA, l0l3, l1, l2, ql[0], ql[1], ql[2],
                vl[0], vl[1], vl[2], u1, fx, fy, fz)
    arm2 = _arm(consts, dmp, pole, cB, sB, l0l3, l1, l2, ql[3], ql[4], ql[5],
                vl[3], vl[4], vl[5], u2, fx, fy, fz)
    arm3 = _arm(consts, dmp, pole, cC, sC, l0l3, l1, l2, ql[6], ql[7], ql[8],
                vl[6], vl[7], vl[8], u3, fx, fy, fz)
    b1, W1, x1, Y1 = arm1[0], arm1[1], arm1[2], arm1[3]
    b2, W2, x2, Y2 = arm2[0], arm2[1], arm2[2], arm2[3]
    b3, W3, x3, Y3 = arm3[0], arm3[1], arm3[2], arm3[3]
    lam = _schur_solve(_schur_factor(W1, W2, W3), (b2[0] - b1[0], b2[1] - b1[1], b2[2] - b1[2],
                                                   b3[0] - b1[0], b3[1] - b1[1], b3[2] - b1[2]))
    la0, la1, la2, lb0, lb1, lb2 = lam
    # vdot = m^-1 rhs + M^-1 H^T lam, i.e. x minus the response to -lam
    vdot = _subtract_response([x1[0], x1[1], x1[2], x2[0], x2[1], x2[2], x3[0], x3[1], x3[2]],
                              Y1, Y2, Y3, (-la0, -la1, -la2, -lb0, -lb1, -lb2))
    return vdot, lam, ((arm1[4], arm1[5], arm1[6]), (arm2[4], arm2[5], arm2[6]), (arm3[4], arm3[5], arm3[6]))


def accelerations(p: DeltaParams, q: ArrayLike, v: ArrayLike, u: ArrayLike, f: ArrayLike,
                  pole: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """Joint accelerations and multipliers of the Baumgarte-stabilised index-1 DAE.

    Solves M vdot + C + D v + G = H^T lam + B u + Jv^T f together with
    H vdot + Hd v + 2 pole H v + pole^2 h = 0 (see the module docstring for the method).

    Args:
        p: robot parameters.
        q, v: joint angles (rad) and rates (rad/s), shape (9,), arm-major.
        u: servo torques (N m), shape (3,).
        f: external force on the wrist (N, world frame), shape (3,).
        pole: Baumgarte pole p (1/s); constraint drift decays like exp(-p t).

    Returns:
        (vdot (9,) rad/s^2, lam (6,) N).
    """
    vdot, lam, _ = _evaluate(p, q, v, u, f, pole)
    return np.array(vdot), np.array(lam)


def state_derivative(p: DeltaParams, x: ArrayLike, u: ArrayLike, f: ArrayLike, pole: float = 5.0) -> list[float]:
    """d/dt [q; v] = [v; vdot] for the 18-vector x = [q; v] (accelerations() without the numpy
    arrays: what an integrator calls, as a plain list)."""
    xl = _as_list(x)
    vdot, _, _ = _evaluate(p, xl[:9], xl[9:], u, f, pole)
    return xl[9:] + vdot


class PlantEvaluation(NamedTuple):
    """Everything a simulation step needs from one DAE evaluation (see evaluate_plant)."""

    vdot: np.ndarray  #: joint accelerations (9,), rad/s^2
    lam: np.ndarray  #: constraint multipliers (6,), N
    z: np.ndarray  #: wrist position (3,), m (as wrist_position)
    zd: np.ndarray  #: wrist velocity (3,), m/s (as wrist_velocity)
    residual: float  #: Euclidean norm of the loop-closure residual h(q), m
    energy: float  #: kinetic + potential energy, J (as energy)


def evaluate_plant(p: DeltaParams, q: ArrayLike, v: ArrayLike, u: ArrayLike, f: ArrayLike,
                   pole: float = 5.0) -> PlantEvaluation:
    """accelerations() plus the wrist, constraint residual and energy from the same pass.

    For a simulation component that needs all of them at every derivative evaluation: about
    1 us more than accelerations() alone instead of separate numpy calls for each output.
    """
    vdot, lam, arms = _evaluate(p, q, v, u, f, pole)
    z, zd, residual, energy = _wrist(arms)
    return PlantEvaluation(np.array(vdot), np.array(lam), np.array(z), np.array(zd), residual, energy)


def plant_outputs(p: DeltaParams, q: ArrayLike, v: ArrayLike, u: ArrayLike, f: ArrayLike,
                  pole: float = 5.0) -> tuple[F3, F3, F3, F3, F6, float, float]:
    """The DeltaRobot component's outputs from one evaluation: servo angles q[0::3], servo rates
    v[0::3], wrist position and velocity, constraint multipliers, loop residual |h| and energy
    (as evaluate_plant, without arrays: the kernel the FMU's C layer runs)."""
    ql, vl = _as_list(q), _as_list(v)
    _, lam, arms = _evaluate(p, ql, vl, u, f, pole)
    z, zd, residual, energy = _wrist(arms)
    return (ql[0], ql[3], ql[6]), (vl[0], vl[3], vl[6]), z, zd, lam, residual, energy


def _wrist(arms: tuple[tuple[F3, F3, float], ...]) -> tuple[F3, F3, float, float]:
    """Wrist position and velocity (the arms' mean), loop residual |h| and energy from the arms."""
    (P1, D1, e1), (P2, D2, e2), (P3, D3, e3) = arms
    h = [P1[k] - P2[k] for k in range(3)] + [P1[k] - P3[k] for k in range(3)]
    z = ((P1[0] + P2[0] + P3[0]) / 3.0, (P1[1] + P2[1] + P3[1]) / 3.0, (P1[2] + P2[2] + P3[2]) / 3.0)
    zd = ((D1[0] + D2[0] + D3[0]) / 3.0, (D1[1] + D2[1] + D3[1]) / 3.0, (D1[2] + D2[2] + D3[2]) / 3.0)
    return z, zd, math.sqrt(sum(t * t for t in h)), e1 + e2 + e3


# -------------------------------------------------------------- projection onto the closed loops

def _arm_wrist(cr: float, sr: float, l0l3: float, l1: float, l2: float, q1: float, q2: float,
               q3: float, v1: float, v2: float, v3: float) -> F6:
    """World wrist point R psi(q_i) and velocity R dpsi/dq(q_i) v_i of one arm (6 floats)."""
    s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                              math.sin(q3), math.cos(q3))
    px, py = l2 * s2 * s3, l0l3 + l1 * c1 + l2 * c2
    dx = l2 * (c2 * s3 * v2 + s2 * c3 * v3)
    dy = -l1 * s1 * v1 - l2 * s2 * v2
    return (cr * px - sr * py, sr * px + cr * py, l1 * s1 + l2 * s2 * c3,
            cr * dx - sr * dy, sr * dx + cr * dy, l1 * c1 * v1 + l2 * (c2 * c3 * v2 - s2 * s3 * v3))


def _arm_linearization(a: float, b: float, beta: float, cr: float, sr: float, l0l3: float,
                       l1: float, l2: float, q1: float, q2: float, q3: float, v1: float,
                       v2: float, v3: float) -> tuple[F6, F6, F9]:
    """One arm at (q_i, v_i), with the closed forms of _arm: (wrist, W, Y).

    wrist: world wrist point and velocity (6 floats, as _arm_wrist); W = Ht m^-1 Ht^T (6 unique);
    Y = m^-1 Ht^T (9, row-major).
    """
    s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                              math.sin(q3), math.cos(q3))
    px, py = l2 * s2 * s3, l0l3 + l1 * c1 + l2 * c2
    j01, j02 = l2 * c2 * s3, l2 * s2 * c3
    j10, j11 = -l1 * s1, -l2 * s2
    h00, h01, h02 = -sr * j10, cr * j01 - sr * j11, cr * j02
    h10, h11, h12 = cr * j10, sr * j01 + cr * j11, sr * j02
    h20, h21, h22 = l1 * c1, l2 * c2 * c3, -l2 * s2 * s3
    m12, m13, m33, i11, i12, i13, i22, i23, i33 = _arm_mass_inverse(a, b, beta, s1, c1, s2, c2, s3, c3)
    W, Y = _arm_response(i11, i12, i13, i22, i23, i33, h00, h01, h02, h10, h11, h12, h20, h21, h22)
    return ((cr * px - sr * py, sr * px + cr * py, l1 * s1 + l2 * s2 * c3,
             h00 * v1 + h01 * v2 + h02 * v3, h10 * v1 + h11 * v2 + h12 * v3,
             h20 * v1 + h21 * v2 + h22 * v3), W, Y)


def _arms_linearization(a: float, b: float, beta: float, l0l3: float, l1: float, l2: float, ql: list[float],
                        vl: list[float]) -> tuple[tuple[F6, F6, F9], tuple[F6, F6, F9], tuple[F6, F6, F9]]:
    """_arm_linearization of the three arms at the joint angles and rates ql, vl (arm-major)."""
    (cA, sA), (cB, sB), (cC, sC) = ARM_COS_SIN
    return (_arm_linearization(a, b, beta, cA, sA, l0l3, l1, l2, ql[0], ql[1], ql[2], vl[0], vl[1], vl[2]),
            _arm_linearization(a, b, beta, cB, sB, l0l3, l1, l2, ql[3], ql[4], ql[5], vl[3], vl[4], vl[5]),
            _arm_linearization(a, b, beta, cC, sC, l0l3, l1, l2, ql[6], ql[7], ql[8], vl[6], vl[7], vl[8]))


def _loop_residuals(arm1: F6, arm2: F6, arm3: F6) -> tuple[F6, F6]:
    """h(q) and H(q) v (6 floats each: arm 1 - arm 2, then arm 1 - arm 3) from the three arms'
    world wrist points and velocities (6 floats each, as _arm_wrist)."""
    x1, y1, z1, u1, v1, w1 = arm1
    x2, y2, z2, u2, v2, w2 = arm2
    x3, y3, z3, u3, v3, w3 = arm3
    return ((x1 - x2, y1 - y2, z1 - z2, x1 - x3, y1 - y3, z1 - z3),
            (u1 - u2, v1 - v2, w1 - w2, u1 - u3, v1 - v3, w1 - w3))


def _subtract_response(x: list[float], Y1: F9, Y2: F9, Y3: F9, lam: F6) -> list[float]:
    """x - M^-1 H^T [la; lb] (arm-major): arm 1 moves by -Y1 (la + lb), arm 2 by Y2 la, arm 3
    by Y3 lb (the world forces F_1 = la + lb, F_2 = -la, F_3 = -lb of the module docstring)."""
    la0, la1, la2, lb0, lb1, lb2 = lam
    F0, F1, F2 = la0 + lb0, la1 + lb1, la2 + lb2
    return [x[0] - (Y1[0] * F0 + Y1[1] * F1 + Y1[2] * F2),
            x[1] - (Y1[3] * F0 + Y1[4] * F1 + Y1[5] * F2),
            x[2] - (Y1[6] * F0 + Y1[7] * F1 + Y1[8] * F2),
            x[3] + (Y2[0] * la0 + Y2[1] * la1 + Y2[2] * la2),
            x[4] + (Y2[3] * la0 + Y2[4] * la1 + Y2[5] * la2),
            x[5] + (Y2[6] * la0 + Y2[7] * la1 + Y2[8] * la2),
            x[6] + (Y3[0] * lb0 + Y3[1] * lb1 + Y3[2] * lb2),
            x[7] + (Y3[3] * lb0 + Y3[4] * lb1 + Y3[5] * lb2),
            x[8] + (Y3[6] * lb0 + Y3[7] * lb1 + Y3[8] * lb2)]


def _closure(l0l3: float, l1: float, l2: float, ql: list[float], vl: list[float]) -> tuple[F6, F6]:
    """h(q) and H(q) v (as _loop_residuals) straight from the nine joint angles and rates."""
    (cA, sA), (cB, sB), (cC, sC) = ARM_COS_SIN
    return _loop_residuals(_arm_wrist(cA, sA, l0l3, l1, l2, ql[0], ql[1], ql[2], vl[0], vl[1], vl[2]),
                           _arm_wrist(cB, sB, l0l3, l1, l2, ql[3], ql[4], ql[5], vl[3], vl[4], vl[5]),
                           _arm_wrist(cC, sC, l0l3, l1, l2, ql[6], ql[7], ql[8], vl[6], vl[7], vl[8]))


def loop_residual(p: DeltaParams, q: ArrayLike) -> float:
    """Euclidean norm of the loop-closure residual h(q) (m): what a drift check needs, in floats."""
    h, _ = _closure(p.l0 - p.l3, p.l1, p.l2, _as_list(q), [0.0] * 9)
    return math.hypot(*h)


def loop_drifted(p: DeltaParams, q: ArrayLike, tolerance: float) -> bool:
    """Whether the loop-closure residual |h(q)| (as the plant's ``residual`` output computes it)
    exceeds ``tolerance`` (never for a tolerance of 0): the drift check after an integrator step."""
    if not tolerance > 0.0:
        return False
    h, _ = _closure(p.l0 - p.l3, p.l1, p.l2, _as_list(q), [0.0] * 9)
    return math.sqrt(sum(t * t for t in h)) > tolerance


def project_to_constraints(p: DeltaParams, q: ArrayLike, v: ArrayLike, *, tol: float = 1e-13,
                           max_iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Nearest (q, v) on the constraint manifold h(q) = 0, H(q) v = 0 in the mass-matrix metric
    (:func:`project_state` as arrays).

    Gauss-Newton steps dq = -M^-1 H^T S^-1 h with S = H M^-1 H^T (the correction of least
    M-norm) until |h(q)| <= tol. Each step also takes dv = -M^-1 H^T S^-1 H v, the velocity
    change of least kinetic energy that satisfies H v = 0 where the step starts. Over the step H
    changes, which leaves H v of order |dq| |v| at the new q; one more dv with that H v (same
    operator) leaves order |dq|^2 |v|. From an integrator's drift (|h| ~ 1e-9 m) one step
    reaches rounding level.

    A solver calls this after every step (the DeltaRobot FMU's Co-Simulation CVODE), hence the
    plain float algebra of accelerations(): M^-1 blockwise and S = [[W1 + W2, W1], [W1, W1 + W3]]
    by the 3x3 block Cholesky, one factorization per step (about 14 us per call from drift,
    against 40 us with dense numpy).

    Args:
        p: robot parameters (the mass matrix depends on them).
        q, v: joint angles (rad) and rates (rad/s), shape (9,), arm-major.
        tol: bound on the Euclidean norm of h(q) (m) that ends the iteration.
        max_iterations: at most this many steps (at least one); if tol is not reached by then,
            the last iterate is returned.

    Returns:
        (q, v) on the manifold, new arrays.

    Raises:
        ArithmeticError: H lost rank (a direct-kinematic singularity).
    """
    ql, vl = _project(p, q, v, tol, max_iterations)
    return np.array(ql), np.array(vl)


def project_state(p: DeltaParams, q: ArrayLike, v: ArrayLike) -> tuple[list[float], list[float]]:
    """:func:`project_to_constraints` with its default tolerance as a float kernel: (q, v) on the
    closed loops as two lists of nine floats. The FMUs compile it (their Co-Simulation CVODE's
    projection, in C)."""
    return _project(p, q, v, 1e-13, 8)


def _project(p: DeltaParams, q: ArrayLike, v: ArrayLike, tol: float,
             max_iterations: int) -> tuple[list[float], list[float]]:
    # the iteration ends on sqrt(sum h_k^2), not math.hypot: CPython's own algorithm, which the
    # C translation cannot reproduce to the bit
    a, b, beta, _, _ = _constants(p)
    l0l3, l1, l2 = p.l0 - p.l3, p.l1, p.l2
    ql, vl = _as_list(q), _as_list(v)
    for _ in range(max_iterations):
        (w1, W1, Y1), (w2, W2, Y2), (w3, W3, Y3) = _arms_linearization(a, b, beta, l0l3, l1, l2, ql, vl)
        h, Hv = _loop_residuals(w1, w2, w3)
        factors = _schur_factor(W1, W2, W3)
        ql = _subtract_response(ql, Y1, Y2, Y3, _schur_solve(factors, h))
        vl = _subtract_response(vl, Y1, Y2, Y3, _schur_solve(factors, Hv))
        h, Hv = _closure(l0l3, l1, l2, ql, vl)
        if math.sqrt(sum(t * t for t in h)) <= tol:
            break
    vl = _subtract_response(vl, Y1, Y2, Y3, _schur_solve(factors, Hv))
    return ql, vl
