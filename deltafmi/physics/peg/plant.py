"""The 6-DOF delta + wrist plant with its peg in the fixture: float kernels (compiled into the
DeltaWristPeg FMU).

The plant is deltafmi.physics.delta_wrist.dynamics (state x = [q (9), qw (3), v (9), vw (3)]),
whose inputs f (force on the tool tip) and moment (couple on the tool) are world-frame. The tool
pose comes from the state: plate centre z and velocity zd as the mean of the three arm ends (as
the plant's own outputs), wrist centre O = z + mount, tip = O + tip_position(qw),
R = tool_rotation(qw), omega = J_w(qw) vw and v_tip = zd + omega x (tip - O). The fixture's
:func:`.contact.peg_wrench` there (force on the peg at the tip and moment about the tip, i.e. a
force at the tip plus a couple) is added to f and moment:

    x' = delta_wrist.state_derivative(x, u, tau, f + F_c, moment + M_c)

The F/T sensor between wrist flange and peg reads the contact wrench in the tool frame,
(R^T F_c, R^T M_c), moment about the tip: an ideal sensor with the peg's weight and inertia
compensated (what a controller gets after the usual tool-load compensation), so it reads zero in
free motion.
"""
from __future__ import annotations

from typing import Sequence

from ..delta.dynamics import F3, F6, F9, _arm_wrist, _as_list
from ..delta.kinematics import ARM_COS_SIN
from ..delta.params import DeltaParams
from ..delta_wrist.dynamics import plant_outputs as wrist_outputs
from ..delta_wrist.dynamics import state_derivative as wrist_derivative
from ..delta_wrist.params import WristMount
from ..wrist.kernels import WristConstants, cross, joint_axes, tip_position, tool_rotation
from .contact import PegWrench, hole_rotation, peg_wrench
from .params import Hole, Peg, PegContact

__all__ = ["tool_pose", "plant_wrench", "state_derivative", "plant_outputs", "event_indicators", "sensor"]


def tool_pose(p: DeltaParams, w: WristConstants, m: WristMount, x: Sequence[float]) -> tuple[F3, F9, F3, F3]:
    """(tip, R row-major, tip velocity, omega), world, of the plant state x (module docstring)."""
    xl = _as_list(x)
    l0l3 = p.l0 - p.l3
    (cA, sA), (cB, sB), (cC, sC) = ARM_COS_SIN
    e1 = _arm_wrist(cA, sA, l0l3, p.l1, p.l2, xl[0], xl[1], xl[2], xl[12], xl[13], xl[14])
    e2 = _arm_wrist(cB, sB, l0l3, p.l1, p.l2, xl[3], xl[4], xl[5], xl[15], xl[16], xl[17])
    e3 = _arm_wrist(cC, sC, l0l3, p.l1, p.l2, xl[6], xl[7], xl[8], xl[18], xl[19], xl[20])
    qw, vw = (xl[9], xl[10], xl[11]), (xl[21], xl[22], xl[23])
    rel = tip_position(w, qw)
    a1, a2, a3 = joint_axes(qw)
    omega = (a1[0] * vw[0] + a2[0] * vw[1] + a3[0] * vw[2], a1[1] * vw[0] + a2[1] * vw[1] + a3[1] * vw[2],
             a1[2] * vw[0] + a2[2] * vw[1] + a3[2] * vw[2])
    spin = cross(omega, rel)
    tip = ((e1[0] + e2[0] + e3[0]) / 3.0 + m.x + rel[0], (e1[1] + e2[1] + e3[1]) / 3.0 + m.y + rel[1],
           (e1[2] + e2[2] + e3[2]) / 3.0 + m.z + rel[2])
    v_tip = ((e1[3] + e2[3] + e3[3]) / 3.0 + spin[0], (e1[4] + e2[4] + e3[4]) / 3.0 + spin[1],
             (e1[5] + e2[5] + e3[5]) / 3.0 + spin[2])
    return tip, tool_rotation(qw), v_tip, omega


def plant_wrench(p: DeltaParams, w: WristConstants, m: WristMount, x: Sequence[float], hole: Hole, peg: Peg,
                 law: PegContact) -> PegWrench:
    """The fixture's wrench on the peg at the plant state x."""
    tip, R, v_tip, omega = tool_pose(p, w, m, x)
    return peg_wrench(hole, peg, law, tip, R, v_tip, omega)


def _loaded(c: PegWrench, f: Sequence[float], moment: Sequence[float]) -> tuple[F3, F3]:
    fl, ml = _as_list(f), _as_list(moment)
    return ((fl[0] + c.force[0], fl[1] + c.force[1], fl[2] + c.force[2]),
            (ml[0] + c.moment[0], ml[1] + c.moment[1], ml[2] + c.moment[2]))


def state_derivative(p: DeltaParams, w: WristConstants, m: WristMount, x: Sequence[float], u: Sequence[float],
                     tau: Sequence[float], f: Sequence[float], moment: Sequence[float], pole: float, hole: Hole,
                     peg: Peg, law: PegContact) -> list[float]:
    """x' of the plant with the contact wrench added to the tool's external force and moment."""
    fc, mc = _loaded(plant_wrench(p, w, m, x, hole, peg, law), f, moment)
    return wrist_derivative(p, w, m, x, u, tau, fc, mc, pole)


def sensor(R: F9, c: PegWrench) -> F6:
    """The F/T sensor reading (module docstring): (R^T F_c, R^T M_c), tool frame."""
    F, M = c.force, c.moment
    return (R[0] * F[0] + R[3] * F[1] + R[6] * F[2], R[1] * F[0] + R[4] * F[1] + R[7] * F[2],
            R[2] * F[0] + R[5] * F[1] + R[8] * F[2], R[0] * M[0] + R[3] * M[1] + R[6] * M[2],
            R[1] * M[0] + R[4] * M[1] + R[7] * M[2], R[2] * M[0] + R[5] * M[1] + R[8] * M[2])


def plant_outputs(p: DeltaParams, w: WristConstants, m: WristMount, x: Sequence[float], u: Sequence[float],
                  tau: Sequence[float], f: Sequence[float], moment: Sequence[float], pole: float, hole: Hole,
                  peg: Peg, law: PegContact) -> tuple:
    """DeltaWrist's outputs (delta_wrist.dynamics.plant_outputs, with the contact wrench applied) then
    the peg's: depth, contact force (3), contact moment about the tip (3), F/T sensor (6), lateral
    and angular misalignment, largest normal force, active contacts."""
    tip, R, v_tip, omega = tool_pose(p, w, m, x)
    c = peg_wrench(hole, peg, law, tip, R, v_tip, omega)
    fc, mc = _loaded(c, f, moment)
    plant = wrist_outputs(p, w, m, x, u, tau, fc, mc, pole)
    return plant + (c.depth, c.force, c.moment, sensor(R, c), c.lateral, c.angular, c.max_normal, c.active)


def event_indicators(p: DeltaParams, w: WristConstants, m: WristMount, x: Sequence[float], hole: Hole,
                     success: int, target: float) -> tuple[float]:
    """The success event: depth - target (tip below the hole's top along its axis), 1 once latched."""
    tip = tool_pose(p, w, m, x)[0]
    Rh = hole_rotation(hole)
    depth = -(Rh[2] * (tip[0] - hole.x) + Rh[5] * (tip[1] - hole.y) + Rh[8] * (tip[2] - hole.z))
    return (1.0 if success else depth - target,)
