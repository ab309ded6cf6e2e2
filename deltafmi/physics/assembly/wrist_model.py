"""The spherical wrist as the assembly controller inverts it: inverse dynamics on a translating
base and the wrist's force on the plate (kernel float subset, over the plant's wrist kernels
:mod:`deltafmi.physics.wrist.kernels`).

With the base (the plate, O) accelerating by a_O, the base acts as gravity g_eff = g_vec - a_O
(:mod:`deltafmi.physics.wrist.dynamics`). For the joint accelerations qdd the controller wants:

    tau = M qdd + h + g(g_eff) + D qd - J_w^T m_ext,
    F_plate = m g_eff - (J_s qdd + b_s) + f_ext,

m_ext the external moment about O on the tool (a force F at the tip p and a moment M give
m_ext = p x F + M, i.e. J_p^T F + J_w^T M = J_w^T m_ext), f_ext the external force, F_plate the
force the wrist puts on the plate (Newton's law for the whole wrist, as
:func:`deltafmi.physics.wrist.coupling.plate_load`, read with qdd given instead of tau: no
inertia matrix is inverted).
"""

from __future__ import annotations

from typing import NamedTuple

from ..wrist.kernels import F3, F9, WristConstants, WristTerms, _frame_gravity, _rates, sym_apply, wrist_terms

__all__ = ["WristState", "wrist_state", "inverse_dynamics"]


class WristState(NamedTuple):
    """The wrist at one (q, qd) as the controller sees it."""

    terms: WristTerms   #: M, h, J_s, b_s, axes, R_3, omega (the plant's kernels)
    tool: F9            #: world <- tool, R_3 Rx(pi)
    tip: F3             #: tool tip relative to O, world (m)
    omega: F3           #: the tool's angular velocity J_w qd (rad/s)
    velocity_product: F3  #: Jd_w qd, the tool's angular acceleration at qdd = 0 (rad/s^2)


def wrist_state(w: WristConstants, q: F3, qd: F3) -> WristState:
    """Tool frame, tip, angular velocity and dynamic terms at (q, qd)."""
    t = wrist_terms(w, q, qd)
    r = t.frame.r3
    e3 = _rates(t.frame, qd)[4]
    return WristState(t, (r[0], -r[1], -r[2], r[3], -r[4], -r[5], r[6], -r[7], -r[8]),
                      (-w.tip * r[2], -w.tip * r[5], -w.tip * r[8]), t.omega, e3)


def inverse_dynamics(w: WristConstants, s: WristState, qd: F3, qdd: F3, base_accel: F3, m_ext: F3,
                     f_ext: F3) -> tuple[F3, F3]:
    """(tau, F_plate) of the module docstring: joint torques (N m) and the wrist's force on the plate (N)."""
    t = s.terms
    fr = t.frame
    g_eff = (-base_accel[0], -base_accel[1], -w.g - base_accel[2])
    mq = sym_apply(t.mass, qdd)
    grav = _frame_gravity(fr, g_eff)
    d = w.damping
    tau = (mq[0] + t.bias[0] + grav[0] + d * qd[0] - (fr.a1[0] * m_ext[0] + fr.a1[1] * m_ext[1] + fr.a1[2] * m_ext[2]),
           mq[1] + t.bias[1] + grav[1] + d * qd[1] - (fr.a2[0] * m_ext[0] + fr.a2[1] * m_ext[1] + fr.a2[2] * m_ext[2]),
           mq[2] + t.bias[2] + grav[2] + d * qd[2] - (fr.a3[0] * m_ext[0] + fr.a3[1] * m_ext[1] + fr.a3[2] * m_ext[2]))
    js, bs = t.js, t.bs
    m = w.m1 + w.m2 + w.m3
    force = (m * g_eff[0] - (js[0] * qdd[0] + js[1] * qdd[1] + js[2] * qdd[2] + bs[0]) + f_ext[0],
             m * g_eff[1] - (js[3] * qdd[0] + js[4] * qdd[1] + js[5] * qdd[2] + bs[1]) + f_ext[1],
             m * g_eff[2] - (js[6] * qdd[0] + js[7] * qdd[1] + js[8] * qdd[2] + bs[2]) + f_ext[2])
    return tau, force
