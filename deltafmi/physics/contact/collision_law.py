"""The compliant collision law of the COLLISION mode and its calibration from material data.

During a collision the gap ``h`` of one contact obeys, for an isolated two-body impact,

    h'' = -a(delta, delta'),   a = kappa * delta**p + gamma * delta**q * delta',   delta = -h >= 0,

with ``q = (p - 1) / 2`` and ``a`` clipped at zero (a contact only pushes). The contact force is
``lambda = m_eff * a`` with ``m_eff = 1 / (H M^-1 H^T)`` frozen at the impact instant, so the talk's
stiff "fast system" is reproduced exactly for an isolated impact while every contact stays a
two-body impact in a chain (see docs/contact.md).

The damping exponent ``q`` makes the law scale-free: with ``delta = L s`` and ``t = (L / v0) tau``,
``L = (v0**2 / kappa)**(1 / (p + 1))``, every impact obeys ``s'' = -(s**p + chi * s**q * s')``,
``s(0) = 0``, ``s'(0) = 1``, with ``chi = gamma / sqrt(kappa)``. The coefficient of restitution
therefore depends on ``chi`` alone (exactly, at every impact speed) and the duration is
``tau_c(chi) * L / v0``. :func:`calibrate` solves that one normalised impact once per ``(e, p)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

from . import dopri

__all__ = ["CollisionLaw", "calibrate", "elastic_duration"]


def _sgnpow(x: float, m: float) -> float:
    return math.copysign(abs(x) ** m, x)


def _end_function(s: float, s_dot: float, m: float, chi: float) -> float:
    """Sign of the normalised force ``s**q (s**m + chi s')`` (m = p - q), as a function that
    crosses zero transversally: the m-th root undoes the flatness of ``s**m`` at ``s = 0``, so an
    elastic law (chi = 0) gives exactly ``s``. Also negative once the gap is open and opening."""
    return _sgnpow(_sgnpow(s, m) + chi * s_dot, 1.0 / m)


@dataclass(frozen=True)
class Calibration:
    """Normalised impact ``s'' = -(s**p + chi s**q s')_+`` for one ``(e, p)``."""

    restitution: float
    exponent: float
    chi: float          #: dimensionless damping ``gamma / sqrt(kappa)``
    tau: float          #: dimensionless duration (time with a positive force)
    s_max: float        #: dimensionless maximal compression


def _normalised_impact(chi: float, p: float) -> tuple[float, float, float]:
    """Integrate the normalised impact; return (restitution, duration, maximal compression)."""
    q = 0.5 * (p - 1.0)

    def rhs(_t: float, y: tuple[float, ...]) -> tuple[float, float]:
        s = max(y[0], 0.0)
        return y[1], -max(s ** p + chi * s ** q * y[1], 0.0)

    def force_zero(_t: float, y: tuple[float, ...]) -> float:
        return _end_function(y[0], y[1], p - q, chi)

    def max_compression(_t: float, y: tuple[float, ...]) -> float:
        return y[1]

    # the undamped impact lasts < 2 * 2**(1/(p+1)) * 1.5; damping only shortens the force phase
    t_end = 20.0
    sol = dopri.integrate(rhs, (0.0, 1.0), t_end, force_zero, [max_compression], rtol=1e-12, atol=1e-14)
    if sol.terminal is None:
        raise RuntimeError(f"normalised impact did not end (chi={chi}, p={p})")
    peak = sol.others[0]
    s_max = peak.y[0] if peak is not None else sol.terminal.y[0]
    return -sol.terminal.y[1], sol.terminal.t, s_max


def elastic_duration(p: float) -> float:
    """Closed-form normalised duration of the undamped impact (``chi = 0``).

    ``tau = 2 s_max B(1/(p+1), 1/2) / (p+1)`` with ``s_max = ((p+1)/2)**(1/(p+1))`` from energy
    conservation ``s'**2/2 + s**(p+1)/(p+1) = 1/2``.
    """
    n = p + 1.0
    s_max = (n / 2.0) ** (1.0 / n)
    beta = math.gamma(1.0 / n) * math.gamma(0.5) / math.gamma(1.0 / n + 0.5)
    return 2.0 * s_max * beta / n


@lru_cache(maxsize=64)
def calibrate(restitution: float, exponent: float) -> Calibration:
    """Find ``chi`` such that the normalised impact rebounds with ``restitution`` (exact to ~1e-10)."""
    e, p = float(restitution), float(exponent)
    if not 0.0 < e <= 1.0:
        raise ValueError(f"restitution must be in (0, 1], got {e}")
    if p < 1.0:
        raise ValueError(f"exponent must be >= 1, got {p}")
    if e == 1.0:
        chi = 0.0
    else:
        hi = 1.0
        while _normalised_impact(hi, p)[0] > e:
            hi *= 4.0
            if hi > 1e7:
                raise ValueError(f"restitution {e} too small to calibrate")
        chi = dopri.find_root(lambda c: _normalised_impact(c, p)[0] - e, 0.0, hi, xtol=1e-14, rtol=1e-13)
    e_got, tau, s_max = _normalised_impact(chi, p)
    return Calibration(restitution=e_got, exponent=p, chi=chi, tau=tau, s_max=s_max)


@dataclass(frozen=True)
class CollisionLaw:
    """Material of a contact: restitution, collision duration at a reference speed, stiffening.

    An isolated two-body impact at ``reference_speed`` rebounds with ``restitution`` and keeps a
    positive force for exactly ``duration`` seconds, whatever the two masses. At another impact
    speed ``v0`` the restitution is unchanged (the law is scale-free) and the duration is
    ``duration * (reference_speed / v0)**((p - 1) / (p + 1))`` (Hertz: the 1/5 power).
    ``exponent`` p = 1 is a linear spring-dashpot, 1.5 Hertz, 3 the talk's cubic ``a2 h**3``.
    """

    restitution: float = 1.0
    duration: float = 1e-4
    reference_speed: float = 1.0
    exponent: float = 3.0
    calibration: Calibration = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.duration <= 0.0 or self.reference_speed <= 0.0:
            raise ValueError("duration and reference_speed must be positive")
        object.__setattr__(self, "calibration", calibrate(self.restitution, self.exponent))

    @property
    def q(self) -> float:
        """Damping exponent ``(p - 1) / 2`` that makes the restitution speed-independent."""
        return 0.5 * (self.exponent - 1.0)

    @property
    def length(self) -> float:
        """Length scale ``L``: ``delta / L`` is the normalised compression at the reference speed."""
        return self.reference_speed * self.duration / self.calibration.tau

    @property
    def kappa(self) -> float:
        """Stiffness per unit effective mass, ``(tau / T) ** (p + 1) * v_ref ** (1 - p)``."""
        p = self.exponent
        return (self.calibration.tau / self.duration) ** (p + 1.0) * self.reference_speed ** (1.0 - p)

    @property
    def gamma(self) -> float:
        """Damping per unit effective mass, ``chi * sqrt(kappa)``."""
        return self.calibration.chi * math.sqrt(self.kappa)

    def acceleration(self, delta: float, delta_dot: float) -> float:
        """Gap deceleration ``a = (kappa delta**p + gamma delta**q delta')_+``; zero when open."""
        if delta <= 0.0:
            return 0.0
        a = self.kappa * delta ** self.exponent + self.gamma * delta ** self.q * delta_dot
        return a if a > 0.0 else 0.0

    def potential(self, delta: float) -> float:
        """Elastic energy per unit effective mass, ``kappa delta**(p+1) / (p+1)``."""
        if delta <= 0.0:
            return 0.0
        return self.kappa * delta ** (self.exponent + 1.0) / (self.exponent + 1.0)

    def end_indicator(self, delta: float, delta_dot: float) -> float:
        """Dimensionless function that is positive while the law pushes and <= 0 where it stops.

        Its sign is that of ``a / (kappa L**(p-q) delta**q) = (delta/L)**(p-q) + chi delta'/v_ref``
        (see ``_end_function``); an elastic law (chi = 0) gives ``delta / L`` and ends at delta = 0.
        """
        return _end_function(delta / self.length, delta_dot / self.reference_speed,
                             self.exponent - self.q, self.calibration.chi)

    def duration_at(self, speed: float) -> float:
        """Duration of an isolated impact at ``speed`` (positive force phase)."""
        p = self.exponent
        return self.duration * (self.reference_speed / speed) ** ((p - 1.0) / (p + 1.0))

    def max_compression(self, speed: float) -> float:
        """Maximal compression of an isolated impact at ``speed``."""
        return self.calibration.s_max * (speed ** 2 / self.kappa) ** (1.0 / (self.exponent + 1.0))
