"""The talk's Modelica ball's kernels (:class:`~.bouncing_ball.ModelicaBouncingBall`): plain-float
functions ``deltafmi build`` compiles to C, which the class calls too. The discrete ``contact`` is
an argument: the event iteration that changes it stays in Python."""
from __future__ import annotations

from typing import NamedTuple, Sequence

__all__ = ["ModelicaBall", "modelica_derivatives", "modelica_energy", "modelica_force", "modelica_indicators",
           "modelica_lam", "modelica_outputs"]


class ModelicaBall(NamedTuple):
    """Parameters of ``myBouncingBall``."""

    g: float
    m: float
    a0: float
    a1: float
    a2: float
    lin_flag: bool


def modelica_lam(p: ModelicaBall, contact: int, x: Sequence[float]) -> float:
    """Multiplier of the contact equation when it is active (``contact == 1 or linFlag``), else 0."""
    if not (contact == 1 or p.lin_flag):
        return 0.0
    q = x[0]
    return p.m * (p.g - p.a1 * x[1] - p.a0 * q - p.a2 * q ** 3)


def modelica_force(p: ModelicaBall, contact: int, x: Sequence[float]) -> float:
    """``f = if linFlag then lambda else contact*lambda``."""
    lam = modelica_lam(p, contact, x)
    return lam if p.lin_flag else contact * lam


def modelica_derivatives(p: ModelicaBall, contact: int, x: Sequence[float]) -> list[float]:
    """``der(q) = v``, ``m der(v) = -m g + f``."""
    return [x[1], -p.g + modelica_force(p, contact, x) / p.m]


def modelica_indicators(p: ModelicaBall, contact: int, x: Sequence[float]) -> list[float]:
    """Zero-crossing functions of the relations: h, hDot, and lambda (1 while lambda = 0)."""
    lam_z = modelica_lam(p, contact, x) if (contact == 1 or p.lin_flag) else 1.0
    return [x[0], x[1], lam_z]


def modelica_energy(p: ModelicaBall, x: Sequence[float]) -> float:
    """Mechanical energy ``m v^2 / 2 + m g q``."""
    return 0.5 * p.m * x[1] ** 2 + p.m * p.g * x[0]


def modelica_outputs(p: ModelicaBall, contact: int, x: Sequence[float]) -> tuple[float, float, float]:
    """``(lambda, f, energy)``."""
    return modelica_lam(p, contact, x), modelica_force(p, contact, x), modelica_energy(p, x)
