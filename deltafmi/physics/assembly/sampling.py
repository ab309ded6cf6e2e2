"""One sample of the assembly controller as a pure function (:func:`sample`), for the FMU's C layer.

Per sample: the reference (the insertion program of :mod:`.program`, or the external tip and
orientation reference), the 6-D impedance law (:func:`.law.evaluate`), the torques held until
the next sample, Newton's warm start for the next sample and the warning latch. A singular
sample (no forward kinematics) holds the previous torques and drops the warm start.

The held torque is the law's torque in two parts. The law is affine in the measured wrench, so
evaluating it once more with the sensor at zero splits it into the MOTION part (inverse dynamics
of the reference and the impedance's spring and damper: smooth between samples) and the FORCE
part (the measured wrench's cancellation and its M_d^-1 feedback). The delta controller's
half-sample lead (:func:`deltafmi.physics.delta.control_law.hold`: 1.5 u_k - 0.5 u_k-1, the
hold's half-sample delay compensated) goes on the motion part only. On the force part it would
double the loop gain at the Nyquist frequency (1.5 + 0.5 = 2 for a signal alternating from one
sample to the next), and against a contact that blocks the tip within one sample (a stiff
spring, or regularised friction at creep speed: a damper of mu f_n / v_eps) that gain is what
decides stability: the force part is held as computed (docs/assembly.md, section 5).
"""

from __future__ import annotations

from typing import NamedTuple, Optional

from ..delta.control_law import STATUS_ILL_CONDITIONED, STATUS_SINGULAR, STATUS_TORQUE_SATURATED, warm_start
from ..wrist.kernels import WristConstants
from .law import STATUS_GIMBAL_DAMPED, STATUS_WRIST_SATURATED, AssemblyLaw, F6, evaluate
from .program import InsertionProgram, reference
from .rotation import F3, F9, TOOL_DOWN, orientation_reference

__all__ = ["AssemblySettings", "AssemblyState", "WARNING_BITS", "initial_state", "sample", "describe_status"]

#: the F/T sensor at zero: the law's motion part
_NO_WRENCH: F6 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
#: status bits that warn, once each
WARNING_BITS = STATUS_ILL_CONDITIONED | STATUS_SINGULAR | STATUS_GIMBAL_DAMPED | STATUS_WRIST_SATURATED

_STATUS_TEXT = ((STATUS_TORQUE_SATURATED, "servo torque saturated"),
                (STATUS_ILL_CONDITIONED, "delta near a singularity"),
                (STATUS_SINGULAR, "singular: no forward kinematics, torques held"),
                (STATUS_GIMBAL_DAMPED, "wrist near gimbal lock: damped inverse"),
                (STATUS_WRIST_SATURATED, "wrist torque saturated"))


def describe_status(status: int) -> str:
    """Human-readable text of a status bit set."""
    return "ok" if status == 0 else "; ".join(t for b, t in _STATUS_TEXT if status & b)


class AssemblySettings(NamedTuple):
    """What a sample needs beyond the law."""

    sample_period: float    #: s
    zoh_lead: bool          #: half-sample lead on the held torques
    use_program: bool       #: the insertion program (true) or the external reference inputs (false)


class AssemblyState(NamedTuple):
    """The controller between samples and what its last sample produced."""

    u: F3                   #: servo torques held (N m)
    tau: F3                 #: wrist torques held (N m)
    u_law: Optional[F3]     #: the motion part of the law's servo torques of the last sample, before the lead
    tau_law: Optional[F3]   #: the motion part of the law's wrist torques of the last sample
    x_next: Optional[F6]    #: Newton's warm start for the next sample
    xd: Optional[F6]        #: the delta's unmeasured rates of the last sample
    status: int             #: status bits of the last sample
    warned: int             #: WARNING_BITS warned so far
    new_warnings: int       #: the WARNING_BITS the last sample raised first
    tip: F3                 #: tool tip estimate (m, world)
    error: F3               #: tip error, nominal hole frame (m)
    rotation_error: F3      #: orientation error, nominal hole frame (rad)
    sigma_min: float        #: wrist distance from gimbal lock
    phase: int              #: the program's phase (0: external reference)
    depth_ref: float        #: the program's reference depth below the nominal hole top (m)
    r: F3                   #: the tip reference of the last sample (m, world)
    start: Optional[F3]     #: the tip at the first sample: the program's start (m, world)
    start_rotation: Optional[F9]  #: the tool rotation at the first sample


def initial_state(tip: F3) -> AssemblyState:
    """No sample taken: no torque, no warm start, nothing warned; ``tip`` the start tip (the
    program's push bound reads the previous sample's tip)."""
    zero = (0.0, 0.0, 0.0)
    return AssemblyState(zero, zero, None, None, None, None, 0, 0, 0, tip, zero, zero, 1.0, 0, 0.0, tip, None, None)


def sample(law: AssemblyLaw, w: WristConstants, settings: AssemblySettings, program: InsertionProgram,
           state: AssemblyState, tau: float, y: F3, yd: F3, qw: F3, qwd: F3, ft: F6, r: F3, rd: F3, rdd: F3,
           phi: F3, phid: F3, phidd: F3) -> AssemblyState:
    """The state after one sample ``tau`` seconds after the start, with the measurements
    (servo and wrist angles and rates, F/T sensor) and the external reference (tip r, rd, rdd;
    tool orientation exp([phi]x) R_down with its rates; unused when the program runs)."""
    phase, depth = 0, 0.0
    rot, omega, alpha = orientation_reference(phi, phid, phidd, TOOL_DOWN)
    start, start_rotation, tip = state.start, state.start_rotation, state.tip
    if settings.use_program and (start is None or start_rotation is None):
        first = evaluate(law, w, y, yd, qw, qwd, ft, r, rd, rdd, rot, omega, alpha, state.x_next)
        if not first.status & STATUS_SINGULAR:  # else the next sample tries again
            start, start_rotation, tip = first.tip, first.rotation, first.tip
    if settings.use_program and start is not None and start_rotation is not None:
        r, rd, rdd, rot, omega, alpha, phase, depth = reference(program, tau, tip, start, start_rotation)
    out = evaluate(law, w, y, yd, qw, qwd, ft, r, rd, rdd, rot, omega, alpha, state.x_next)
    status = out.status
    raised = status & WARNING_BITS
    new = raised - (raised & state.warned)
    if status & STATUS_SINGULAR:
        return AssemblyState(state.u, state.tau, None, None, None, None, status, state.warned | new, new, state.tip,
                             state.error, state.rotation_error, state.sigma_min, phase, depth, r, start, start_rotation)
    u_motion, tau_motion = out.u, out.tau
    if settings.zoh_lead:
        free = evaluate(law, w, y, yd, qw, qwd, _NO_WRENCH, r, rd, rdd, rot, omega, alpha, out.x)
        if not free.status & STATUS_SINGULAR:
            u_motion, tau_motion = free.u, free.tau
    u, clipped = _held(u_motion, state.u_law if settings.zoh_lead else None, out.u, law.delta.torque_limit)
    tw, clipped_w = _held(tau_motion, state.tau_law if settings.zoh_lead else None, out.tau,
                          law.wrist_torque_limit)
    if clipped:
        status = status | STATUS_TORQUE_SATURATED
    if clipped_w:
        status = status | STATUS_WRIST_SATURATED
    x0, x1, x2, x3, x4, x5 = warm_start(out.x, out.xd, state.xd, settings.sample_period)
    return AssemblyState(u, tw, u_motion, tau_motion, (x0, x1, x2, x3, x4, x5), out.xd, status, state.warned | new,
                         new, out.tip, out.error, out.rotation_error, out.sigma_min, phase, depth, r, start,
                         start_rotation)


def _held(motion: F3, previous: Optional[F3], total: F3, limit: float) -> tuple[F3, bool]:
    """The torque to hold: ``total`` (the law's) plus the half-sample lead (motion - previous) / 2
    of its ``motion`` part (none without a ``previous`` one), clipped to +-limit; and whether it was."""
    u0, u1, u2 = total
    if previous is not None:
        u0 = u0 + 0.5 * (motion[0] - previous[0])
        u1 = u1 + 0.5 * (motion[1] - previous[1])
        u2 = u2 + 0.5 * (motion[2] - previous[2])
    if max(abs(u0), abs(u1), abs(u2)) <= limit:
        return (u0, u1, u2), False
    return (min(max(u0, -limit), limit), min(max(u1, -limit), limit), min(max(u2, -limit), limit)), True
