"""6-D impedance control of the delta robot with its spherical wrist (kernel float subset).

Choice: the delta's 3-D feedback linearisation plus an inner computed-torque loop on the wrist,
not a 6x6 task-space inversion. The wrist's three axes meet in O, so the tool's ORIENTATION is a
function of the wrist angles alone and O's POSITION of the delta's servo angles alone: the 6-D
task Jacobian is block triangular, [tip; omega]' = [[1, J_p], [0, J_w]] [zd; qwd], and its
inverse needs only J_w^-1 (3x3, closed form, damped near gimbal lock) and a cross product. Each
robot keeps its own exact inverse dynamics (the delta's from
:mod:`deltafmi.physics.delta.control_law`, the wrist's joint-space M qdd + h + g on the moving
plate in :mod:`.wrist_model`) and the coupling is exact: the wrist's force on the plate,
computed for the commanded motion, is fed forward to the delta, and the plate's acceleration
enters the wrist's as a change of gravity. Nothing is approximated, nothing is iterated, and
the gimbal singularity stays a 3x3 matter of the wrist.

Per sample, from the servo angles y, rates yd, wrist angles qw, rates qwd and the tool-frame
force/torque sensor ft = (F_tool, M_tool) (the contact wrench on the peg: force, and moment about
the tip):

1. delta forward kinematics (warm-started Newton) -> plate z, zd; O = z + mount; tool rotation R,
   tip p = O + R (0, 0, tip), tip velocity pd = zd + omega x (p - O), omega = J_w qwd;
2. translational impedance in the nominal HOLE frame R_h (axes x, y lateral, z along the hole):
   e = R_h^T (p - r), a_h = M_d^-1 (F_h - D_d e' - K_d e) per axis, F_h = R_h^T R F_tool;
   desired tip acceleration a_tip = rdd + R_h a_h;
3. rotational impedance about the tip, in the hole frame: e_R = log(R R_ref^T) (rotation vector,
   world), alpha_h = I_d^-1 (M_h - D_r (omega - omega_ref)_h - K_r e_R,h), alpha = alpha_ref + R_h alpha_h;
4. wrist: qwdd = J_w^-1 (alpha - Jd_w qwd) (damped least squares near gimbal lock, below);
5. O's acceleration: a_O = a_tip - alpha' x (p - O) - omega x (omega x (p - O)) with alpha' the
   angular acceleration that qwdd really gives;
6. wrist torques by inverse dynamics with the base accelerating by a_O, cancelling the measured
   contact wrench (moment about O: (p - O) x F + M); the wrist's force on the plate F_plate;
7. delta torques u = ID_delta(a_O) - Jc^T F_plate (the delta law's impedance mode with zero
   stiffness and damping: exact inverse dynamics of the plate plus the load carried).

Closed loop. With an exact model and sensor the tip and tool obey, per hole-frame axis k,

    M_d,k e_k'' + D_d,k e_k' + K_d,k e_k = F_k,        I_d,k eR_k'' + D_r,k eR_k' + K_r,k eR_k = M_k

exactly for the translation, and for the rotation exactly while e_R keeps a fixed axis (then
e_R' = omega - omega_ref); for a general e_R to second order in |e_R|. In free space (F = M = 0)
the errors decay with the chosen second-order dynamics (the talk's h'' + h' + h = 0 scaled:
D = 2 zeta sqrt(K M)); in contact the tip is the chosen impedance; no mode switches. The
compliance centre is the tool tip: a lateral force at the tip moves it without turning the peg
and a moment turns the peg about the tip (Whitney's remote-centre compliance, which is what
lets a chamfer centre a peg and a two-point contact align it).

Sampling. The law runs at the sample instants and its torques are held (the delta controller's
half-sample lead on their motion part only: :mod:`.sampling`). The measured-wrench cancellation is
a sampled force feedback: along a direction n the closed loop feels the contact force scaled by
mu = (n^T M_d^-1 n) / (n^T Lambda^-1 n) (Lambda the robot's natural inertia at the tip), the part
mu - 1 of it a sample late. A contact that blocks the tip within one sample takes what the
actuators push, so the force then follows F_k+1 = (1 - mu) F_k: stable for 0 < mu < 2, an
apparent mass above half the natural one along every direction a contact can block
(docs/assembly.md, section 5, where the shipped impedances sit).

Gimbal lock (|q2| -> pi/2, :mod:`deltafmi.physics.wrist.singularity`): below sigma_min = sqrt(1
- |sin q2|) < sigma0 the wrist's joint accelerations are the damped least-squares solution
qwdd = J_w^T (J_w J_w^T + lambda^2 1)^-1 b, lambda^2 = sigma0^2 - sigma_min^2 (Nakamura & Hanafusa
1986): bounded (|qwdd| <= |b| / sigma0), exact again above sigma0; step 5 uses the angular
acceleration actually produced, so the tip's translation stays exact even there. Status bit
STATUS_GIMBAL_DAMPED says it was active.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Optional, Sequence

from ..delta.control_law import (STATUS_SINGULAR, ControlLaw, _inv3, evaluate as
                                 delta_evaluate, make_law)
from ..wrist.kernels import WristConstants, wrist_constants
from .rotation import F3, F9, apply, apply_t, cross, matmul, rotation_vector, transpose
from .wrist_model import WristState, inverse_dynamics, wrist_state

__all__ = ["ImpedanceGains", "AssemblyLaw", "AssemblyOutput", "make_assembly_law", "evaluate", "gains",
           "STATUS_GIMBAL_DAMPED", "STATUS_WRIST_SATURATED", "F6"]

F6 = tuple[float, float, float, float, float, float]

STATUS_GIMBAL_DAMPED = 16     #: the wrist's damped least-squares inverse was active (near gimbal lock)
STATUS_WRIST_SATURATED = 32   #: some wrist torque clipped to +-wrist_torque_limit

_ZERO: F3 = (0.0, 0.0, 0.0)


class ImpedanceGains(NamedTuple):
    """The chosen impedance per hole-frame axis (x, y lateral, z along the hole)."""

    mass: F3            #: M_d (kg)
    stiffness: F3       #: K_d (N/m)
    damping: F3         #: D_d (N s/m)
    inertia: F3         #: I_d about the tip (kg m^2)
    rot_stiffness: F3   #: K_r (N m/rad)
    rot_damping: F3     #: D_r (N m s/rad)


def gains(mass: Sequence[float], stiffness: Sequence[float], inertia: Sequence[float],
          rot_stiffness: Sequence[float], zeta: float = 1.0) -> ImpedanceGains:
    """Gains for the damping ratio ``zeta`` on every axis: D = 2 zeta sqrt(K M), likewise in rotation."""
    if not (zeta >= 0.0 and math.isfinite(zeta)):
        raise ValueError(f"zeta must be a finite number >= 0, got {zeta}")

    def f3(v: Sequence[float], name: str) -> F3:
        a, b, c = (float(t) for t in v)
        if min(a, b, c) < 0.0 or not all(math.isfinite(t) for t in (a, b, c)):
            raise ValueError(f"{name} must be three finite numbers >= 0, got {tuple(v)}")
        return a, b, c
    m, k = f3(mass, "mass"), f3(stiffness, "stiffness")
    i, kr = f3(inertia, "inertia"), f3(rot_stiffness, "rot_stiffness")
    if min(m) <= 0.0 or min(i) <= 0.0:
        raise ValueError(f"mass {m} and inertia {i} must be > 0")
    d = tuple(2.0 * zeta * math.sqrt(k[j] * m[j]) for j in range(3))
    dr = tuple(2.0 * zeta * math.sqrt(kr[j] * i[j]) for j in range(3))
    return ImpedanceGains(m, k, (d[0], d[1], d[2]), i, kr, (dr[0], dr[1], dr[2]))


class AssemblyLaw(NamedTuple):
    """Everything :func:`evaluate` needs but the wrist's model (a :class:`WristConstants`, passed
    beside it: the kernels' structs hold no dataclass); build both with :func:`make_assembly_law`."""

    delta: ControlLaw       #: the delta's law in impedance mode with zero gains: inverse dynamics + load
    mount: F3               #: wrist centre O relative to the plate centre z (m)
    hole: F9                #: nominal hole frame, world <- hole
    gains: ImpedanceGains
    sigma0: float           #: gimbal damping threshold on sigma_min(J_w)
    wrist_torque_limit: float   #: N m


class AssemblyOutput(NamedTuple):
    """One evaluation's torques and what it estimated (all floats)."""

    u: F3               #: servo torques (N m), saturated
    tau: F3             #: wrist torques (N m), saturated
    tip: F3             #: tool tip, world (m)
    tip_velocity: F3    #: m/s
    rotation: F9        #: tool rotation, world <- tool
    error: F3           #: tip error R_h^T (p - r), hole frame (m)
    rotation_error: F3  #: R_h^T log(R R_ref^T), hole frame (rad)
    x: F6               #: the delta's unmeasured angles (warm start)
    xd: F6              #: their rates
    status: int         #: delta STATUS_* bits | STATUS_GIMBAL_DAMPED | STATUS_WRIST_SATURATED
    sigma_min: float    #: sqrt(1 - |sin q2|), the wrist's distance from gimbal lock


def make_assembly_law(delta_params: object, wrist_params: object, mount: Sequence[float], hole: F9,
                      impedance: ImpedanceGains, sigma0: float = 0.2, torque_limit: float = 300.0,
                      wrist_torque_limit: float = 20.0,
                      cond_limit: float = 100.0) -> tuple[AssemblyLaw, WristConstants]:
    """The law and the wrist model for the delta ``delta_params`` (DeltaParams-like, its payload
    WITHOUT the wrist) and the wrist ``wrist_params`` (WristParams) mounted at ``mount`` (m) from
    the plate centre, the nominal hole frame ``hole`` and the chosen ``impedance``."""
    if not 0.0 < sigma0 < 1.0:
        raise ValueError(f"sigma0 must be in (0, 1), got {sigma0}")
    if not (torque_limit > 0.0 and wrist_torque_limit > 0.0):
        raise ValueError(f"torque limits must be > 0, got {torque_limit} and {wrist_torque_limit}")
    delta = make_law(delta_params, impedance=True, torque_limit=torque_limit, cond_limit=cond_limit)
    mx, my, mz = (float(t) for t in mount)
    law = AssemblyLaw(delta, (mx, my, mz), hole, impedance, float(sigma0), float(wrist_torque_limit))
    return law, wrist_constants(wrist_params)


def _singular(x: Sequence[float], status: int) -> AssemblyOutput:
    nan = math.nan
    return AssemblyOutput(_ZERO, _ZERO, (nan, nan, nan), _ZERO, (nan,) * 9, (nan, nan, nan), (nan, nan, nan),
                          (x[0], x[1], x[2], x[3], x[4], x[5]), (0.0,) * 6, status | STATUS_SINGULAR, nan)


def _wrist_accelerations(s: WristState, b: F3, sigma_min: float, sigma0: float) -> tuple[F3, bool]:
    """qdd with J_w qdd = b: exact above sigma0, damped least squares below (module docstring)."""
    fr = s.terms.frame
    a1, a2, a3 = fr.a1, fr.a2, fr.a3
    if sigma_min >= sigma0:
        inv = _inv3((a1[0], a2[0], a3[0], a1[1], a2[1], a3[1], a1[2], a2[2], a3[2]))
        if inv is not None:
            return apply(inv, b), False
    lam2 = sigma0 * sigma0 - sigma_min * sigma_min
    jjt = (a1[0] * a1[0] + a2[0] * a2[0] + a3[0] * a3[0] + lam2, a1[0] * a1[1] + a2[0] * a2[1] + a3[0] * a3[1],
           a1[0] * a1[2] + a2[0] * a2[2] + a3[0] * a3[2], a1[1] * a1[0] + a2[1] * a2[0] + a3[1] * a3[0],
           a1[1] * a1[1] + a2[1] * a2[1] + a3[1] * a3[1] + lam2, a1[1] * a1[2] + a2[1] * a2[2] + a3[1] * a3[2],
           a1[2] * a1[0] + a2[2] * a2[0] + a3[2] * a3[0], a1[2] * a1[1] + a2[2] * a2[1] + a3[2] * a3[1],
           a1[2] * a1[2] + a2[2] * a2[2] + a3[2] * a3[2] + lam2)
    inv = _inv3(jjt)
    if inv is None:
        return _ZERO, True
    yv = apply(inv, b)
    return (a1[0] * yv[0] + a1[1] * yv[1] + a1[2] * yv[2], a2[0] * yv[0] + a2[1] * yv[1] + a2[2] * yv[2],
            a3[0] * yv[0] + a3[1] * yv[1] + a3[2] * yv[2]), True


def _axis_law(m: F3, k: F3, d: F3, force: F3, e: F3, ed: F3) -> F3:
    """Per axis (force - d e' - k e) / m: the impedance's acceleration."""
    return ((force[0] - d[0] * ed[0] - k[0] * e[0]) / m[0], (force[1] - d[1] * ed[1] - k[1] * e[1]) / m[1],
            (force[2] - d[2] * ed[2] - k[2] * e[2]) / m[2])


def _clip(v: F3, lim: float) -> tuple[F3, bool]:
    if max(abs(v[0]), abs(v[1]), abs(v[2])) <= lim:
        return v, False
    return (min(max(v[0], -lim), lim), min(max(v[1], -lim), lim), min(max(v[2], -lim), lim)), True


def evaluate(law: AssemblyLaw, w: WristConstants, y: F3, yd: F3, qw: F3, qwd: F3, ft: F6, r: F3, rd: F3, rdd: F3,
             rot_ref: F9, omega_ref: F3, alpha_ref: F3, x_guess: Optional[F6]) -> AssemblyOutput:
    """One evaluation of the 6-D impedance law (module docstring); pure, no state kept.

    ``w``: the wrist's model; ``ft``: the F/T sensor (tool frame: force on the peg, moment about
    the tip); ``r``, ``rd``, ``rdd``: tip reference (world); ``rot_ref``, ``omega_ref``,
    ``alpha_ref``: tool reference rotation (world <- tool) and its angular velocity and
    acceleration (world); ``x_guess``: the delta forward kinematics' warm start (None: closed form)."""
    fk = delta_evaluate(law.delta, y, yd, _ZERO, _ZERO, _ZERO, _ZERO, 0.0, x_guess, _ZERO)
    if fk.status & STATUS_SINGULAR:
        return _singular(x_guess if x_guess is not None else (math.nan,) * 6, fk.status)
    x6 = (fk.x[0], fk.x[1], fk.x[2], fk.x[3], fk.x[4], fk.x[5])
    ws = wrist_state(w, qw, qwd)
    omega, rel = ws.omega, ws.tip
    z, zd, mount = fk.z, fk.zd, law.mount
    tip = (z[0] + mount[0] + rel[0], z[1] + mount[1] + rel[1], z[2] + mount[2] + rel[2])
    spin = cross(omega, rel)
    tipd = (zd[0] + spin[0], zd[1] + spin[1], zd[2] + spin[2])
    force = apply(ws.tool, (ft[0], ft[1], ft[2]))
    moment = apply(ws.tool, (ft[3], ft[4], ft[5]))
    g, hole = law.gains, law.hole
    # translational impedance in the hole frame
    e = apply_t(hole, (tip[0] - r[0], tip[1] - r[1], tip[2] - r[2]))
    ed = apply_t(hole, (tipd[0] - rd[0], tipd[1] - rd[1], tipd[2] - rd[2]))
    ah = apply(hole, _axis_law(g.mass, g.stiffness, g.damping, apply_t(hole, force), e, ed))
    a_tip = (rdd[0] + ah[0], rdd[1] + ah[1], rdd[2] + ah[2])
    # rotational impedance about the tip
    e_rot = apply_t(hole, rotation_vector(matmul(ws.tool, transpose(rot_ref))))
    w_err = apply_t(hole, (omega[0] - omega_ref[0], omega[1] - omega_ref[1], omega[2] - omega_ref[2]))
    al = apply(hole, _axis_law(g.inertia, g.rot_stiffness, g.rot_damping, apply_t(hole, moment), e_rot, w_err))
    vp = ws.velocity_product
    b = (alpha_ref[0] + al[0] - vp[0], alpha_ref[1] + al[1] - vp[1], alpha_ref[2] + al[2] - vp[2])
    sigma_min = math.sqrt(max(0.0, 1.0 - abs(math.sin(qw[1]))))
    qwdd, damped = _wrist_accelerations(ws, b, sigma_min, law.sigma0)
    # the angular acceleration qwdd gives, and O's acceleration that puts the tip at a_tip
    fr = ws.terms.frame
    a1, a2, a3 = fr.a1, fr.a2, fr.a3
    alpha = (a1[0] * qwdd[0] + a2[0] * qwdd[1] + a3[0] * qwdd[2] + vp[0],
             a1[1] * qwdd[0] + a2[1] * qwdd[1] + a3[1] * qwdd[2] + vp[1],
             a1[2] * qwdd[0] + a2[2] * qwdd[1] + a3[2] * qwdd[2] + vp[2])
    t1 = cross(alpha, rel)
    t2 = cross(omega, spin)
    a_o = (a_tip[0] - t1[0] - t2[0], a_tip[1] - t1[1] - t2[1], a_tip[2] - t1[2] - t2[2])
    m_o = cross(rel, force)
    tau, f_plate = inverse_dynamics(w, ws, qwd, qwdd, a_o,
                                    (m_o[0] + moment[0], m_o[1] + moment[1], m_o[2] + moment[2]), force)
    out = delta_evaluate(law.delta, y, yd, _ZERO, _ZERO, a_o, _ZERO, 0.0, x6, (-f_plate[0], -f_plate[1], -f_plate[2]))
    if out.status & STATUS_SINGULAR:
        return _singular(x6, out.status)
    status = out.status | (STATUS_GIMBAL_DAMPED if damped else 0)
    tau, clipped = _clip(tau, law.wrist_torque_limit)
    if clipped:
        status = status | STATUS_WRIST_SATURATED
    return AssemblyOutput(out.u, tau, tip, tipd, ws.tool, e, e_rot, x6,
                          (fk.xd[0], fk.xd[1], fk.xd[2], fk.xd[3], fk.xd[4], fk.xd[5]), status, sigma_min)
