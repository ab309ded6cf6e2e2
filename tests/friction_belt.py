"""The stick-slip oscillator: a block (mass ``m``) on a belt moving at ``v_b > 0``, held to a wall
by a spring ``k``, normal force ``N``, Coulomb friction ``mu_s > mu_k`` (``c_v = 0``).

Limit cycle (derived here; ``omega = sqrt(k / m)``, ``x_k = mu_k N / k``,
``Delta = (mu_s - mu_k) N / k``):

* STICK: the block rides the belt, ``x' = v_b``, held by ``lambda_t = k x`` until
  ``k x = mu_s N``: release at ``x_r = x_k + Delta``.
* SLIP (``v_t = x' - v_b < 0``, friction ``+mu_k N``): ``m x'' = -k (x - x_k)``, from
  ``(x_k + Delta, v_b)``: ``x - x_k = R cos(omega tau - phi)`` with
  ``R = sqrt(Delta^2 + (v_b / omega)^2)``, ``phi = atan2(v_b / omega, Delta)``. The velocity is
  back at ``v_b`` when ``omega tau = pi + 2 phi``, at ``x = x_k - Delta``, where the stick force
  ``k x = (2 mu_k - mu_s) N`` is inside the static cone: it sticks again.
* STICK from ``x_k - Delta`` to ``x_k + Delta`` at ``v_b``: ``2 Delta / v_b``.

Period ``T = 2 Delta / v_b + (pi + 2 phi) / omega``; the block oscillates about ``x_k`` with
amplitude ``R`` (``x`` spans ``[x_k - R, x_k + R]``, both extremes reached while slipping).
The first stick, from any start, lands on this cycle (the release point is always ``x_r``).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from deltafmi.physics.friction.law import FrictionParams
from deltafmi.physics.friction.planar_block import PlanarBlock
from deltafmi.physics.friction.system import FrictionSystem

__all__ = ["make_belt_oscillator", "stick_slip_cycle"]


class StickSlipCycle(NamedTuple):
    """The closed-form limit cycle."""

    period: float
    amplitude: float         #: R
    centre: float            #: x_k
    release: float           #: x at STICK -> SLIP
    capture: float           #: x at SLIP -> STICK
    slip_duration: float


def stick_slip_cycle(mass: float, stiffness: float, normal_force: float, belt_speed: float,
                     friction: FrictionParams) -> StickSlipCycle:
    """Period, amplitude and switching points of the limit cycle (module docstring)."""
    omega = math.sqrt(stiffness / mass)
    x_k = friction.mu_k * normal_force / stiffness
    delta = (friction.mu_s - friction.mu_k) * normal_force / stiffness
    phi = math.atan2(belt_speed / omega, delta)
    slip = (math.pi + 2.0 * phi) / omega
    return StickSlipCycle(2.0 * delta / belt_speed + slip, math.hypot(delta, belt_speed / omega),
                          x_k, x_k + delta, x_k - delta, slip)


def make_belt_oscillator(friction: FrictionParams, *, mass: float = 1.0, stiffness: float = 100.0,
                         belt_speed: float = 0.1, g: float = 9.81,
                         x0: float = 0.0) -> tuple[FrictionSystem, np.ndarray]:
    """The system (normal force ``m g``) and the initial state: at rest at ``x0``."""
    model = PlanarBlock(mass, (0.0, -mass * g), friction, stiffness=stiffness, surface_speed=belt_speed)
    system = FrictionSystem(model, v_ref=belt_speed, f_ref=mass * g)
    return system, np.array([x0, 0.0, 0.0, 0.0])
