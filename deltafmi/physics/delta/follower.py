"""A target follower: the wrist reference that chases an operator's target within set limits.

Pure functions over floats (the FMU's compiled kernels are these, translated to C by
:mod:`deltafmi.builder.codegen`: fixed-size NamedTuples, ``math`` only). The law, per axis vector
in task space (metres):

- the target is clamped to the nominal workspace (horizontal radius <= r_max, z_min <= z <= z_max:
  the cylinder the Trajectory enforces), radially for the horizontal part;
- outer loop: speed command ``vd = (wn / 2) e``, ``e = target - r``, its norm limited to
  ``min(v_max, sqrt(a_max |e|))`` (the second term is the speed from which braking at a_max / 2
  stops within |e|: half the limit, so that the inner loop's lag still stops in time);
- inner loop: ``a = 2 wn (vd - r')``, its norm limited to ``a_max``.

Unlimited, the two loops are ``r'' = wn^2 e - 2 wn r'``: a critically damped approach with
bandwidth ``wn`` (the step response ``1 - (1 + wn t) exp(-wn t)``). Each sample of period ``h``
advances the state exactly for the target held over the sample: in the linear region (no limit
active at the sample's start) by the closed-form solution of the critically damped system; with a
limit active, with the speed command ``vd`` held over the sample and the inner loop solved exactly
(the velocity moves straight towards ``vd``: first at ``a_max`` while ``|vd - r'| > a_max / (2 wn)``,
then exponentially at rate ``2 wn``). So ``|r'| <= v_max`` and ``|r''| <= a_max`` hold at every
sample, and a far target is approached at constant direction by a closed-form cruise.

Timing (:func:`sample`): the sample at t_k reads the target and advances the state to t_k + h,
the outputs held from t_k; a Co-Simulation step from t over h takes the samples in [t, t + h)
with the target at t (:func:`follower_step`), as the delta controller's samples do.
"""

from __future__ import annotations

import math
from typing import NamedTuple

__all__ = ["FollowerSettings", "FollowerState", "STATUS_CLAMPED", "STATUS_SPEED_LIMITED", "STATUS_ACCEL_LIMITED",
           "acceleration", "advance", "clamp_target", "initial_state", "sample", "follower_outputs",
           "follower_step", "follower_update"]

F3 = tuple[float, float, float]

#: status bits: the target lies outside the workspace (clamped), the speed / acceleration limit acts
STATUS_CLAMPED = 1
STATUS_SPEED_LIMITED = 2
STATUS_ACCEL_LIMITED = 4


class FollowerSettings(NamedTuple):
    """The follower's parameters."""

    wn: float               #: bandwidth of the critically damped approach (rad/s)
    v_max: float            #: speed limit, vector norm (m/s)
    a_max: float            #: acceleration limit, vector norm (m/s^2)
    sample_period: float    #: s
    r_max: float            #: workspace: horizontal radius (m)
    z_min: float            #: workspace: lowest z (m)
    z_max: float            #: workspace: highest z (m)


class FollowerState(NamedTuple):
    """The follower after its last sample: the reference at the next sample instant."""

    r: F3                   #: position (m)
    v: F3                   #: velocity (m/s)
    target: F3              #: the clamped target read at the last sample (m)
    status: int             #: STATUS_* bits of the last sample (the limits that acted in it)


def _norm(x: F3) -> float:
    return math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])


def clamp_target(s: FollowerSettings, target: F3) -> tuple[F3, int]:
    """The target moved into the workspace (the nearest point of the cylinder) and STATUS_CLAMPED
    when it had to move."""
    x, y, z = target
    status = 0
    rho = math.sqrt(x * x + y * y)
    if rho > s.r_max:
        x, y = x * (s.r_max / rho), y * (s.r_max / rho)
        status = STATUS_CLAMPED
    if z < s.z_min:
        z, status = s.z_min, STATUS_CLAMPED
    elif z > s.z_max:
        z, status = s.z_max, STATUS_CLAMPED
    return (x, y, z), status


def _speed_command(s: FollowerSettings, r: F3, target: F3) -> tuple[F3, int]:
    """The outer loop's speed command vd and STATUS_SPEED_LIMITED when its limit acts."""
    e = (target[0] - r[0], target[1] - r[1], target[2] - r[2])
    d = _norm(e)
    k = 0.5 * s.wn
    limit = min(s.v_max, math.sqrt(s.a_max * d))
    if k * d > limit:
        g = limit / d
        return (g * e[0], g * e[1], g * e[2]), STATUS_SPEED_LIMITED
    return (k * e[0], k * e[1], k * e[2]), 0


def _inner(s: FollowerSettings, vd: F3, v: F3) -> tuple[F3, int]:
    """The inner loop's acceleration towards the speed command ``vd`` and STATUS_ACCEL_LIMITED."""
    c = 2.0 * s.wn
    a = (c * (vd[0] - v[0]), c * (vd[1] - v[1]), c * (vd[2] - v[2]))
    n = _norm(a)
    if n > s.a_max:
        g = s.a_max / n
        return (g * a[0], g * a[1], g * a[2]), STATUS_ACCEL_LIMITED
    return a, 0


def acceleration(s: FollowerSettings, r: F3, v: F3, target: F3) -> tuple[F3, int]:
    """The law's acceleration at position ``r``, velocity ``v`` towards ``target`` (clamped
    already), and the STATUS_SPEED_LIMITED / STATUS_ACCEL_LIMITED bits that act there."""
    vd, speed = _speed_command(s, r, target)
    a, accel = _inner(s, vd, v)
    return a, speed | accel


def _axis(wn: float, E: float, x0: float, v0: float, h: float) -> tuple[float, float]:
    """x(h), x'(h) of x'' = -wn^2 x - 2 wn x' from x0, v0; E = exp(-wn h)."""
    c = v0 + wn * x0
    return (x0 + c * h) * E, (v0 - wn * c * h) * E


def _linear(wn: float, r: F3, v: F3, target: F3, h: float) -> tuple[F3, F3]:
    """Exact solution over ``h`` of the unlimited law, x'' = -wn^2 x - 2 wn x' with x = r - target."""
    E = math.exp(-wn * h)
    x0, v0 = _axis(wn, E, r[0] - target[0], v[0], h)
    x1, v1 = _axis(wn, E, r[1] - target[1], v[1], h)
    x2, v2 = _axis(wn, E, r[2] - target[2], v[2], h)
    return (target[0] + x0, target[1] + x1, target[2] + x2), (v0, v1, v2)


def _limited(s: FollowerSettings, r: F3, v: F3, vd: F3, h: float) -> tuple[F3, F3]:
    """Exact solution over ``h`` of r'' = 2 wn (vd - r') with its norm limited to a_max, vd held:
    the gap D = |vd - r'| closes along a fixed direction, D' = -min(2 wn D, a_max)."""
    g = (vd[0] - v[0], vd[1] - v[1], vd[2] - v[2])
    D = _norm(g)
    if D == 0.0:
        return (r[0] + v[0] * h, r[1] + v[1] * h, r[2] + v[2] * h), v
    c = 2.0 * s.wn
    Dc = s.a_max / c     # below this gap the acceleration is not limited
    t1 = 0.0             # time at the limit
    D1 = D               # the gap when the limit ends
    integral = 0.0       # of the gap over the sample
    if D > Dc:
        t1 = min((D - Dc) / s.a_max, h)
        D1 = D - s.a_max * t1
        integral = D * t1 - 0.5 * s.a_max * t1 * t1
    E = math.exp(-c * (h - t1))
    Dh = D1 * E
    integral += D1 * (1.0 - E) / c
    f = Dh / D
    q = integral / D
    v1 = (vd[0] - f * g[0], vd[1] - f * g[1], vd[2] - f * g[2])
    r1 = (r[0] + vd[0] * h - q * g[0], r[1] + vd[1] * h - q * g[1], r[2] + vd[2] * h - q * g[2])
    return r1, v1


def advance(s: FollowerSettings, r: F3, v: F3, target: F3, h: float) -> tuple[F3, F3, int]:
    """Position and velocity ``h`` later with ``target`` (clamped) held, and the status bits of the
    limits acting at the start."""
    vd, speed = _speed_command(s, r, target)
    _, accel = _inner(s, vd, v)
    status = speed | accel
    if status == 0:
        r1, v1 = _linear(s.wn, r, v, target, h)
        return r1, v1, 0
    r1, v1 = _limited(s, r, v, vd, h)
    return r1, v1, status


def initial_state(s: FollowerSettings, r0: F3, target: F3) -> FollowerState:
    """At rest at ``r0`` before any sample, ``target`` the input then (for the first outputs)."""
    held, clamped = clamp_target(s, target)
    _, status = acceleration(s, r0, (0.0, 0.0, 0.0), held)
    return FollowerState(r0, (0.0, 0.0, 0.0), held, status | clamped)


def sample(s: FollowerSettings, state: FollowerState, target: F3) -> FollowerState:
    """The sample at t_k: ``target`` read (and clamped), then the state advanced to t_k + h with it
    held. The outputs held from t_k are the reference at the next instant, as a Co-Simulation
    step from t_k ends with the reference at its end."""
    held, clamped = clamp_target(s, target)
    r, v, status = advance(s, state.r, state.v, held, s.sample_period)
    return FollowerState(r, v, held, status | clamped)


def follower_outputs(s: FollowerSettings, state: FollowerState) -> tuple[F3, F3, F3, int]:
    """The outputs r, rd, rdd, status of ``state``: rdd is the law's acceleration there."""
    a, _ = acceleration(s, state.r, state.v, state.target)
    return state.r, state.v, a, state.status


def follower_step(s: FollowerSettings, state: FollowerState, t0: float, k: int, t: float, h: float,
                  target: F3) -> tuple[FollowerState, int, F3, F3, F3, int]:
    """The Co-Simulation step from ``t`` over ``h``: the samples due in [t, t + h) with the target
    at ``t``. Returns the state, the next sample's index and the outputs r, rd, rdd, status."""
    period = s.sample_period
    end = t + h - 1e-9 * period
    while t0 + k * period < end:
        state = sample(s, state, target)
        k += 1
    r, rd, rdd, status = follower_outputs(s, state)
    return state, k, r, rd, rdd, status


def follower_update(s: FollowerSettings, state: FollowerState, t0: float, k: int, t: float,
                    target: F3) -> tuple[FollowerState, int, float, F3, F3, F3, int]:
    """The event update at ``t`` (Model Exchange's time events, FMI 3.0 Clock ticks): the sample
    due at ``t``, if any. Returns the state, the next sample's index, the next sample instant and
    the outputs."""
    period = s.sample_period
    if t >= t0 + k * period - 1e-9 * period:
        state = sample(s, state, target)
        k += 1
        while t0 + k * period <= t:  # never schedule an instant already passed
            k += 1
    r, rd, rdd, status = follower_outputs(s, state)
    return state, k, t0 + k * period, r, rd, rdd, status
