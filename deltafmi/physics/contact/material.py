"""A compliant contact material in force units: stiffness and damping for sustained contact, a
coefficient of restitution for impacts.

The examples' surfaces are rigid: a :class:`~.collision_law.CollisionLaw` per unit effective mass
in COLLISION and the talk's stabilised constraint ``h'' + alpha1 h' + alpha0 h = 0`` in CONTACT,
which holds the gap shut (zero penetration at rest). A tool pressed on a surface by a controller
is different: what a force controller sees is the compliance of the tool, its pads and the
surface, so the sustained contact is a Kelvin-Voigt element,

    CONTACT:    lambda = (k delta + c delta')_+ ,   delta = -h,

with the static penetration ``F / k`` under a load ``F``. Impacts keep the collision law, matched
to the same spring: at an impact with effective mass ``m_eff`` (frozen, as for every collision)
the linear law (p = 1) gets ``kappa = k / m_eff``, so its force ``m_eff a(delta, delta')`` has the
elastic stiffness ``k`` too, and the damping ``chi(e) sqrt(k m_eff)`` that makes the isolated impact
rebound with exactly ``e`` after ``tau(e) sqrt(m_eff / k)`` seconds (docs/contact.md, section 3).
Capture into CONTACT therefore keeps the elastic force continuous; only the damping changes,
from the impact's (set by ``e``) to the material's ``c``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .collision_law import CollisionLaw, calibrate

__all__ = ["CompliantMaterial"]


@dataclass(frozen=True)
class CompliantMaterial:
    """Linear spring-damper contact (stiffness N/m, damping N s/m) with impact restitution.

    ``reference_speed`` only scales the FREE-mode event indicator (docs/contact.md, section 6).
    """

    stiffness: float
    damping: float
    restitution: float = 0.5
    reference_speed: float = 1.0

    def __post_init__(self) -> None:
        if not (self.stiffness > 0.0 and self.damping >= 0.0 and self.reference_speed > 0.0):
            raise ValueError(f"contact stiffness must be > 0 and damping >= 0, got "
                             f"k = {self.stiffness} N/m, c = {self.damping} N s/m")
        calibrate(self.restitution, 1.0)  # validates the restitution, caches the calibration

    def collision_law(self, m_eff: float) -> CollisionLaw:
        """The linear collision law whose force ``m_eff * a`` has the elastic stiffness ``k``."""
        tau = calibrate(self.restitution, 1.0).tau
        return CollisionLaw(restitution=self.restitution, duration=tau * math.sqrt(m_eff / self.stiffness),
                            reference_speed=self.reference_speed, exponent=1.0)

    def indicator(self, delta: float, delta_dot: float) -> float:
        """``k delta + c delta'`` (N) before the clip: <= 0 where the contact stops pushing."""
        return self.stiffness * delta + self.damping * delta_dot

    def force(self, delta: float, delta_dot: float) -> float:
        """Contact force in CONTACT, ``(k delta + c delta')_+`` (zero with an open gap)."""
        if delta <= 0.0:
            return 0.0
        return max(self.indicator(delta, delta_dot), 0.0)

    def potential(self, delta: float) -> float:
        """Elastic energy ``k delta^2 / 2`` (J)."""
        return 0.5 * self.stiffness * delta * delta if delta > 0.0 else 0.0

    def static_penetration(self, load: float) -> float:
        """Penetration at rest under the normal load ``load`` (N): ``load / k``."""
        return max(load, 0.0) / self.stiffness
