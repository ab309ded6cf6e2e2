"""One sample of the delta robot's sampled controller as a pure function (:func:`sample`).

:class:`~.control.DeltaController` keeps a :class:`SampleState` and calls :func:`sample` once per
sample period; the FMU's C layer runs the same function, translated to C by
:mod:`deltafmi.builder.codegen` (hence the fixed-size, fully annotated NamedTuples and the
subset of Python the translator reads). Per sample: the tactile loop's shift of the reference,
the control law (:func:`.control_law.evaluate`) with the integral frozen while the previous
torque was saturated, the held torque on a singular sample, the zero-order-hold lead
(:func:`.control_law.hold`), Newton's warm start for the next sample and the warning latch.
"""

from __future__ import annotations

from typing import NamedTuple, Optional

from .control_law import (STATUS_ILL_CONDITIONED, STATUS_SINGULAR, STATUS_TORQUE_SATURATED, ControlLaw,
                          describe_status, evaluate, hold, warm_start)

__all__ = ["SampleSettings", "SampleState", "WARNING_BITS", "initial_state", "sample", "warning_text", "F3"]

F3 = tuple[float, float, float]
F6 = tuple[float, float, float, float, float, float]

#: status bits that warn, once each, from one :func:`initial_state` on
WARNING_BITS = STATUS_ILL_CONDITIONED | STATUS_SINGULAR


class SampleSettings(NamedTuple):
    """What a sample needs beyond the :class:`~.control_law.ControlLaw`."""

    sample_period: float    #: s
    zoh_lead: bool          #: the half-sample torque lead (DeltaController's docstring)
    tactile_gain: float     #: reference speed along tactile_axis per N of pad-force difference (m/(N s))
    tactile_axis: F3        #: horizontal unit vector (its z component is 0)


class SampleState(NamedTuple):
    """The controller between samples, and what the last sample produced."""

    integral: F3            #: integral state int(r - z) dt (m s)
    u: F3                   #: the torque held until the next sample (N m)
    status: int             #: STATUS_* bits of the last sample
    cond: float             #: Frobenius condition number of Jc of the last sample (nan before any)
    shift: float            #: the tactile loop's shift of the reference along tactile_axis (m)
    z: Optional[F3]         #: wrist estimate of the last non-singular sample (None before any)
    iterations: int         #: Newton iterations of the last sample (-1: closed form or none)
    u_law: Optional[F3]     #: the law's torque of the last sample, before the lead (None: none)
    x_next: Optional[F6]    #: Newton's warm start for the next sample (None: cold start)
    xd: Optional[F6]        #: the unmeasured angles' rates of the last sample
    warned: int             #: WARNING_BITS warned since initial_state()
    new_warnings: int       #: the WARNING_BITS the last sample raised for the first time


def initial_state() -> SampleState:
    """A controller with no sample taken: no integral, no torque, no warm start, nothing warned."""
    return SampleState((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0, float("nan"), 0.0, None, -1, None, None, None, 0, 0)


def sample(law: ControlLaw, settings: SampleSettings, state: SampleState, y: F3, yd: F3, r: F3, rd: F3,
           rdd: F3, force: F3, tactile: float) -> SampleState:
    """The state after one sample at servo angles ``y`` and rates ``yd`` (rad, rad/s), reference
    ``r``, ``rd``, ``rdd`` (m, m/s, m/s^2), commanded contact force ``force`` (N, impedance mode)
    and tactile pad-force difference ``tactile`` (N); the torque to hold is its ``u``.

    The integral is frozen while the previous torque was saturated (conditional integration);
    a singular sample holds the previous torque (clipped to the limit) and drops the warm start.
    """
    shift = state.shift
    rate = settings.tactile_gain * float(tactile)
    if shift != 0.0 or rate != 0.0:
        ax, ay, _ = settings.tactile_axis
        r = (r[0] + shift * ax, r[1] + shift * ay, r[2])
        rd = (rd[0] + rate * ax, rd[1] + rate * ay, rd[2])
    shift += rate * settings.sample_period
    dt = 0.0 if state.status & STATUS_TORQUE_SATURATED else settings.sample_period
    out = evaluate(law, y, yd, r, rd, rdd, state.integral, dt, state.x_next, force)
    status = out.status
    # the bits not warned yet (status & ~warned, without ~: the translator's ints are | and &)
    raised = status & WARNING_BITS
    new = raised - (raised & state.warned)
    lim = law.torque_limit
    if status & STATUS_SINGULAR:
        u0, u1, u2 = state.u
        held = (min(max(u0, -lim), lim), min(max(u1, -lim), lim), min(max(u2, -lim), lim))
        return SampleState(state.integral, held, status, out.cond, shift, state.z, out.iterations, None, None,
                           None, state.warned | new, new)
    u, clipped = hold(out.u, state.u_law if settings.zoh_lead else None, lim)
    if clipped:
        status = status | STATUS_TORQUE_SATURATED
    # warm start one sample ahead, so one Newton step usually reaches the tolerance
    x0, x1, x2, x3, x4, x5 = warm_start(out.x, out.xd, state.xd, settings.sample_period)
    return SampleState(out.integral, u, status, out.cond, shift, out.z, out.iterations, out.u,
                       (x0, x1, x2, x3, x4, x5), out.xd, state.warned | new, new)


def warning_text(state: SampleState, torque_limit: float) -> Optional[str]:
    """The warning of the last sample's ``new_warnings`` (each WARNING_BITS bit warns once), or None."""
    if not state.new_warnings:
        return None
    return (f"delta controller: {describe_status(state.new_warnings)} (cond(Jc) = {state.cond:.3g}); "
            f"torques saturate at +-{torque_limit:g} N m")
