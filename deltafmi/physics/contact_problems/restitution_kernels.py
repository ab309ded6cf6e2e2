"""The restitution ball's kernels: its ``ContactSystem`` evaluation in plain floats (see
:mod:`.contact_kernels`), compiled into its FMU and called by its Python methods alike."""
from __future__ import annotations

from typing import NamedTuple, Sequence

from ..contact.law_kernels import LawConstants
from .contact_kernels import (contact_response, elastic_energy, free_rates, indicator_pairs,
                              kinetic_energy)

__all__ = ["BallModes", "RestitutionBall", "ball_derivatives", "ball_evaluate", "ball_indicators", "ball_outputs"]


class RestitutionBall(NamedTuple):
    """The restitution ball: mass, gravity, its collision law, the CONTACT law."""

    m: float
    g: float
    law: LawConstants
    alpha0: float
    alpha1: float


class BallModes(NamedTuple):
    """The floor contact's mode and effective mass (frozen at the impact)."""

    modes: tuple[int]
    m_eff: tuple[float]


def ball_evaluate(p: RestitutionBall, modes: Sequence[int], m_eff: Sequence[float], x: Sequence[float],
                  force: float) -> tuple:
    """``(h, hdot, H, lambda, v')`` of the ball (gap ``h = q``) under ``force`` for ``modes``."""
    h = [x[0]]
    hdot = [x[1]]
    H = [[1.0]]
    lam, vdot = contact_response(h, hdot, H, [0.0], [p.m], [-p.m * p.g + force], [True], [True], modes, m_eff,
                                 p.law, p.alpha0, p.alpha1)
    return h, hdot, H, lam, vdot


def ball_derivatives(p: RestitutionBall, d: BallModes, x: Sequence[float], force: float) -> list[float]:
    """``[q', v']``."""
    h, hdot, H, lam, vdot = ball_evaluate(p, d.modes, d.m_eff, x, force)
    return free_rates(x[1:], [True]) + vdot


def ball_indicators(p: RestitutionBall, d: BallModes, x: Sequence[float], force: float) -> list[float]:
    """The contact's two event indicators."""
    h, hdot, H, lam, vdot = ball_evaluate(p, d.modes, d.m_eff, x, force)
    return indicator_pairs(h, hdot, lam, [True], d.modes, p.law)


def ball_outputs(p: RestitutionBall, d: BallModes, x: Sequence[float], force: float) -> tuple[float, float]:
    """``(lambda, energy)``: floor force; kinetic + potential + elastic energy."""
    h, hdot, H, lam, vdot = ball_evaluate(p, d.modes, d.m_eff, x, force)
    energy = kinetic_energy([p.m], x[1:]) + p.m * p.g * x[0] + elastic_energy(h, [True], d.modes, d.m_eff, p.law)
    return lam[0], energy
