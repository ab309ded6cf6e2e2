"""The box on the table's kernels: its ``ContactSystem`` evaluation in plain floats (see
:mod:`.contact_kernels`), compiled into its FMU and called by its Python methods alike."""
from __future__ import annotations

import math
from typing import NamedTuple, Sequence

from ..contact.law_kernels import LawConstants
from .contact_kernels import (contact_response, elastic_energy, free_rates, indicator_pairs,
                              kinetic_energy)

__all__ = ["BoxModes", "BoxParams", "box_derivatives", "box_evaluate", "box_indicators", "box_outputs"]

Pair = tuple[float, float]
ALL = (True, True, True, True)  #: every corner is a contact; no coordinate is frozen


class BoxParams(NamedTuple):
    """Mass, inertia about the centre of mass, gravity, corners (body frame, from the centre of
    mass), the corners' collision law and the CONTACT law."""

    mass: float
    inertia: float
    g: float
    corners: tuple[Pair, Pair, Pair, Pair]
    law: LawConstants
    alpha0: float
    alpha1: float


class BoxModes(NamedTuple):
    """Mode and effective mass (frozen at the impact) of each corner."""

    modes: tuple[int, int, int, int]
    m_eff: tuple[float, float, float, float]


def box_evaluate(p: BoxParams, modes: Sequence[int], m_eff: Sequence[float], x: Sequence[float],
                 push: Sequence[float], torque: float) -> tuple:
    """``(h, hdot, H, lambda, v')`` of the box (state ``[x, y, theta, x', y', theta']``) under the
    extra force ``push`` and ``torque``, for ``modes`` (BoxModel's gaps, Jacobian and forces)."""
    c = math.cos(x[2])
    s = math.sin(x[2])
    omega = x[5]
    h = []
    H = []
    hdot = []
    dHv = []
    for cx, cy in p.corners:
        rx = cx * c - cy * s
        ry = cx * s + cy * c
        h.append(x[1] + ry)
        H.append([0.0, 1.0, rx])
        hdot.append(0.0 * x[3] + 1.0 * x[4] + rx * omega)
        dHv.append(-omega ** 2 * ry)
    Q = [0.0 + push[0], -p.mass * p.g + push[1], 0.0 + torque]
    lam, vdot = contact_response(h, hdot, H, dHv, [p.mass, p.mass, p.inertia], Q, ALL[:3], ALL, modes, m_eff,
                                 p.law, p.alpha0, p.alpha1)
    return h, hdot, H, lam, vdot


def box_derivatives(p: BoxParams, d: BoxModes, x: Sequence[float], push: Sequence[float],
                    torque: float) -> list[float]:
    """``[q', v']``."""
    h, hdot, H, lam, vdot = box_evaluate(p, d.modes, d.m_eff, x, push, torque)
    return free_rates(x[3:], ALL[:3]) + vdot


def box_indicators(p: BoxParams, d: BoxModes, x: Sequence[float], push: Sequence[float],
                   torque: float) -> list[float]:
    """Two event indicators per corner."""
    h, hdot, H, lam, vdot = box_evaluate(p, d.modes, d.m_eff, x, push, torque)
    return indicator_pairs(h, hdot, lam, ALL, d.modes, p.law)


def box_outputs(p: BoxParams, d: BoxModes, x: Sequence[float], push: Sequence[float],
                torque: float) -> tuple:
    """``(lambda[4], gap[4], total force, energy)``: corner forces and heights, their sum, kinetic +
    potential + elastic energy."""
    h, hdot, H, lam, vdot = box_evaluate(p, d.modes, d.m_eff, x, push, torque)
    total = 0.0
    for f in lam:
        total = total + f
    energy = (kinetic_energy([p.mass, p.mass, p.inertia], x[3:]) + p.mass * p.g * x[1]
              + elastic_energy(h, ALL, d.modes, d.m_eff, p.law))
    return lam + h + [total, energy]
