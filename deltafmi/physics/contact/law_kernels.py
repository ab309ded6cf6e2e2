"""The collision law of :class:`~.collision_law.CollisionLaw` as plain-float kernels.

Its constants as a NamedTuple (:class:`LawConstants`, evaluated once from the law's properties)
and its acceleration, potential and end indicator as functions of them, in the Python subset
``deltafmi build`` translates to C (deltafmi/builder/codegen/translate.py): the compiled contact
models of :mod:`deltafmi.physics.contact_problems` and :mod:`deltafmi.physics.delta` share them.
"""
from __future__ import annotations

from typing import NamedTuple

from .collision_law import CollisionLaw

__all__ = ["LawConstants", "law_constants", "law_acceleration", "law_potential", "law_end_indicator"]


class LawConstants(NamedTuple):
    """A :class:`CollisionLaw`'s numbers, as its methods compute them (per unit effective mass)."""

    kappa: float
    gamma: float
    exponent: float
    q: float
    length: float
    reference_speed: float
    chi: float


def law_constants(law: CollisionLaw) -> LawConstants:
    """The constants of ``law`` (its properties, evaluated once)."""
    return LawConstants(law.kappa, law.gamma, law.exponent, law.q, law.length, law.reference_speed,
                        law.calibration.chi)


def _sgnpow(x: float, m: float) -> float:
    a = abs(x) ** m
    return a if x >= 0.0 else -a


def law_acceleration(law: LawConstants, delta: float, delta_dot: float) -> float:
    """:meth:`CollisionLaw.acceleration`: ``(kappa delta**p + gamma delta**q delta')_+``."""
    if delta <= 0.0:
        return 0.0
    a = law.kappa * delta ** law.exponent + law.gamma * delta ** law.q * delta_dot
    return a if a > 0.0 else 0.0


def law_potential(law: LawConstants, delta: float) -> float:
    """:meth:`CollisionLaw.potential`: ``kappa delta**(p+1) / (p+1)``, zero when open."""
    if delta <= 0.0:
        return 0.0
    return law.kappa * delta ** (law.exponent + 1.0) / (law.exponent + 1.0)


def law_end_indicator(law: LawConstants, delta: float, delta_dot: float) -> float:
    """:meth:`CollisionLaw.end_indicator`: positive while the law pushes."""
    m = law.exponent - law.q
    return _sgnpow(_sgnpow(delta / law.length, m) + law.chi * (delta_dot / law.reference_speed), 1.0 / m)
