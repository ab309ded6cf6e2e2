"""Delta robot kinematics in the seed talk's nine joint angles.

Each arm i has q_i = [q_i1 (servo), q_i2, q_i3]; in the arm's own frame its wrist point (the
plate centre seen from that arm) is

    psi(q_i) = [l2 sin q2 sin q3,  l0 - l3 + l1 cos q1 + l2 cos q2,  l1 sin q1 + l2 sin q2 cos q3].

The upper arm turns in the local y-z plane (q1 = 0 horizontal and radially out, q1 < 0 down);
the forearm leaves the elbow along the unit vector [sin q2 sin q3, cos q2, sin q2 cos q3]
(q2 its polar angle from +y, q3 its azimuth about y). Arm i's wrist in the world is R_i psi(q_i).
Branch: q_i2 in (-pi, 0), q_i3 in (-pi/2, pi/2) (forearms point down) with the elbows out.

The loop closure h(q) = [psi(q1) - R2 psi(q2); psi(q1) - R3 psi(q3)] = 0 ties the arms together.
Inverse kinematics (wrist -> nine angles) and forward kinematics (servo angles -> wrist, by
three-sphere intersection) are both closed form.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .params import ARM_ROTATIONS, R2, R3, DeltaParams

__all__ = ["arm_psi", "arm_jacobian", "arm_bias", "inverse_kinematics", "joint_rates", "forward_kinematics",
           "wrist_position", "wrist_velocity", "constraint", "constraint_jacobian", "constraint_bias",
           "virtual_jacobian", "wrist_along", "stretched_height", "ARM_COS_SIN", "F9"]

ArrayLike = Sequence[float] | np.ndarray
F9 = tuple[float, float, float, float, float, float, float, float, float]

_SQ3_2 = math.sqrt(3.0) / 2.0
# (cos, sin) of the arm rotation angles 0, +2pi/3, -2pi/3: rotations done by hand in float math.
ARM_COS_SIN = ((1.0, 0.0), (-0.5, _SQ3_2), (-0.5, -_SQ3_2))


def arm_psi(p: DeltaParams, qi: ArrayLike) -> np.ndarray:
    """Wrist point of one arm in that arm's frame, psi(q_i) (m), shape (3,)."""
    q1, q2, q3 = (float(x) for x in qi)
    s2 = math.sin(q2)
    return np.array([
        p.l2 * s2 * math.sin(q3),
        p.l0 - p.l3 + p.l1 * math.cos(q1) + p.l2 * math.cos(q2),
        p.l1 * math.sin(q1) + p.l2 * s2 * math.cos(q3),
    ])


def arm_jacobian(p: DeltaParams, qi: ArrayLike) -> np.ndarray:
    """d psi / d q_i of one arm, shape (3, 3) (rows x, y, z; columns q_i1, q_i2, q_i3)."""
    q1, q2, q3 = (float(x) for x in qi)
    s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                              math.sin(q3), math.cos(q3))
    l1, l2 = p.l1, p.l2
    return np.array([
        [0.0, l2 * c2 * s3, l2 * s2 * c3],
        [-l1 * s1, -l2 * s2, 0.0],
        [l1 * c1, l2 * c2 * c3, -l2 * s2 * s3],
    ])


def arm_bias(p: DeltaParams, qi: ArrayLike, vi: ArrayLike) -> np.ndarray:
    """(d/dt d psi/d q_i) v_i of one arm: the velocity-product part of the wrist acceleration."""
    q1, q2, q3 = (float(x) for x in qi)
    v1, v2, v3 = (float(x) for x in vi)
    s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                              math.sin(q3), math.cos(q3))
    l1, l2 = p.l1, p.l2
    w = v2 * v2 + v3 * v3
    return np.array([
        l2 * (-s2 * s3 * w + 2.0 * c2 * c3 * v2 * v3),
        -l1 * c1 * v1 * v1 - l2 * c2 * v2 * v2,
        -l1 * s1 * v1 * v1 - l2 * (s2 * c3 * w + 2.0 * c2 * s3 * v2 * v3),
    ])


# ----------------------------------------------------------------------------- inverse kinematics

def _to_arm_frame(z: ArrayLike, arm: int) -> tuple[float, float, float]:
    """World point -> arm frame, R_i^T z."""
    c, s = ARM_COS_SIN[arm]
    x, y, zz = (float(t) for t in z)
    return c * x + s * y, -s * x + c * y, zz


def _arm_ik(p: DeltaParams, x: float, y: float, z: float) -> tuple[float, float, float] | str:
    """Angles of one arm reaching the local wrist point (x, y, z), or why it cannot."""
    l1, l2 = p.l1, p.l2
    Y = y - (p.l0 - p.l3)  # wrist joint relative to the servo axis, y component
    rho = math.hypot(Y, z)
    k = (x * x + Y * Y + z * z + l1 * l1 - l2 * l2) / (2.0 * l1)
    if rho == 0.0 or abs(k) > rho:
        # |wrist joint - elbow| ranges over [dmin, dmax] as the elbow turns on its circle.
        dmin = math.hypot(x, rho - l1)
        dmax = math.hypot(x, rho + l1)
        if l2 < dmin:
            return f"a forearm of at least {dmin:.4f} m (l2 = {l2:.4f} m)"
        return f"a forearm of at most {dmax:.4f} m (l2 = {l2:.4f} m)"
    q1 = math.atan2(z, Y) + math.acos(min(1.0, k / rho))  # '+': elbow out
    if q1 > math.pi:
        q1 -= 2.0 * math.pi
    ux, uy, uz = x, Y - l1 * math.cos(q1), z - l1 * math.sin(q1)
    if uz >= 0.0:
        return "its forearm to point upwards (outside the branch q_i3 in (-pi/2, pi/2))"
    return q1, math.atan2(-math.hypot(ux, uz), uy), math.atan2(-ux, -uz)


def _reachable(p: DeltaParams, z: ArrayLike) -> bool:
    return all(not isinstance(_arm_ik(p, *_to_arm_frame(z, i)), str) for i in range(3))


def stretched_height(p: DeltaParams) -> float:
    """Wrist height with all three arms stretched (upper arm in line with forearm), x = y = 0 (m).

    The lowest reachable point of the workspace; -1.4607 m for RL5.
    """
    dr = p.l0 - p.l3
    return -math.sqrt((p.l1 + p.l2) ** 2 - dr * dr)


def _bisect(pred, lo: float, hi: float, n: int = 60) -> float:
    """Last value in [lo, hi] where pred holds, for pred true at lo and false at hi."""
    for _ in range(n):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if pred(mid) else (lo, mid)
    return lo


def _workspace_note(p: DeltaParams, z: ArrayLike) -> str:
    """Describe the reachable workspace at the height of z, for error messages."""
    x, y, h = (float(t) for t in z)
    if not _reachable(p, (0.0, 0.0, h)):
        zlow = stretched_height(p)
        ztop = _bisect(lambda t: _reachable(p, (0.0, 0.0, t)), zlow + 1e-12, 0.0)
        return (f"no point at this height is reachable (on the robot axis the workspace spans "
                f"{zlow:.4f} <= z <= {ztop:.4f} m)")
    r = math.hypot(x, y)
    ex, ey = (x / r, y / r) if r > 0.0 else (1.0, 0.0)
    reach = p.l0 + p.l1 + p.l2
    rmax = _bisect(lambda t: _reachable(p, (t * ex, t * ey, h)), 0.0, reach)
    return f"the workspace at this height is r <= {rmax:.4f} m in this direction"


def inverse_kinematics(p: DeltaParams, z: ArrayLike) -> np.ndarray:
    """All nine joint angles placing the wrist (plate centre) at z, closed form.

    Returns q ordered [q11, q12, q13, q21, q22, q23, q31, q32, q33] on the branch q_i2 in
    (-pi, 0), q_i3 in (-pi/2, pi/2), elbows out.

    Raises:
        ValueError: z is out of reach; the message names z, the arm that cannot reach it and
            the reachable workspace at that height.
    """
    q: list = []
    for arm in range(3):
        sol = _arm_ik(p, *_to_arm_frame(z, arm))
        if isinstance(sol, str):
            zs = ", ".join(f"{float(t):.4f}" for t in z)
            raise ValueError(f"z0 = ({zs}) m is out of reach: arm {arm + 1} needs {sol}; "
                             f"{_workspace_note(p, z)}")
        q.extend(sol)
    return np.array(q)


def joint_rates(p: DeltaParams, q: ArrayLike, zd: ArrayLike) -> np.ndarray:
    """The nine joint rates moving the wrist at velocity zd with the loops kept closed (H v = 0).

    Arm by arm: R_i dpsi/dq(q_i) v_i = zd, a 3x3 solve each (regular away from the singular
    poses), so every arm's wrist point moves with zd and Jv v = zd.
    """
    zd = np.asarray(zd, dtype=float)
    return np.concatenate([np.linalg.solve(r @ arm_jacobian(p, qi), zd)
                           for r, qi in zip(ARM_ROTATIONS, _split(q))])


# ----------------------------------------------------------------------------- forward kinematics

def forward_kinematics(p: DeltaParams, y: ArrayLike) -> np.ndarray:
    """Wrist position z (3,) from the three servo angles y, closed form.

    The wrist lies at distance l2 from each of the points C_i = R_i [0, l0 - l3 + l1 cos y_i,
    l1 sin y_i] (elbow shifted by the plate radius); of the two intersections of the three
    spheres, the one below the plane of the C_i (platform below the base) is returned.

    Raises:
        ValueError: the spheres do not intersect (servo angles no forearms can close).
    """
    dr = p.l0 - p.l3
    cs = []
    for (cr, sr), yi in zip(ARM_COS_SIN, y):
        rad = dr + p.l1 * math.cos(yi)
        cs.append((-sr * rad, cr * rad, p.l1 * math.sin(yi)))
    (x1, y1, z1), (x2, y2, z2), (x3, y3, z3) = cs
    ax, ay, az = x1 - x3, y1 - y3, z1 - z3
    bx, by, bz = x2 - x3, y2 - y3, z2 - z3
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    n2 = nx * nx + ny * ny + nz * nz
    a2, b2 = ax * ax + ay * ay + az * az, bx * bx + by * by + bz * bz
    # circumcentre O = C3 + ((|a|^2 b - |b|^2 a) x (a x b)) / (2 |a x b|^2)
    wx, wy, wz = a2 * bx - b2 * ax, a2 * by - b2 * ay, a2 * bz - b2 * az
    ox = (wy * nz - wz * ny) / (2.0 * n2)
    oy = (wz * nx - wx * nz) / (2.0 * n2)
    oz = (wx * ny - wy * nx) / (2.0 * n2)
    d2 = p.l2 * p.l2 - (ox * ox + oy * oy + oz * oz)
    if d2 < 0.0:
        raise ValueError(f"servo angles y = {list(map(float, y))} rad: the forearms cannot "
                         f"close (circumradius of the elbow triangle exceeds l2 = {p.l2} m)")
    t = math.sqrt(d2 / n2) * (-1.0 if nz > 0.0 else 1.0)
    return np.array([x3 + ox + t * nx, y3 + oy + t * ny, z3 + oz + t * nz])


# ------------------------------------------------------------------- constraint and wrist outputs

def _split(q: ArrayLike) -> list[np.ndarray]:
    q = np.asarray(q, dtype=float)
    return [q[0:3], q[3:6], q[6:9]]


def wrist_position(p: DeltaParams, q: ArrayLike) -> np.ndarray:
    """Wrist (plate centre) position z (m): the mean of the three arms' wrist points.

    Equal to psi(q_1) on the constraint manifold; the mean is the one whose time derivative is
    exactly wrist_velocity = Jv v.
    """
    return sum(r @ arm_psi(p, qi) for r, qi in zip(ARM_ROTATIONS, _split(q))) / 3.0


def virtual_jacobian(p: DeltaParams, q: ArrayLike) -> np.ndarray:
    """The seed's virtual Jacobian (3, 9): 1/3 [dpsi/dq(q1), R2 dpsi/dq(q2), R3 dpsi/dq(q3)]."""
    return np.hstack([r @ arm_jacobian(p, qi) for r, qi in zip(ARM_ROTATIONS, _split(q))]) / 3.0


def wrist_along(p: DeltaParams, n: tuple[float, float, float], q: list[float]) -> tuple[float, F9]:
    """``n . z(q)`` and the row ``n^T Jv(q)`` (9 floats) for a direction ``n``, in plain floats.

    ``z`` is the mean of the arms' wrist points (as :func:`wrist_position`), so the row is exactly
    the derivative of the first value. A contact's gap along a plane normal needs both at every
    derivative evaluation (translated to C for the FMUs, like the dynamics).
    """
    l0l3, l1, l2 = p.l0 - p.l3, p.l1, p.l2
    nx, ny, nz = n
    height = 0.0
    row: list[float] = []
    for arm in range(3):
        cr, sr = ARM_COS_SIN[arm]
        q1, q2, q3 = q[3 * arm], q[3 * arm + 1], q[3 * arm + 2]
        s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                                  math.sin(q3), math.cos(q3))
        ax, ay = cr * nx + sr * ny, cr * ny - sr * nx  # R_i^T n (z unchanged)
        height += ax * l2 * s2 * s3 + ay * (l0l3 + l1 * c1 + l2 * c2) + nz * (l1 * s1 + l2 * s2 * c3)
        row.append((nz * l1 * c1 - ay * l1 * s1) / 3.0)
        row.append((ax * l2 * c2 * s3 - ay * l2 * s2 + nz * l2 * c2 * c3) / 3.0)
        row.append((ax * l2 * s2 * c3 - nz * l2 * s2 * s3) / 3.0)
    return height / 3.0, (row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7], row[8])


def wrist_velocity(p: DeltaParams, q: ArrayLike, v: ArrayLike) -> np.ndarray:
    """Wrist velocity zd = Jv(q) v (m/s)."""
    return virtual_jacobian(p, q) @ np.asarray(v, dtype=float)


def constraint(p: DeltaParams, q: ArrayLike) -> np.ndarray:
    """Loop closure h(q) = [psi(q1) - R2 psi(q2); psi(q1) - R3 psi(q3)] (m), shape (6,)."""
    q1, q2, q3 = _split(q)
    p1 = arm_psi(p, q1)
    return np.concatenate([p1 - R2 @ arm_psi(p, q2), p1 - R3 @ arm_psi(p, q3)])


def constraint_jacobian(p: DeltaParams, q: ArrayLike) -> np.ndarray:
    """H = dh/dq, shape (6, 9)."""
    q1, q2, q3 = _split(q)
    j1 = arm_jacobian(p, q1)
    H = np.zeros((6, 9))
    H[0:3, 0:3] = j1
    H[3:6, 0:3] = j1
    H[0:3, 3:6] = -R2 @ arm_jacobian(p, q2)
    H[3:6, 6:9] = -R3 @ arm_jacobian(p, q3)
    return H


def constraint_bias(p: DeltaParams, q: ArrayLike, v: ArrayLike) -> np.ndarray:
    """(dH/dt) v, shape (6,): so that hdd = H vdot + constraint_bias."""
    (q1, q2, q3), (v1, v2, v3) = _split(q), _split(v)
    a1 = arm_bias(p, q1, v1)
    return np.concatenate([a1 - R2 @ arm_bias(p, q2, v2), a1 - R3 @ arm_bias(p, q3, v3)])
