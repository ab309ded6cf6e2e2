"""The insertion program: the tool's reference pose for a peg-in-hole insertion (kernel subset).

Three stretches of one time-driven reference; the control law never changes (no mode switch):

1. approach (0 <= tau < approach_time): from the start pose (p0, R0) (the measured pose at the
   first sample) to the pose above the NOMINAL hole (tip on the nominal hole axis,
   approach_height above its top, peg axis along the nominal hole axis) by the quintic
   s(x) = 10 x^3 - 15 x^4 + 6 x^5 (zero speed and acceleration at both ends). Orientation:
   R_ref = exp(s phi0) R0 with phi0 = log(R_goal R0^T), a rotation about the fixed axis phi0, so
   omega_ref = s' phi0 and alpha_ref = s'' phi0 exactly.
2. descent: the tip reference moves down the nominal hole axis from -approach_height to
   final_depth (depth measured from the hole's top along -hole axis), at entry_speed until it
   reaches entry_depth (past the chamfer: the first contact happens at this speed), then at
   insertion_speed; each speed step, the first from 0, the impedance's damping smooths. The
   first contact's impact force grows with the speed at which the peg meets the chamfer (v
   sqrt(k m) for a contact stiffness k and the tool's effective mass m), so a real cell enters
   slowly and inserts fast; entry_speed = insertion_speed is one speed throughout.
3. hold: the reference stays at final_depth.

Bounded push. The axial reference never leads the measured tip by more than push_force / K_ax
(K_ax the axial impedance stiffness): depth_ref = min(depth_program, depth_tip + push_force /
K_ax). With the force-sensing impedance of :mod:`.law` the static axial force is K_ax e_ax, so
a blocked or wedged peg is pushed with at most push_force (plus the transient damping force);
while that bound is active the axial reference velocity is 0, so the damping acts on the tip's
own speed. Lateral and angular compliance come from the law's gains in the hole frame: the
chamfer's and the bore's contact forces centre and align the peg against the low lateral
stiffness and the low rotational stiffness about the tip.
"""

from __future__ import annotations

from typing import NamedTuple

from ..peg.contact import hole_rotation as _peg_hole_rotation
from ..peg.params import Hole
from .rotation import F3, F9, TOOL_DOWN, apply, matmul, rotation_from_vector, rotation_vector, transpose

__all__ = ["InsertionProgram", "ProgramReference", "make_program", "hole_frame", "reference", "PHASE_APPROACH",
           "PHASE_DESCENT", "PHASE_HOLD"]

PHASE_APPROACH = 1
PHASE_DESCENT = 2
PHASE_HOLD = 3


class InsertionProgram(NamedTuple):
    """The program's data (SI units); build it with :func:`make_program`."""

    hole_top: F3            #: nominal hole top centre, world (m)
    hole: F9                #: nominal hole frame, world <- hole (row-major); hole z out of the hole
    goal_rotation: F9       #: tool rotation aligned with the nominal hole (tool z = -hole z)
    approach_height: float  #: tip height above the hole top at the end of the approach (m)
    approach_time: float    #: duration of the approach (s), > 0
    insertion_speed: float  #: descent speed along the hole axis (m/s), > 0
    final_depth: float      #: depth where the reference stops (m), below the hole's top
    push_force: float       #: bound on the static axial push (N), > 0
    axial_stiffness: float  #: K_ax of the law (N/m), > 0
    entry_speed: float      #: descent speed until the reference reaches entry_depth (m/s), > 0
    entry_depth: float      #: depth where the descent speeds up to insertion_speed (m)


class ProgramReference(NamedTuple):
    """The reference at one instant: tip (world), tool rotation and rates, phase, depth."""

    r: F3
    rd: F3
    rdd: F3
    rotation: F9
    omega: F3
    alpha: F3
    phase: int
    depth: float   #: the reference's depth below the nominal hole top (m; negative above it)


def _quintic(x: float) -> F3:
    """s, ds/dx, d2s/dx2 of 10 x^3 - 15 x^4 + 6 x^5."""
    x2 = x * x
    return (x2 * x * (10.0 - 15.0 * x + 6.0 * x2), 30.0 * x2 * (1.0 - 2.0 * x + x2),
            60.0 * x * (1.0 - 3.0 * x + 2.0 * x2))


def reference(prog: InsertionProgram, tau: float, tip: F3, start: F3, start_rotation: F9) -> ProgramReference:
    """The reference ``tau`` seconds after the start, from the start tip ``start`` (world, m) and
    tool rotation ``start_rotation``, with the measured tip ``tip`` (world, m) for the push bound."""
    hx, hy, hz = prog.hole_top
    ax, ay, az = apply(prog.hole, (0.0, 0.0, 1.0))       # hole axis, out of the hole
    h = prog.approach_height
    if tau < prog.approach_time:
        s, ds, dds = _quintic(tau / prog.approach_time)
        ds, dds = ds / prog.approach_time, dds / (prog.approach_time * prog.approach_time)
        p0x, p0y, p0z = start
        gx, gy, gz = hx + h * ax - p0x, hy + h * ay - p0y, hz + h * az - p0z
        phi0 = rotation_vector(matmul(prog.goal_rotation, transpose(start_rotation)))
        rot = matmul(rotation_from_vector((s * phi0[0], s * phi0[1], s * phi0[2])), start_rotation)
        rx, ry, rz = p0x + s * gx, p0y + s * gy, p0z + s * gz
        depth = -((rx - hx) * ax + (ry - hy) * ay + (rz - hz) * az)
        return ProgramReference((rx, ry, rz), (ds * gx, ds * gy, ds * gz),
                                (dds * gx, dds * gy, dds * gz), rot, (ds * phi0[0], ds * phi0[1], ds * phi0[2]),
                                (dds * phi0[0], dds * phi0[1], dds * phi0[2]), PHASE_APPROACH, depth)
    descent = tau - prog.approach_time
    entry_time = 0.0  # the descent's seconds at entry_speed
    if prog.entry_depth > -h:
        entry_time = (prog.entry_depth + h) / prog.entry_speed
    if descent < entry_time:
        depth, speed = -h + prog.entry_speed * descent, prog.entry_speed
    else:
        depth = -h + prog.entry_speed * entry_time + prog.insertion_speed * (descent - entry_time)
        speed = prog.insertion_speed
    phase = PHASE_DESCENT
    if depth >= prog.final_depth:
        depth, speed, phase = prog.final_depth, 0.0, PHASE_HOLD
    # the measured tip's depth along the nominal axis; the reference leads it by <= push / K
    tip_depth = -((tip[0] - hx) * ax + (tip[1] - hy) * ay + (tip[2] - hz) * az)
    lead = prog.push_force / prog.axial_stiffness
    if depth > tip_depth + lead:
        depth, speed = tip_depth + lead, 0.0
    zero = (0.0, 0.0, 0.0)
    return ProgramReference((hx - depth * ax, hy - depth * ay, hz - depth * az),
                            (-speed * ax, -speed * ay, -speed * az), zero, prog.goal_rotation, zero, zero, phase, depth)


def make_program(hole_top: F3, hole_tilt: tuple[float, float], approach_height: float = 0.02,
                 approach_time: float = 0.5, insertion_speed: float = 0.01, final_depth: float = 0.03,
                 push_force: float = 20.0, axial_stiffness: float = 1000.0, entry_speed: float | None = None,
                 entry_depth: float = 0.0) -> InsertionProgram:
    """The program for the nominal hole at ``hole_top`` (m, world) tilted by ``hole_tilt`` =
    (tilt_x, tilt_y) (rad, R_h = Ry Rx); ``entry_speed`` (default: insertion_speed) is the
    descent's speed down to ``entry_depth``. Raises ValueError naming a parameter out of range."""
    entry_speed = insertion_speed if entry_speed is None else entry_speed
    for name, value in (("approach_time", approach_time), ("insertion_speed", insertion_speed),
                        ("push_force", push_force), ("axial_stiffness", axial_stiffness),
                        ("entry_speed", entry_speed)):
        if not value > 0.0:
            raise ValueError(f"{name} must be > 0, got {value}")
    if not approach_height >= 0.0:
        raise ValueError(f"approach_height must be >= 0 m, got {approach_height}")
    hole = hole_frame(hole_tilt)
    hx, hy, hz = (float(t) for t in hole_top)
    return InsertionProgram((hx, hy, hz), hole, matmul(hole, TOOL_DOWN),
                            float(approach_height), float(approach_time), float(insertion_speed), float(final_depth),
                            float(push_force), float(axial_stiffness), float(entry_speed), float(entry_depth))


def hole_frame(tilt: tuple[float, float]) -> F9:
    """World <- hole frame for the tilts (tilt_x, tilt_y) (rad), R_h = Ry(tilt_y) Rx(tilt_x): the
    peg plant's convention (:class:`deltafmi.physics.peg.params.Hole`); hole z points out of the hole."""
    return _peg_hole_rotation(Hole(tilt_x=float(tilt[0]), tilt_y=float(tilt[1])))
