"""The robot's contact systems in plain floats: the kernels the contact FMUs compile to C.

:class:`~deltafmi.physics.contact.ContactSystem` keeps the FREE / COLLISION / CONTACT machine
(its event iteration, the frozen effective masses, the capture decisions) in Python; between
events the continuous part depends only on the state, the inputs and each contact's mode and law.
That part is written here once, with fixed-length float tuples and ``math`` only (the subset of
deltafmi/builder/codegen/translate.py), for the tool against a plane (:class:`ToolPlane`, 18 states,
one contact) and the tool, a box and the table (:class:`BoxTable`, 24 states, six contacts):

* ``*_derivatives``: ``x' = [v, v']`` with each contact's force in its mode acting on the wrist
  (through the robot's closed-loop DAE, :func:`.dynamics._evaluate`) and on the box; the tool on
  the plane also carries Coulomb friction in CONTACT (STICK / SLIP, :mod:`.tool_friction`);
* ``*_indicators``: the machine's event indicators (as ``ContactSystem._indicator_pair``);
* ``*_outputs``: the components' outputs from the same evaluation.

The systems of :mod:`.contact` and :mod:`.box` evaluate through these functions too, so the
Python machine decides its events on exactly the numbers the compiled kernels give. Every
contact here has a compliant material (a spring-damper in CONTACT); the rigid stabilised
CONTACT law, which couples the contacts through a joint solve, stays with ``ContactSystem``
(it only serves the capture decision's load estimate there).
"""
from __future__ import annotations

import math
from typing import Any, NamedTuple, Sequence

from ..contact.law_kernels import LawConstants, law_acceleration, law_constants, law_end_indicator, law_potential
from ..contact.system import COLLISION, CONTACT, EPS, FREE
from ..friction.law import SEPARATED
from .dynamics import F3, _as_list, _evaluate, _wrist
from .kinematics import wrist_along
from .params import DeltaParams
from .tool_friction import ToolFriction, friction_evaluation, friction_indicator, world_force

__all__ = ["ContactLaw", "ToolPlane", "BoxTable", "contact_law", "contact_force", "indicator_pair",
           "plane_evaluation", "plane_derivatives", "plane_indicators", "plane_outputs",
           "box_evaluation", "box_derivatives", "box_indicators", "box_outputs"]

F8 = tuple[float, float, float, float, float, float, float, float]
F12 = tuple[float, float, float, float, float, float, float, float, float, float, float, float]


class ContactLaw(NamedTuple):
    """One contact's mode and the constants of its laws: the collision law in force (matched to
    the effective mass of the last impact) and the compliant material of CONTACT."""

    mode: int  #: 0 FREE, 1 COLLISION, 2 CONTACT
    m_eff: float  #: effective mass frozen at the last impact (kg)
    law: LawConstants  #: the collision law, per unit effective mass
    stiffness: float  #: material spring (N/m)
    damping: float  #: material damper (N s/m)


def contact_law(system: Any, i: int, mode: int) -> ContactLaw:
    """Contact ``i`` of a :class:`~deltafmi.physics.contact.ContactSystem` (compliant) in ``mode``."""
    material = system.materials[i]
    return ContactLaw(int(mode), float(system.m_eff[i]), law_constants(system.laws[i]), material.stiffness,
                      material.damping)


def contact_force(c: ContactLaw, h: float, hdot: float) -> float:
    """The contact's force (N) at gap ``h`` closing at ``-hdot``: zero in FREE, ``m_eff`` times the
    collision law in COLLISION, the material's ``(k delta + c delta')_+`` in CONTACT."""
    delta, ddot = -h, -hdot
    if c.mode == COLLISION:
        return c.m_eff * law_acceleration(c.law, delta, ddot)
    if c.mode == CONTACT:
        if delta <= 0.0:
            return 0.0
        return max(c.stiffness * delta + c.damping * ddot, 0.0)
    return 0.0


def indicator_pair(c: ContactLaw, h: float, hdot: float) -> tuple[float, float]:
    """The contact's two event indicators (see ``ContactSystem.event_indicators``)."""
    law = c.law
    if c.mode == FREE:
        return max(h / law.length, hdot / law.reference_speed + EPS), 1.0
    if c.mode == COLLISION:
        return law_end_indicator(law, -h, -hdot) + EPS, -hdot / law.reference_speed + EPS
    return c.stiffness * -h + c.damping * -hdot, 1.0


def _elastic(c: ContactLaw, h: float) -> float:
    """Energy stored in the contact (J): the collision law's or the material's spring."""
    delta = -h
    if delta <= 0.0 or c.mode == FREE:
        return 0.0
    if c.mode == COLLISION:
        return c.m_eff * law_potential(c.law, delta)
    return 0.5 * c.stiffness * delta * delta


# ------------------------------------------------------------------------ the tool and a plane

class ToolPlane(NamedTuple):
    """The tool tip over a plane: gap ``h = normal . z(q) + offset``."""

    normal: F3  #: unit plane normal, towards the robot
    offset: float  #: ``normal . (tool - (0, 0, height))``
    tool: F3  #: tool tip relative to the plate centre (m)
    pole: float  #: Baumgarte pole of the loop closures (1/s)
    law: ContactLaw
    friction: ToolFriction  #: friction in CONTACT (:mod:`.tool_friction`); FRICTIONLESS: none


def plane_evaluation(p: DeltaParams, c: ToolPlane, x: Sequence[float], u: Sequence[float],
                     f: Sequence[float]) -> tuple:
    """One evaluation at ``x = [q, v]``: (gap, its rate, contact force, v', loop forces, arms,
    (lambda_t1, lambda_t2, v_t1, v_t2) the tangential force and velocity, zero without friction)."""
    xl = _as_list(x)
    ql, vl = xl[:9], xl[9:]
    fl = _as_list(f)
    height, row = wrist_along(p, c.normal, ql)
    h = height + c.offset
    hdot = 0.0
    for k in range(9):
        hdot += row[k] * vl[k]
    lam = contact_force(c.law, h, hdot)
    n = c.normal
    wrist = (fl[0] + n[0] * lam, fl[1] + n[1] * lam, fl[2] + n[2] * lam)
    if c.law.mode == CONTACT and c.friction.mode != SEPARATED:
        vdot, loops, arms, tangential = friction_evaluation(p, c.friction, ql, vl, u, wrist, c.pole, lam)
    else:
        vdot, loops, arms = _evaluate(p, ql, vl, u, wrist, c.pole)
        tangential = (0.0, 0.0, 0.0, 0.0)
    return h, hdot, lam, vdot, loops, arms, tangential


def plane_derivatives(p: DeltaParams, c: ToolPlane, x: Sequence[float], u: Sequence[float],
                      f: Sequence[float]) -> list[float]:
    """``x' = [v, v']`` (18 values)."""
    _, _, _, vdot, _, _, _ = plane_evaluation(p, c, x, u, f)
    xl = _as_list(x)
    return xl[9:] + vdot


def plane_indicators(p: DeltaParams, c: ToolPlane, x: Sequence[float], u: Sequence[float],
                     f: Sequence[float]) -> tuple[float, float]:
    """The contact's two event indicators; in CONTACT with friction the second (unused by the
    normal machine there) is the friction mode's (:func:`.tool_friction.friction_indicator`)."""
    h, hdot, lam, _, _, _, tangential = plane_evaluation(p, c, x, u, f)
    z = indicator_pair(c.law, h, hdot)
    if c.law.mode == CONTACT and c.friction.mode != SEPARATED:
        return z[0], friction_indicator(c.friction, lam, tangential)
    return z


def plane_outputs(p: DeltaParams, c: ToolPlane, x: Sequence[float], u: Sequence[float],
                  f: Sequence[float]) -> tuple:
    """DeltaRobotContact's outputs: servo angles and rates, wrist position and velocity, tool tip,
    loop forces, loop residual, energy (kinetic + potential + elastic), the plane's normal force on
    the tool (world), its magnitude, the gap, the penetration and the friction force (world)."""
    h, _, lam, _, loops, arms, tangential = plane_evaluation(p, c, x, u, f)
    xl = _as_list(x)
    z, zd, residual, energy = _wrist(arms)
    tip = (z[0] + c.tool[0], z[1] + c.tool[1], z[2] + c.tool[2])
    n = c.normal
    return ((xl[0], xl[3], xl[6]), (xl[9], xl[12], xl[15]), z, zd, tip, loops, residual,
            energy + _elastic(c.law, h), (lam * n[0], lam * n[1], lam * n[2]), lam, h, max(-h, 0.0),
            world_force(c.friction, tangential))


# ------------------------------------------------------------------- the tool, a box and a table

class BoxTable(NamedTuple):
    """The tool, a box (planar in x-z: centre x, height above the table, rotation) and the table.

    Contacts: 0 tool tip - table, 1 tool tip - box top face, 2-5 box corners - table."""

    tool: F3  #: tool tip relative to the plate centre (m)
    table: float  #: table height (m)
    pole: float  #: Baumgarte pole of the loop closures (1/s)
    top: float  #: height of the box's top face above its centre of mass, body frame (m)
    mass: float  #: box mass (kg)
    inertia: float  #: box inertia about its centre of mass (kg m^2)
    g: float  #: gravity (m/s^2)
    corners: F8  #: corners relative to the centre of mass (x, z per corner), body frame
    force: F3  #: extra generalised force on the box (Fx, Fz, torque)
    laws: tuple[ContactLaw, ContactLaw, ContactLaw, ContactLaw, ContactLaw, ContactLaw]


def box_evaluation(p: DeltaParams, c: BoxTable, x: Sequence[float], u: Sequence[float],
                   f: Sequence[float]) -> tuple:
    """One evaluation at ``x = [q (9), box (3), v (9), box rates (3)]``: (gaps, their rates,
    contact forces, robot v', box accelerations, loop forces, arms, wrist force)."""
    xl = _as_list(x)
    ql, vl = xl[:9], xl[12:21]
    bx, bz, theta = xl[9], xl[10], xl[11]
    bvx, bvz, bw = xl[21], xl[22], xl[23]
    fl = _as_list(f)
    x_wrist, row_x = wrist_along(p, (1.0, 0.0, 0.0), ql)
    z_wrist, row_z = wrist_along(p, (0.0, 0.0, 1.0), ql)
    x_tip = x_wrist + c.tool[0]
    z_tip = z_wrist + c.tool[2] - c.table
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    nx, nz, tx, tz = -sin_t, cos_t, cos_t, sin_t
    dx, dz = x_tip - bx, z_tip - bz
    arm = tx * dx + tz * dz  # lever of the tool's push about the box's centre of mass
    rate_z = 0.0
    rate_n = 0.0
    for k in range(9):
        rate_z += row_z[k] * vl[k]
        rate_n += (nx * row_x[k] + nz * row_z[k]) * vl[k]
    h = [z_tip, nx * dx + nz * dz - c.top]
    hdot = [rate_z, rate_n - nx * bvx - nz * bvz - arm * bw]
    corners = c.corners
    # corner j's world offset from the centre of mass is (lever, height): its gap's rate is
    # bvz + lever * bw, and lever times its force its torque on the box
    levers = [corners[2 * j] * cos_t - corners[2 * j + 1] * sin_t for j in range(4)]
    for j in range(4):
        h.append(bz + (corners[2 * j] * sin_t + corners[2 * j + 1] * cos_t))
        hdot.append(bvz + levers[j] * bw)
    lam = [contact_force(c.laws[i], h[i], hdot[i]) for i in range(6)]
    wrist = (fl[0] + nx * lam[1], fl[1], fl[2] + lam[0] + nz * lam[1])
    vdot, loops, arms = _evaluate(p, ql, vl, u, wrist, c.pole)
    fx = c.force[0] - nx * lam[1]
    fz = -c.mass * c.g + c.force[1] - nz * lam[1]
    torque = c.force[2] - arm * lam[1]
    for j in range(4):
        fz += lam[2 + j]
        torque += levers[j] * lam[2 + j]
    box = (fx / c.mass, fz / c.mass, torque / c.inertia)
    return h, hdot, lam, vdot, box, loops, arms, wrist


def box_derivatives(p: DeltaParams, c: BoxTable, x: Sequence[float], u: Sequence[float],
                    f: Sequence[float]) -> list[float]:
    """``x' = [v, box rates, v', box accelerations]`` (24 values)."""
    _, _, _, vdot, box, _, _, _ = box_evaluation(p, c, x, u, f)
    xl = _as_list(x)
    return xl[12:] + vdot + [box[0], box[1], box[2]]


def box_indicators(p: DeltaParams, c: BoxTable, x: Sequence[float], u: Sequence[float],
                   f: Sequence[float]) -> F12:
    """The twelve event indicators: the six contacts' first, then their second."""
    h, hdot, _, _, _, _, _, _ = box_evaluation(p, c, x, u, f)
    z = [indicator_pair(c.laws[i], h[i], hdot[i]) for i in range(6)]
    return (z[0][0], z[1][0], z[2][0], z[3][0], z[4][0], z[5][0],
            z[0][1], z[1][1], z[2][1], z[3][1], z[4][1], z[5][1])


def box_outputs(p: DeltaParams, c: BoxTable, x: Sequence[float], u: Sequence[float],
                f: Sequence[float]) -> tuple:
    """DeltaRobotBox's outputs: servo angles and rates, wrist position and velocity, tool tip, loop
    forces, loop residual, energy (robot and box, kinetic + potential, + elastic), the six contact
    forces, gaps and penetrations, and the force of the table and the box on the tool (world)."""
    h, _, lam, _, _, loops, arms, wrist = box_evaluation(p, c, x, u, f)
    xl = _as_list(x)
    fl = _as_list(f)
    z, zd, residual, energy = _wrist(arms)
    bvx, bvz, bw = xl[21], xl[22], xl[23]
    energy += 0.5 * (c.mass * bvx * bvx + c.mass * bvz * bvz + c.inertia * bw * bw) + c.mass * c.g * xl[10]
    for i in range(6):
        energy += _elastic(c.laws[i], h[i])
    tip = (z[0] + c.tool[0], z[1] + c.tool[1], z[2] + c.tool[2])
    forces = (lam[0], lam[1], lam[2], lam[3], lam[4], lam[5])
    gaps = (h[0], h[1], h[2], h[3], h[4], h[5])
    return ((xl[0], xl[3], xl[6]), (xl[12], xl[15], xl[18]), z, zd, tip, loops, residual, energy, forces, gaps,
            (max(-h[0], 0.0), max(-h[1], 0.0), max(-h[2], 0.0), max(-h[3], 0.0), max(-h[4], 0.0), max(-h[5], 0.0)),
            (wrist[0] - fl[0], wrist[1] - fl[1], wrist[2] - fl[2]))
