"""The wrist's load on the delta's travelling plate, with the wrist's joints eliminated.

The plate only translates (its parallelograms hold its orientation), so the wrist centre O moves
with the plate's acceleration a and the wrist sees gravity g_eff = g_vec - a (see
:mod:`.dynamics`). Newton's law for the whole wrist (mass m, total first moment s = sum_i s_i,
sdd = J_s qdd + b_s) gives the force on the plate

    F = m (g_vec - a) - J_s qdd - b_s + f_ext,
    qdd = M^-1 (tau - h - D qd + J_s^T (g_vec - a))            (wrist dynamics, base moving)

and eliminating qdd:

    F = -Lambda a + f_0,   Lambda = m 1 - J_s M^-1 J_s^T,
    f_0 = Lambda g_vec - J_s M^-1 (tau - h - D qd) - b_s + f_ext.

Lambda (symmetric, positive definite: m 1 minus what the free joints let swing) is the wrist's
apparent mass at O and f_0 the force it would exert on a non-accelerating plate. tau holds every
generalized force on the wrist's joints, J_p^T f_tip for a force f_tip at the tool tip included,
and f_ext the resultant external force (f_tip); the torque on the plate is reacted by the
parallelograms and does not load the servos (its couple on each elbow has no component along
the servo axis), so the 9-coordinate delta model needs only F.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

from .dynamics import (WristState, _free_torques, _mass_matrix, _moment_acceleration, _velocity_product,
                       first_moment_jacobian)
from .params import WristParams

__all__ = ["PlateLoad", "plate_load"]

ArrayLike = Sequence[float] | np.ndarray


class PlateLoad(NamedTuple):
    """The wrist's force on the plate as a function of the plate's acceleration a: -Lambda a + f0."""

    apparent_mass: np.ndarray  #: Lambda (3, 3), kg
    force: np.ndarray  #: f0 (3,), N


def plate_load(p: WristParams, q: ArrayLike, qd: ArrayLike, tau: ArrayLike,
               external_force: ArrayLike | None = None) -> PlateLoad:
    """Lambda and f0 of the module docstring at (q, qd) with joint torques tau (N m)."""
    st = WristState(p, q, qd)
    M = _mass_matrix(st)
    Js = first_moment_jacobian(p, q)
    MinvJsT = np.linalg.solve(M, Js.T)
    Lam = st.masses.sum() * np.eye(3) - Js @ MinvJsT
    Lam = 0.5 * (Lam + Lam.T)
    b_s = _moment_acceleration(st, _velocity_product(st))
    f0 = Lam @ np.array([0.0, 0.0, -p.g]) - MinvJsT.T @ _free_torques(p, st, qd, tau) - b_s
    if external_force is not None:
        f0 = f0 + np.asarray(external_force, dtype=float)
    return PlateLoad(Lam, f0)
