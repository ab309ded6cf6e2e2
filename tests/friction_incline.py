"""A block on an incline of angle ``theta``, with its closed-form motion.

Frame: ``x`` down the slope, ``y`` the outward normal; gravity is ``m g (sin theta, -cos theta)``,
so the normal force is ``N = m g cos theta``. Closed forms (Coulomb, ``c_v = 0``):

* at rest it sticks forever iff ``tan theta <= mu_s``, with ``lambda_t = -m g sin theta``;
* sliding down (``v > 0``): ``a = g (sin theta - mu_k cos theta)``;
* sliding up (``v < 0``): ``a = g (sin theta + mu_k cos theta)``, stopping at ``t1 = -v0 / a``
  after ``-v0^2 / (2 a)``; it then sticks if ``tan theta <= mu_s``, else slides down from rest;
* with viscous friction, sliding down from rest: ``v = v_inf (1 - exp(-c_v t / m))``,
  ``v_inf = m a / c_v``, ``x = v_inf (t - m / c_v (1 - exp(-c_v t / m)))``;
* free to slide in the incline's plane (2-D friction, :func:`make_plane_incline`): the path
  invariant of :func:`plane_path_invariant` and the stop time of :func:`plane_stop_time`.
"""
from __future__ import annotations

import math

import numpy as np

from deltafmi.physics.friction.law import FrictionParams
from deltafmi.physics.friction.planar_block import PlanarBlock
from deltafmi.physics.friction.system import FrictionSystem

__all__ = ["incline_position", "incline_viscous_position", "make_incline", "make_plane_incline", "plane_path_invariant",
           "plane_stop_time"]


def make_incline(theta: float, friction: FrictionParams, *, mass: float = 1.0, g: float = 9.81,
                 v0: float = 0.0) -> tuple[FrictionSystem, np.ndarray]:
    """The system and its initial state ``[x, y, x', y'] = [0, 0, v0, 0]``."""
    force = (mass * g * math.sin(theta), -mass * g * math.cos(theta))
    system = FrictionSystem(PlanarBlock(mass, force, friction), v_ref=1.0, f_ref=mass * g)
    return system, np.array([0.0, 0.0, v0, 0.0])


def incline_position(t: float, theta: float, friction: FrictionParams, *, g: float = 9.81,
                     v0: float = 0.0) -> float:
    """Closed-form ``x(t)`` down the slope for Coulomb friction (``c_v = 0``), any ``v0``."""
    s, c = math.sin(theta), math.cos(theta)
    a_down = g * (s - friction.mu_k * c)
    x0 = 0.0
    if v0 < 0.0:                                   # decelerates up the slope, stops at t1
        a_up = g * (s + friction.mu_k * c)
        t1 = -v0 / a_up
        if t <= t1:
            return v0 * t + 0.5 * a_up * t * t
        x0, t, v0 = -v0 * v0 / (2.0 * a_up), t - t1, 0.0
    if v0 == 0.0 and math.tan(theta) <= friction.mu_s:
        return x0
    return x0 + v0 * t + 0.5 * a_down * t * t


def incline_viscous_position(t: float, theta: float, friction: FrictionParams, mass: float,
                             *, g: float = 9.81) -> float:
    """Closed-form ``x(t)`` sliding from rest with Coulomb and viscous friction (``tan theta > mu_s``)."""
    a = g * (math.sin(theta) - friction.mu_k * math.cos(theta))
    tau = mass / friction.c_v
    return a * tau * (t - tau * (-math.expm1(-t / tau)))


# --- in the plane of the incline (2-D tangential friction) ---------------------------------
def make_plane_incline(theta: float, friction: FrictionParams, velocity: tuple[float, float], *,
                       mass: float = 1.0, g: float = 9.81) -> tuple[FrictionSystem, np.ndarray]:
    """The block free to slide in the incline's plane: ``(x, y, z)`` with ``x`` down the slope,
    ``y`` across, ``z`` the normal; initial state at the origin with tangential ``velocity``."""
    force = (mass * g * math.sin(theta), 0.0, -mass * g * math.cos(theta))
    system = FrictionSystem(PlanarBlock(mass, force, friction), v_ref=1.0, f_ref=mass * g)
    return system, np.array([0.0, 0.0, 0.0, velocity[0], velocity[1], 0.0])


def plane_path_invariant(vx: float, vy: float, theta: float, mu_k: float) -> float:
    """Constant of the Coulomb slide in the incline's plane (``c_v = 0``). With ``phi`` the angle
    from the downslope axis, ``v' = g (sin th cos phi - mu_k cos th)``, ``v phi' = -g sin th sin phi``,
    so ``d ln v / d phi = -cot phi + n / sin phi`` (``n = mu_k / tan th``) and
    ``I = v sin phi / tan^n(phi / 2) = |v_y|^(1 - n) (v + v_x)^n`` is constant."""
    n = mu_k / math.tan(theta)
    return abs(vy) ** (1.0 - n) * (math.hypot(vx, vy) + vx) ** n


def plane_stop_time(vx: float, vy: float, theta: float, mu_k: float, *, g: float = 9.81) -> float:
    """Time to stop from ``(vx, vy)`` when ``n = mu_k / tan th > 1``: with ``u = tan(phi / 2)``,
    ``t = -int v dphi / (g sin th sin phi) = I / (2 g sin th) (u0^(n-1) / (n-1) + u0^(n+1) / (n+1))``."""
    n = mu_k / math.tan(theta)
    u0 = abs(vy) / (math.hypot(vx, vy) + vx)
    invariant = plane_path_invariant(vx, vy, theta, mu_k)
    return invariant / (2.0 * g * math.sin(theta)) * (u0 ** (n - 1.0) / (n - 1.0) + u0 ** (n + 1.0) / (n + 1.0))
