"""Coulomb friction of the robot's tool on a plane, in plain floats (kernels the contact FMU compiles).

The laws are those of :mod:`deltafmi.physics.friction.law` (the STICK and SLIP modes of one
contact with a tangential plane), written for the robot's closed-loop DAE. The plate only
translates, so the tool tip's tangential velocity is the wrist's: with an orthonormal tangent
basis ``t1, t2`` of the plane, ``s_j = t_j . z(q)`` and ``v_t = (t_j^T Jv(q) v)_j``. While the
contact is in CONTACT (the compliant normal force ``lambda_n`` is an explicit function of the
state) the tangential force ``lambda_t`` (2 components) acts on the wrist as ``T lambda_t``:

* SLIP: ``lambda_t = -mu_k lambda_n e - c_v v_t``, ``e`` the unit slip direction
  (:func:`slip_direction`, the anchored ``axis`` once ``v_t`` has turned past 90 deg from it);
* STICK: the multiplier of the tip's tangential constraint ``s = anchor``, stabilised by the
  robot's Baumgarte pole ``p`` (double pole, as the loop closures):
  ``s'' + 2 p s' + p^2 (s - anchor) = 0``. The DAE is affine in the wrist force, so
  ``s'' = a0 + A lambda_t`` with ``a0`` the tangential acceleration without friction and
  ``A = T^T Lambda^-1 T`` (2 x 2, the inverse operational-space inertia with the loops closed)
  from two more solves with unit forces along ``t1``, ``t2``; then ``lambda_t = A^-1 (target - a0)``.

``s'' = row . v' + bias`` with ``row = t^T Jv`` (:func:`.kinematics.wrist_along`) and
``bias = t . mean_i R_i (d/dt dpsi_i/dq) v_i`` (:func:`along_bias`, the velocity-product term).
"""
from __future__ import annotations

import math
from typing import NamedTuple, Sequence

from ..friction.law import SEPARATED, SLIP_POSITIVE, STICK
from ..friction.system import EPS as FRICTION_EPS
from .dynamics import F3, F6, _evaluate
from .kinematics import ARM_COS_SIN, F9, wrist_along
from .params import DeltaParams

__all__ = ["ToolFriction", "FRICTIONLESS", "tangent_basis", "along_bias", "tangential_state", "slip_direction",
           "friction_evaluation", "friction_indicator", "world_force", "F_REF", "V_REF"]

F2 = tuple[float, float]
F4 = tuple[float, float, float, float]
#: scales of the dimensionless friction indicator: STICK (force margin) and SLIP (velocity)
F_REF, V_REF = 1.0, 1.0


class ToolFriction(NamedTuple):
    """The tool's friction on the plane and its discrete state (fixed between events)."""

    mode: int  #: SEPARATED (no friction force: frictionless, or not in CONTACT), STICK, SLIP_POSITIVE
    mu_s: float  #: static Coulomb coefficient
    mu_k: float  #: kinetic Coulomb coefficient (<= mu_s)
    viscous: float  #: viscous coefficient c_v while slipping (N s/m)
    t1: F3  #: first unit tangent of the plane (world)
    t2: F3  #: second unit tangent, normal x t1
    axis: F2  #: SLIP: unit slip axis in (t1, t2) coordinates
    anchor: F2  #: STICK: the wrist's (t1 . z, t2 . z) where it stuck (m)


#: no friction: the contact kernels then evaluate exactly as the frictionless model
FRICTIONLESS = ToolFriction(SEPARATED, 0.0, 0.0, 0.0, (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 0.0), (0.0, 0.0))


def tangent_basis(normal: Sequence[float]) -> tuple[F3, F3]:
    """Orthonormal ``(t1, t2)`` with ``t2 = n x t1``: ``t1`` the world x axis projected on the plane
    (the y axis if the normal is within 25 deg of x), so a horizontal table has ``t1 = x``, ``t2 = y``."""
    nx, ny, nz = (float(c) for c in normal)
    ax, ay, az = (1.0, 0.0, 0.0) if abs(nx) < 0.9 else (0.0, 1.0, 0.0)
    d = ax * nx + ay * ny + az * nz
    ux, uy, uz = ax - d * nx, ay - d * ny, az - d * nz
    norm = math.sqrt(ux * ux + uy * uy + uz * uz)
    t1 = (ux / norm, uy / norm, uz / norm)
    return t1, (ny * t1[2] - nz * t1[1], nz * t1[0] - nx * t1[2], nx * t1[1] - ny * t1[0])


def along_bias(p: DeltaParams, n: F3, q: list[float], v: list[float]) -> float:
    """``n . mean_i R_i (d/dt dpsi_i/dq) v_i``: the velocity-product part of ``n . z''``."""
    l1, l2 = p.l1, p.l2
    nx, ny, nz = n
    total = 0.0
    for arm in range(3):
        cr, sr = ARM_COS_SIN[arm]
        q1, q2, q3 = q[3 * arm], q[3 * arm + 1], q[3 * arm + 2]
        v1, v2, v3 = v[3 * arm], v[3 * arm + 1], v[3 * arm + 2]
        s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                                  math.sin(q3), math.cos(q3))
        w = v2 * v2 + v3 * v3
        ax, ay = cr * nx + sr * ny, cr * ny - sr * nx  # R_i^T n (z unchanged)
        total += (ax * l2 * (-s2 * s3 * w + 2.0 * c2 * c3 * v2 * v3)
                  + ay * (-l1 * c1 * v1 * v1 - l2 * c2 * v2 * v2)
                  + nz * (-l1 * s1 * v1 * v1 - l2 * (s2 * c3 * w + 2.0 * c2 * s3 * v2 * v3)))
    return total / 3.0


def _dot9(a: F9, b: list[float]) -> float:
    total = 0.0
    for k in range(9):
        total += a[k] * b[k]
    return total


def tangential_state(p: DeltaParams, fr: ToolFriction, q: list[float], v: list[float]) -> tuple[F2, F2, F9, F9]:
    """The wrist's tangential position ``s``, velocity ``v_t`` and the rows ``t_j^T Jv``."""
    s1, row1 = wrist_along(p, fr.t1, q)
    s2, row2 = wrist_along(p, fr.t2, q)
    return (s1, s2), (_dot9(row1, v), _dot9(row2, v)), row1, row2


def slip_direction(fr: ToolFriction, vt1: float, vt2: float) -> F2:
    """:func:`deltafmi.physics.friction.law.slip_force_direction` in floats: ``v_t / |v_t|``
    while ``v_t . axis > 0``, else the anchored ``axis``."""
    speed = math.sqrt(vt1 * vt1 + vt2 * vt2)
    if speed > 0.0 and vt1 * fr.axis[0] + vt2 * fr.axis[1] > 0.0:
        return vt1 / speed, vt2 / speed
    return fr.axis[0], fr.axis[1]


def _pushed(w: F3, t1: F3, t2: F3, l1: float, l2: float) -> F3:
    """The wrist force ``w + l1 t1 + l2 t2``."""
    return (w[0] + l1 * t1[0] + l2 * t2[0], w[1] + l1 * t1[1] + l2 * t2[1], w[2] + l1 * t1[2] + l2 * t2[2])


def friction_evaluation(p: DeltaParams, fr: ToolFriction, q: list[float], v: list[float], u: Sequence[float],
                        wrist: F3, pole: float,
                        lam_n: float) -> tuple[list[float], F6, tuple[tuple[F3, F3, float], ...], F4]:
    """The DAE with the tool's friction (mode STICK or SLIP) on top of the wrist force ``wrist``
    (external plus normal contact force): (v', loop forces, arms, (lambda_t1, lambda_t2, v_t1, v_t2))."""
    s, vt, row1, row2 = tangential_state(p, fr, q, v)
    if fr.mode == STICK:
        vdot0, _, _ = _evaluate(p, q, v, u, wrist, pole)
        vdot1, _, _ = _evaluate(p, q, v, u, _pushed(wrist, fr.t1, fr.t2, 1.0, 0.0), pole)
        vdot2, _, _ = _evaluate(p, q, v, u, _pushed(wrist, fr.t1, fr.t2, 0.0, 1.0), pole)
        d1 = [vdot1[k] - vdot0[k] for k in range(9)]
        d2 = [vdot2[k] - vdot0[k] for k in range(9)]
        a11, a12, a21, a22 = _dot9(row1, d1), _dot9(row1, d2), _dot9(row2, d1), _dot9(row2, d2)
        tp, pp = 2.0 * pole, pole * pole
        r1 = -tp * vt[0] - pp * (s[0] - fr.anchor[0]) - along_bias(p, fr.t1, q, v) - _dot9(row1, vdot0)
        r2 = -tp * vt[1] - pp * (s[1] - fr.anchor[1]) - along_bias(p, fr.t2, q, v) - _dot9(row2, vdot0)
        det = a11 * a22 - a12 * a21
        lt1 = (a22 * r1 - a12 * r2) / det
        lt2 = (a11 * r2 - a21 * r1) / det
    else:
        e1, e2 = slip_direction(fr, vt[0], vt[1])
        lt1 = -fr.mu_k * lam_n * e1 - fr.viscous * vt[0]
        lt2 = -fr.mu_k * lam_n * e2 - fr.viscous * vt[1]
    vdot, loops, arms = _evaluate(p, q, v, u, _pushed(wrist, fr.t1, fr.t2, lt1, lt2), pole)
    return vdot, loops, arms, (lt1, lt2, vt[0], vt[1])


def friction_indicator(fr: ToolFriction, lam_n: float, tangential: F4) -> float:
    """The contact's friction indicator (``z > 0`` while its mode holds): STICK
    ``(mu_s lambda_n - |lambda_t|) / F_REF + EPS`` (the static cone), SLIP ``v_t . axis / V_REF + EPS``
    (a stop, or the velocity turned past 90 deg), 1 without friction (as FrictionSystem's)."""
    lt1, lt2, vt1, vt2 = tangential
    if fr.mode == STICK:
        return (fr.mu_s * lam_n - math.sqrt(lt1 * lt1 + lt2 * lt2)) / F_REF + FRICTION_EPS
    if fr.mode == SLIP_POSITIVE:
        return (vt1 * fr.axis[0] + vt2 * fr.axis[1]) / V_REF + FRICTION_EPS
    return 1.0


def world_force(fr: ToolFriction, tangential: F4) -> F3:
    """The tangential force of the plane on the tool in the world frame, ``lambda_t1 t1 + lambda_t2 t2``."""
    return _pushed((0.0, 0.0, 0.0), fr.t1, fr.t2, tangential[0], tangential[1])
