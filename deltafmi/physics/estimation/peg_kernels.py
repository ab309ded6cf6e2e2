"""The peg estimator's arithmetic as float kernels: one sample's prediction (the Runge-Kutta step of
the reduced state with the process Jacobian's columns that are due), the contact law's
linearisation, and the hole locator's search.

Written in the float subset of deltafmi/builder/codegen/translate.py (floats, ints, fixed-length
tuples and lists, ``math``; no numpy), so that the PegEstimator FMU compiles them into its kernel
library (``NativeKernels(functions=...)``, fmu_src/peg_estimator.py) and its filter calls them
mid-sample; the Python functions are the reference and the fallback (the same numbers, bit for bit,
as the generator keeps Python's operation order). The numpy functions of :mod:`.wrist_process` and
:mod:`.peg_contact` are made of them. Their mechanics: those modules' docstrings.

Layouts (flat float sequences, what a compiled function returns):

- :func:`prediction`: the state after the sample period (12), then the 18 columns of d s'/d[s, W]
  (rows 6..11, the accelerations; 6 each, in column order), zeros for the columns not due;
- :func:`contact_linearization`: the law's wrench c (6), the 16 columns of dc/d[s, h] (6 each,
  zeros for those of s with ``hole_only``), the number of active contacts (1);
- :func:`hole_search`: 1.0 and the hole (4) that explains the felt wrench best, or five zeros;
- :func:`servo_kinematics`: the servo angles (3) at the plate position and their rows of dq/dz (9).
"""
from __future__ import annotations

import math

from ..delta.control_law import _inv3
from ..delta.kinematics import ARM_COS_SIN
from ..delta.params import ARM_ROTATIONS, DeltaParams
from ..delta_wrist.dynamics import state_derivative
from ..delta_wrist.params import WristMount
from ..peg.contact import placed_peg_wrench
from ..peg.params import Hole, Peg, PegContact
from ..wrist.kernels import WristConstants, cross, joint_axes, tip_position, tool_rotation

__all__ = ["POSITION_STEP", "RATE_STEP", "HOLE_STEPS", "JACOBIAN_COLUMNS", "PREDICTION_SIZE", "LINEARIZATION_SIZE", "FUNCTIONS",
           "joint_angles", "full_state", "servo_kinematics", "tool_pose", "reduced_derivative", "prediction", "process_columns",
           "contact_linearization",
           "hole_search"]

#: forward-difference steps of the reduced state's columns: positions (m, rad), rates (m/s, rad/s)
POSITION_STEP = 1e-7
RATE_STEP = 1e-6
#: forward-difference steps of the hole's columns (m, m, rad, rad)
HOLE_STEPS = (1e-7, 1e-7, 1e-6, 1e-6)
JACOBIAN_COLUMNS = 18
PREDICTION_SIZE = 12 + 6 * JACOBIAN_COLUMNS
LINEARIZATION_SIZE = 6 + 6 * 16 + 1
_GRID = 20e-6  # m, the locator's grid (peg_contact's docstring)
#: (cos, sin) of the arm rotations as ARM_ROTATIONS holds them (the Jacobians' frames)
_ARMS = tuple((float(r[0][0]), float(r[1][0])) for r in ARM_ROTATIONS)

F3 = tuple[float, float, float]
F9 = tuple[float, float, float, float, float, float, float, float, float]


# ------------------------------------------------------------------------ kinematics of the loops

def _arm_angles(p: DeltaParams, c: float, s: float, z: F3) -> F3:
    """One arm's angles reaching the plate centre z (world), elbow out: the closed form of
    deltafmi.physics.delta.kinematics.inverse_kinematics."""
    x, y, zz = c * z[0] + s * z[1], -s * z[0] + c * z[1], z[2]
    l1, l2 = p.l1, p.l2
    Y = y - (p.l0 - p.l3)
    rho = math.sqrt(Y * Y + zz * zz)
    k = (x * x + Y * Y + zz * zz + l1 * l1 - l2 * l2) / (2.0 * l1)
    if rho == 0.0 or abs(k) > rho:
        raise ValueError("the estimated plate position is out of the delta's reach")
    q1 = math.atan2(zz, Y) + math.acos(min(1.0, k / rho))
    if q1 > math.pi:
        q1 -= 2.0 * math.pi
    ux, uy, uz = x, Y - l1 * math.cos(q1), zz - l1 * math.sin(q1)
    if uz >= 0.0:
        raise ValueError("the estimated plate position needs a forearm pointing upwards")
    return q1, math.atan2(-math.sqrt(ux * ux + uz * uz), uy), math.atan2(-ux, -uz)


def joint_angles(p: DeltaParams, z: F3) -> list[float]:
    """The nine joint angles placing the plate centre at z (arm-major)."""
    (cA, sA), (cB, sB), (cC, sC) = ARM_COS_SIN
    return list(_arm_angles(p, cA, sA, z) + _arm_angles(p, cB, sB, z) + _arm_angles(p, cC, sC, z))


def _arm_jacobian(p: DeltaParams, c: float, s: float, q1: float, q2: float, q3: float) -> F9:
    """R_i dpsi/dq(q_i), row-major: one arm's end against its angles, world frame."""
    s1, c1, s2, c2, s3, c3 = math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2), math.sin(q3), math.cos(q3)
    l1, l2 = p.l1, p.l2
    j0, j1, j2 = 0.0, l2 * c2 * s3, l2 * s2 * c3
    j3, j4, j5 = -l1 * s1, -l2 * s2, 0.0
    return (c * j0 - s * j3, c * j1 - s * j4, c * j2 - s * j5, s * j0 + c * j3, s * j1 + c * j4, s * j2 + c * j5,
            l1 * c1, l2 * c2 * c3, -l2 * s2 * s3)


def _arm_inverse(p: DeltaParams, c: float, s: float, q1: float, q2: float, q3: float) -> F9:
    inverse = _inv3(_arm_jacobian(p, c, s, q1, q2, q3))
    if inverse is None:
        raise ArithmeticError("an arm of the delta is singular at the estimated plate position")
    return inverse


def full_state(p: DeltaParams, s: list[float]) -> tuple[list[float], tuple]:
    """(x (24), T = dq/dz (9 x 3 row-major, 27)): the plant's state [q, qw, v, vw] on its loops
    for the reduced state s (12), v = T zd."""
    q = joint_angles(p, (s[0], s[1], s[2]))
    (cA, sA), (cB, sB), (cC, sC) = _ARMS
    T = (_arm_inverse(p, cA, sA, q[0], q[1], q[2]) + _arm_inverse(p, cB, sB, q[3], q[4], q[5])
         + _arm_inverse(p, cC, sC, q[6], q[7], q[8]))
    v = [T[3 * j] * s[6] + T[3 * j + 1] * s[7] + T[3 * j + 2] * s[8] for j in range(9)]
    return q + [s[3], s[4], s[5]] + v + [s[9], s[10], s[11]], T


def servo_kinematics(p: DeltaParams, z: list[float]) -> list[float]:
    """The servo angles at the plate centre z (3) and their rows of T = dq/dz (3 x 3 row-major):
    the angle measurement's prediction and Jacobian (12 floats)."""
    q = joint_angles(p, (z[0], z[1], z[2]))
    (cA, sA), (cB, sB), (cC, sC) = _ARMS
    t1 = _arm_inverse(p, cA, sA, q[0], q[1], q[2])
    t2 = _arm_inverse(p, cB, sB, q[3], q[4], q[5])
    t3 = _arm_inverse(p, cC, sC, q[6], q[7], q[8])
    return [q[0], q[3], q[6], t1[0], t1[1], t1[2], t2[0], t2[1], t2[2], t3[0], t3[1], t3[2]]


def _arm_acceleration(p: DeltaParams, c: float, s: float, q1: float, q2: float, q3: float, v1: float, v2: float,
                      v3: float, a1: float, a2: float, a3: float) -> F3:
    """R_i (dpsi/dq a_i + d/dt(dpsi/dq) v_i): one arm end's acceleration, world frame."""
    s1, c1, s2, c2, s3, c3 = math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2), math.sin(q3), math.cos(q3)
    l1, l2 = p.l1, p.l2
    w = v2 * v2 + v3 * v3
    lx = l2 * c2 * s3 * a2 + l2 * s2 * c3 * a3 + l2 * (-s2 * s3 * w + 2.0 * c2 * c3 * v2 * v3)
    ly = -l1 * s1 * a1 - l2 * s2 * a2 + (-l1 * c1 * v1 * v1 - l2 * c2 * v2 * v2)
    lz = (l1 * c1 * a1 + l2 * c2 * c3 * a2 - l2 * s2 * s3 * a3
          + (-l1 * s1 * v1 * v1 - l2 * (s2 * c3 * w + 2.0 * c2 * s3 * v2 * v3)))
    return c * lx - s * ly, s * lx + c * ly, lz


def _accelerations(p: DeltaParams, w: WristConstants, m: WristMount, x: list[float], u: list[float],
                   tau: list[float], W: list[float], pole: float) -> list[float]:
    """[zdd, qddw] (6) of the plant at its full state x on the loops under (u, tau, W): zdd the
    mean of the arm ends' accelerations, Jv vdot + dJv/dt v."""
    xd = state_derivative(p, w, m, x, u, tau, W[0:3], W[3:6], pole)
    (cA, sA), (cB, sB), (cC, sC) = _ARMS
    e1 = _arm_acceleration(p, cA, sA, x[0], x[1], x[2], x[12], x[13], x[14], xd[12], xd[13], xd[14])
    e2 = _arm_acceleration(p, cB, sB, x[3], x[4], x[5], x[15], x[16], x[17], xd[15], xd[16], xd[17])
    e3 = _arm_acceleration(p, cC, sC, x[6], x[7], x[8], x[18], x[19], x[20], xd[18], xd[19], xd[20])
    return [(e1[0] + e2[0] + e3[0]) / 3.0, (e1[1] + e2[1] + e3[1]) / 3.0, (e1[2] + e2[2] + e3[2]) / 3.0,
            xd[21], xd[22], xd[23]]


def tool_pose(w: WristConstants, m: WristMount, s: list[float]) -> tuple[F3, F9, F3, F3]:
    """(tip, R row-major, tip velocity, omega), world, as deltafmi.physics.peg.plant.tool_pose
    computes them from the full state: O = z + mount, tip = O + p(qw), omega = J_w vw,
    v_tip = zd + omega x p(qw)."""
    qw = (s[3], s[4], s[5])
    rel = tip_position(w, qw)
    a1, a2, a3 = joint_axes(qw)
    omega = (a1[0] * s[9] + a2[0] * s[10] + a3[0] * s[11], a1[1] * s[9] + a2[1] * s[10] + a3[1] * s[11],
             a1[2] * s[9] + a2[2] * s[10] + a3[2] * s[11])
    spin = cross(omega, rel)
    tip = (s[0] + m.x + rel[0], s[1] + m.y + rel[1], s[2] + m.z + rel[2])
    return tip, tool_rotation(qw), (s[6] + spin[0], s[7] + spin[1], s[8] + spin[2]), omega


# ------------------------------------------------------------------------------------ prediction

def reduced_derivative(p: DeltaParams, w: WristConstants, m: WristMount, s: list[float], u: list[float],
                       tau: list[float], W: list[float], pole: float) -> list[float]:
    """s' (12) under servo torques u, wrist torques tau and the contact wrench W (6)."""
    x = full_state(p, s)[0]
    return [s[6], s[7], s[8], s[9], s[10], s[11]] + _accelerations(p, w, m, x, u, tau, W, pole)


def _runge_kutta(p: DeltaParams, w: WristConstants, m: WristMount, s: list[float], u: list[float], tau: list[float],
                 W: list[float], pole: float, period: float, substeps: int, a0: list[float]) -> list[float]:
    """s after the period, classical Runge-Kutta in substeps steps; a0: the accelerations at s.
    One loop over the stages (a C loop: the plant is inlined once)."""
    h = period / substeps
    y = s
    k1 = [0.0] * 12
    k2 = [0.0] * 12
    k3 = [0.0] * 12
    stage = 0
    for i in range(4 * substeps):
        if i == 0:
            k = [s[6], s[7], s[8], s[9], s[10], s[11]] + a0
        else:
            k = reduced_derivative(p, w, m, y, u, tau, W, pole)
        if stage == 0:
            k1 = k
            y = [s[j] + 0.5 * h * k[j] for j in range(12)]
        elif stage == 1:
            k2 = k
            y = [s[j] + 0.5 * h * k[j] for j in range(12)]
        elif stage == 2:
            k3 = k
            y = [s[j] + h * k[j] for j in range(12)]
        else:
            s = [s[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k[j]) for j in range(12)]
            y = s
        stage += 1
        if stage == 4:
            stage = 0
    return s


def _column(p: DeltaParams, w: WristConstants, m: WristMount, s: list[float], x0: list[float], T: tuple,
            a0: list[float], u: list[float], tau: list[float], W: list[float], pole: float, k: int) -> list[float]:
    """Column k of d[zdd, qddw]/d[s, W] (6): the state's by forward differences (positions through
    the inverse kinematics, rates through v = T zd at fixed q), the wrench's exact by linearity."""
    h = POSITION_STEP if k < 6 else RATE_STEP
    Wk = W
    if k >= 12:
        x = x0
        Wk = [W[j] + 1.0 if j == k - 12 else W[j] for j in range(6)]
    elif k < 3:
        x = full_state(p, [s[j] + h if j == k else s[j] for j in range(12)])[0]
    elif k < 6:
        x = [x0[j] + h if j == 6 + k else x0[j] for j in range(24)]  # qw
    elif k < 9:
        x = [x0[j] + h * T[3 * (j - 12) + k - 6] if j >= 12 and j < 21 else x0[j] for j in range(24)]
    else:
        x = [x0[j] + h if j == 12 + k else x0[j] for j in range(24)]  # vw
    a = _accelerations(p, w, m, x, u, tau, Wk, pole)
    if k >= 12:
        return [a[j] - a0[j] for j in range(6)]
    return [(a[j] - a0[j]) / h for j in range(6)]


def prediction(p: DeltaParams, w: WristConstants, m: WristMount, s: list[float], u: list[float], tau: list[float],
               W: list[float], pole: float, period: float, substeps: int, first: int, count: int) -> list[float]:
    """One sample's prediction with u, tau and W held (module docstring's layout): s after
    ``period`` (classical Runge-Kutta, ``substeps`` steps), and the process Jacobian's columns
    first, first + 1, ... (count of them, modulo 18), evaluated at s; the Runge-Kutta step's first
    stage is the Jacobian's base point."""
    x0, T = full_state(p, s)
    a0 = _accelerations(p, w, m, x0, u, tau, W, pole)
    return (_runge_kutta(p, w, m, s, u, tau, W, pole, period, substeps, a0)
            + _columns(p, w, m, s, x0, T, a0, u, tau, W, pole, first, count))


def process_columns(p: DeltaParams, w: WristConstants, m: WristMount, s: list[float], u: list[float],
                    tau: list[float], W: list[float], pole: float, first: int, count: int) -> list[float]:
    """The columns of :func:`prediction` alone (108 floats: 18 columns of 6, zeros where not due)."""
    x0, T = full_state(p, s)
    a0 = _accelerations(p, w, m, x0, u, tau, W, pole)
    return _columns(p, w, m, s, x0, T, a0, u, tau, W, pole, first, count)


def _columns(p: DeltaParams, w: WristConstants, m: WristMount, s: list[float], x0: list[float], T: tuple,
             a0: list[float], u: list[float], tau: list[float], W: list[float], pole: float, first: int,
             count: int) -> list[float]:
    out = [0.0] * (6 * JACOBIAN_COLUMNS)
    for i in range(count):  # a C loop: the plant is inlined once
        k = first + i
        if k >= JACOBIAN_COLUMNS:
            k -= JACOBIAN_COLUMNS
        column = _column(p, w, m, s, x0, T, a0, u, tau, W, pole, k)
        at = 6 * k
        out = [column[j - at] if j >= at and j < at + 6 else out[j] for j in range(6 * JACOBIAN_COLUMNS)]
    return out


# ----------------------------------------------------------------------------------- contact law

def _law(hole: Hole, peg: Peg, law: PegContact, pose: tuple[F3, F9, F3, F3],
         h: tuple[float, float, float, float]) -> tuple[list[float], float]:
    """(the law's wrench (6), its active contacts) at the tool pose with the hole at h."""
    c = placed_peg_wrench(hole, h, peg, law, pose[0], pose[1], pose[2], pose[3])
    return [c.force[0], c.force[1], c.force[2], c.moment[0], c.moment[1], c.moment[2]], c.active


def contact_linearization(hole: Hole, peg: Peg, law: PegContact, w: WristConstants, m: WristMount, s: list[float],
                          h: list[float], hole_only: bool) -> list[float]:
    """The contact law's wrench at (s, h) and its forward-difference Jacobian by [s, h] (module
    docstring's layout); with ``hole_only`` the columns of s are zeros (not evaluated)."""
    placed = (h[0], h[1], h[2], h[3])
    pose = tool_pose(w, m, s)
    out = [0.0] * LINEARIZATION_SIZE
    w0 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    offset = 11 if hole_only else -1
    for i in range(5 if hole_only else 17):  # the law at (s, h), then column k: a C loop, the law inlined once
        k = -1 if i == 0 else i + offset
        step = 1.0
        at = pose
        moved = placed
        if k >= 12:
            step = HOLE_STEPS[k - 12]
            moved = (h[0] + step if k == 12 else h[0], h[1] + step if k == 13 else h[1],
                     h[2] + step if k == 14 else h[2], h[3] + step if k == 15 else h[3])
        elif k >= 0:
            step = POSITION_STEP if k < 6 else RATE_STEP
            at = tool_pose(w, m, [s[j] + step if j == k else s[j] for j in range(12)])
        wk, active = _law(hole, peg, law, at, moved)
        if k < 0:
            w0 = wk
            out = wk + out[6:LINEARIZATION_SIZE - 1] + [active]
        else:
            column = [(wk[j] - w0[j]) / step for j in range(6)]
            first = 6 + 6 * k
            out = [column[j - first] if j >= first and j < first + 6 else out[j] for j in range(LINEARIZATION_SIZE)]
    return out


def _misfit(hole: Hole, peg: Peg, law: PegContact, pose: tuple[F3, F9, F3, F3], x: float, y: float, h: list[float],
            felt: list[float], weights: list[float]) -> float:
    """sum ((c - felt) / weights)^2 of the law's wrench c with the hole at (x, y, h's tilt)."""
    c = _law(hole, peg, law, pose, (x, y, h[2], h[3]))[0]
    total = 0.0
    for j in range(6):
        r = (c[j] - felt[j]) / weights[j]
        total += r * r
    return total


def hole_search(hole: Hole, peg: Peg, law: PegContact, w: WristConstants, m: WristMount, s: list[float],
                h: list[float], felt: list[float], weights: list[float]) -> list[float]:
    """The search of :func:`deltafmi.physics.estimation.peg_contact.locate_hole` (its docstring):
    [1.0, x, y, tilt_x, tilt_y] of the hole whose law explains the felt wrench best along the
    felt lateral force, or five zeros where there is none. One loop over the evaluations (a C
    loop, the law inlined once): the grid's cells, the distance -1 m (no contact), then four
    passes of 21 points (numpy.linspace(lo, hi, 21)), each bracket a tenth of the last."""
    lateral = math.sqrt(felt[0] * felt[0] + felt[1] * felt[1])
    if not lateral > 0.0:
        return [0.0, 0.0, 0.0, 0.0, 0.0]
    ex, ey = felt[0] / lateral, felt[1] / lateral
    pose = tool_pose(w, m, s)
    tx, ty = pose[0][0], pose[0][1]
    reach = hole.bore_radius + hole.chamfer_width + hole.edge_radius - peg.radius + 2.0 * _GRID
    cells = 0  # as numpy.arange(0.0, reach, _GRID): ceil(reach / _GRID) points i * _GRID
    while float(cells) < reach / _GRID:
        cells += 1
    best, best_value = 0, math.inf
    lo, hi, step = 0.0, 0.0, 0.0
    fine = 0  # the point of the current pass
    found = True
    for i in range(cells + 1 + 4 * 21):
        if i < cells:
            d = float(i) * _GRID
        elif i == cells:
            d = -1.0
        else:
            d = float(fine) * step + lo if fine < 20 else hi
        value = _misfit(hole, peg, law, pose, tx + d * ex, ty + d * ey, h, felt, weights)
        if i < cells:
            if value < best_value:
                best, best_value = i, value
        elif i == cells:
            if best_value >= value:  # no better than no contact at all
                found = False
                break
            lo, hi = float(max(best - 1, 0)) * _GRID, float(min(best + 1, cells - 1)) * _GRID
            step = (hi - lo) / 20.0
            best, best_value = 0, math.inf
        else:
            if value < best_value:
                best, best_value = fine, value
            fine += 1
            if fine == 21:
                lower, upper = max(best - 1, 0), min(best + 1, 20)
                new_lo = float(lower) * step + lo if lower < 20 else hi
                hi = float(upper) * step + lo if upper < 20 else hi
                lo = new_lo
                step = (hi - lo) / 20.0
                best, best_value, fine = 0, math.inf, 0
    if not found:
        return [0.0, 0.0, 0.0, 0.0, 0.0]
    d = 0.5 * (lo + hi)
    return [1.0, tx + d * ex, ty + d * ey, h[2], h[3]]


#: the kernels a component compiles (``NativeKernels(functions=...)``): name -> (function, argument types:
#: a dataclass of floats, n floats, float, int, bool)
FUNCTIONS = {
    "prediction": (prediction, (DeltaParams, WristConstants, WristMount, 12, 3, 3, 6, float, float, int, int, int)),
    "contact_linearization": (contact_linearization, (Hole, Peg, PegContact, WristConstants, WristMount, 12, 4, bool)),
    "hole_search": (hole_search, (Hole, Peg, PegContact, WristConstants, WristMount, 12, 4, 6, 6)),
    "servo_kinematics": (servo_kinematics, (DeltaParams, 3)),
}
