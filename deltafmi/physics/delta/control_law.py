"""Feedback-linearising wrist-position controller of the delta robot (seed talk, "Inner Loop
Feedback Linearization"), written for speed in plain float arithmetic.

Per sample, from the measured servo angles y and rates yd:

1. forward kinematics: Newton iteration on h(x, y) = 0 (6-D) warm-started from the previous
   sample (its x extrapolated one sample ahead, so one iteration usually reaches 1e-12 m), or
   the closed-form three-sphere solution (cold start, fallback, or on request);
2. velocities: zd = Jc yd with the control Jacobian Jc = dPsi/dx dg/dy + dPsi/dy, and xd;
3. outer loop in wrist coordinates:
   a = kI int(r - z) + kP (r - z) + kD (rd - zd) + rdd   (integral clamped, conditional);
4. inner loop: u = My Jc^-1 (a - Jc' yd) + c_y(q, v) + D v + tau_g, the exact inverse dynamics
   of the constrained robot in servo coordinates. ``coriolis=False`` drops every velocity term
   and leaves the seed's law u = My Jc^-1 a + tau_g.

Impedance (soft-contact) mode, ``impedance=True``: the PID of step 3 is off; the outer loop is a
wrist force F = K (r - z) + D (rd - zd) + f_cmd (stiffness K and damping D per world axis, in
N/m and N s/m, plus a commanded force f_cmd, the force the tool is to exert on the world) with
a = rdd fed forward, and u = My Jc^-1 (a - Jc' yd) + ... + Jc^T F. Since My Jc^-1 = Jc^T Lambda
(Lambda the wrist inertia), the robot then obeys Lambda (zdd - rdd) = F + f_ext: a mass-spring-
damper about the reference with the robot's own inertia (Hogan's impedance control without a
force sensor). The same law holds in free space, at the impact and while pressing: nothing
switches. At rest in contact the force on the world is K (r - z) + f_cmd along the normal plus
whatever gravity the controller's model does not cancel.

Why it is cheap. The 6x6 dh/dx = [[A1, -A2, 0], [A1, 0, -A3]] (A_i = R_i dpsi/dx_i, 3x2) is
never formed: the columns of A_i are orthogonal to the forearm direction n_i, so a solve with
it splits into one 3x3 solve with N = [n_1 n_2 n_3]^T (the classic delta Jacobian) plus two dot
products per arm. The seed's 9x9 system [B H^T][tau; lambda] = G splits the same way: with the
constraint force F_i on arm i (sum F_i = 0, which is what H^T lambda means), rows 2-3 of each
arm fix F_i up to a multiple of n_i, and N^T fixes the multiples. So Jc = N^-1 diag(n_i . b_i)
(b_i = dpsi/dq_i1 in the world). Inverse dynamics runs arm by arm on the point-mass form of the
forearm (a thin rod is three point masses m2/6, 2 m2/3, m2/6 at elbow, middle and wrist).

Reduced inertia. The seed's My = M11 - M12 (dh/dx)^-1 dh/dy keeps the servo rows of the
reordered M but drops the constraint force those rows carry (dh/dy != 0). The exact value,
used here (implicitly) and returned by :func:`reduced_inertia`, is the projection
My = T^T M T, q' = T y', T = [I; dg/dy] in (y, x) order: symmetric positive definite.

Frame and parameters as in ``deltafmi.physics.delta.params`` (DESIGN.md); any object with the
``DeltaParams`` attributes works, so the controller's model may differ from the plant's.

The stateful sampled controller and numpy analysis helpers are in :mod:`.control`; this
module is the pure law (translated to C for the FMUs, deltafmi/builder/codegen: hence the
fixed-length float tuples).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, Optional, Sequence

import numpy as np

__all__ = [
    "ControlLaw", "ControlOutput", "evaluate", "make_law", "describe_status", "hold", "warm_start",
    "STATUS_OK", "STATUS_TORQUE_SATURATED", "STATUS_INTEGRAL_CLAMPED", "STATUS_ILL_CONDITIONED",
    "STATUS_SINGULAR",
]

F3 = tuple[float, float, float]
F4 = tuple[float, float, float, float]
F6 = tuple[float, float, float, float, float, float]
F9 = tuple[float, float, float, float, float, float, float, float, float]
#: per arm: (cos, sin) of its rotation, (cos, sin) of the servo angle, wrist-sphere centre
Elbow = tuple[float, float, float, float, float, float, float]

STATUS_OK = 0
STATUS_TORQUE_SATURATED = 1   #: some servo torque clipped to +-torque_limit
STATUS_INTEGRAL_CLAMPED = 2   #: the integral term is at +-integral_limit on some axis
STATUS_ILL_CONDITIONED = 4    #: near a singularity: cond(Jc) or 1/min_i|cos(forearm, elbow
                              #: velocity)| above cond_limit
STATUS_SINGULAR = 8           #: no forward kinematics or a singular solve: no torque computed

_STATUS_TEXT = ((1, "torque saturated"), (2, "integral clamped"), (4, "Jc ill-conditioned"),
                (8, "singular: no forward kinematics or singular Jacobian"))

_CR, _SR = math.cos(2.0 * math.pi / 3.0), math.sin(2.0 * math.pi / 3.0)
#: (cos, sin) of the arm rotations R1 = I, R2 = Rz(+2pi/3), R3 = Rz(-2pi/3)
_ROT = ((1.0, 0.0), (_CR, _SR), (_CR, -_SR))


def describe_status(status: int) -> str:
    """Human-readable text of a status bit set."""
    return "ok" if status == 0 else "; ".join(t for b, t in _STATUS_TEXT if status & b)


class _Model(NamedTuple):
    """Constants of the arm model, derived once from the parameters."""

    a: float        # l0 - l3: the wrist spheres are centred at the elbows shifted by -l3
    l1: float
    l2: float
    jrot: float     # J1 + Jm about the servo axis
    m1r1g: float    # m1 r1 g
    s0: float       # forearm + plate point masses: m2 + mp'  (mp' = (mp + payload) / 3)
    s1: float       # first moment along the forearm / l2:  m2/2 + mp'
    s2: float       # second moment / l2^2:  m2/3 + mp'
    g: float
    damping: float


def _model(params: Any) -> _Model:
    mpp = (params.mp + params.payload) / 3.0
    return _Model(params.l0 - params.l3, params.l1, params.l2, params.J1 + params.Jm,
                  params.m1 * params.r1 * params.g, params.m2 + mpp, params.m2 / 2.0 + mpp,
                  params.m2 / 3.0 + mpp, params.g, params.damping)


class ControlLaw(NamedTuple):
    """Everything :func:`evaluate` needs: model constants, gains, limits and options.

    Build it with :func:`make_law`. ``integral_max`` bounds the integral STATE per axis
    (m s) so that ``kI * integral`` stays within ``integral_limit`` (m/s^2).
    """

    model: _Model
    kI: float
    kP: float
    kD: float
    integral_max: float
    feedforward: bool
    coriolis: bool
    torque_limit: float
    cond_limit: float
    fk: str
    newton_tol: float
    newton_max_iter: int
    impedance: bool
    stiffness: F3
    task_damping: F3


def make_law(params: Any, pole: float = 7.0, kI: Optional[float] = None, kP: Optional[float] = None,
             kD: Optional[float] = None, integral_limit: float = 1.0, feedforward: bool = True,
             coriolis: bool = True, torque_limit: float = 300.0, cond_limit: float = 100.0,
             fk: str = "newton", newton_tol: float = 1e-12, newton_max_iter: int = 6,
             impedance: bool = False, stiffness: Sequence[float] = (0.0, 0.0, 0.0),
             task_damping: Sequence[float] = (0.0, 0.0, 0.0)) -> ControlLaw:
    """Control law from kinematic/inertial ``params`` and the outer-loop design.

    Gains default to a triple pole at ``-pole`` (rad/s): kI = p^3, kP = 3 p^2, kD = 3 p.
    ``integral_limit`` (m/s^2) bounds the integral action kI int(r - z) per axis; ``fk`` is
    ``"newton"`` (warm-started, the seed's method) or ``"closed"`` (three-sphere intersection).
    ``impedance`` selects the impedance mode (module docstring) with ``stiffness`` (N/m) and
    ``task_damping`` (N s/m) per world axis x, y, z; the PID gains are then unused.
    """
    p = float(pole)
    if not p > 0.0 and any(gain is None or gain < 0 for gain in (kI, kP, kD)):
        raise ValueError(f"pole must be > 0 to derive the gains from it, got {pole}")
    kI = p ** 3 if kI is None or kI < 0 else float(kI)
    kP = 3.0 * p * p if kP is None or kP < 0 else float(kP)
    kD = 3.0 * p if kD is None or kD < 0 else float(kD)
    if fk not in ("newton", "closed"):
        raise ValueError(f"fk must be 'newton' or 'closed', got {fk!r}")
    if not (torque_limit > 0 and integral_limit >= 0 and cond_limit > 1):
        raise ValueError("torque_limit must be > 0, integral_limit >= 0 and cond_limit > 1")
    stiffness3, damping3 = _f3(stiffness), _f3(task_damping)
    if min(stiffness3) < 0.0 or min(damping3) < 0.0:
        raise ValueError(f"impedance stiffness {stiffness3} and damping {damping3} must be >= 0")
    imax = integral_limit / kI if kI > 0.0 else 0.0
    return ControlLaw(_model(params), kI, kP, kD, imax, bool(feedforward), bool(coriolis),
                      float(torque_limit), float(cond_limit), fk, float(newton_tol),
                      int(newton_max_iter), bool(impedance), stiffness3, damping3)


class ControlOutput(NamedTuple):
    """Result of one controller evaluation (all plain floats / tuples)."""

    u: tuple            #: servo torques (N m), saturated; zeros when status has STATUS_SINGULAR
    integral: tuple     #: updated integral state int(r - z) dt (m s)
    z: tuple            #: estimated wrist position (m)
    zd: tuple           #: estimated wrist velocity (m/s)
    x: tuple            #: unmeasured angles (q12, q13, q22, q23, q32, q33) (rad)
    xd: tuple           #: their rates (rad/s)
    cond: float         #: Frobenius condition number of Jc (inf when singular)
    status: int         #: STATUS_* bits
    iterations: int     #: Newton iterations (-1: closed form used)


# --------------------------------------------------------------------------------------------
# kinematics kernels (floats in, floats out)
# --------------------------------------------------------------------------------------------
def _inv3(m: Sequence[float]) -> Optional[F9]:
    """Inverse of a 3x3 matrix given as 9 floats (row major), or None when singular."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    c00 = m11 * m22 - m12 * m21
    c01 = m12 * m20 - m10 * m22
    c02 = m10 * m21 - m11 * m20
    det = m00 * c00 + m01 * c01 + m02 * c02
    if not abs(det) > 1e-12:
        return None
    k = 1.0 / det
    return (c00 * k, (m02 * m21 - m01 * m22) * k, (m01 * m12 - m02 * m11) * k,
            c01 * k, (m00 * m22 - m02 * m20) * k, (m02 * m10 - m00 * m12) * k,
            c02 * k, (m01 * m20 - m00 * m21) * k, (m00 * m11 - m01 * m10) * k)


def _elbows(k: _Model, y: F3) -> list[Elbow]:
    """Per arm: (cos, sin) of its rotation, (cos, sin) of its servo angle and the wrist-sphere
    centre E_i in the world (the elbow shifted by -l3 towards the axis)."""
    a, l1 = k.a, k.l1
    out: list[Elbow] = []
    for (cr, sr), yi in zip(_ROT, y):
        c1, s1 = math.cos(yi), math.sin(yi)
        rho = a + l1 * c1
        out.append((cr, sr, c1, s1, -sr * rho, cr * rho, l1 * s1))
    return out


def _closed_fk(l2: float, elb: list[Elbow]) -> Optional[F3]:
    """Lower intersection point of the three spheres |z - E_i| = l2, or None if they miss."""
    (_, _, _, _, e1x, e1y, e1z), (_, _, _, _, e2x, e2y, e2z), (_, _, _, _, e3x, e3y, e3z) = elb
    ux, uy, uz = e2x - e1x, e2y - e1y, e2z - e1z
    vx, vy, vz = e3x - e1x, e3y - e1y, e3z - e1z
    d = math.sqrt(ux * ux + uy * uy + uz * uz)
    if d < 1e-12:
        return None
    ux, uy, uz = ux / d, uy / d, uz / d
    i = ux * vx + uy * vy + uz * vz
    wx, wy, wz = vx - i * ux, vy - i * uy, vz - i * uz
    j = math.sqrt(wx * wx + wy * wy + wz * wz)
    if j < 1e-12:
        return None
    wx, wy, wz = wx / j, wy / j, wz / j
    px = 0.5 * d                               # equal radii
    py = (i * i + j * j - 2.0 * i * px) / (2.0 * j)
    h2 = l2 * l2 - px * px - py * py
    if h2 < 0.0:
        return None
    nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    pz = -math.sqrt(h2) if nz > 0.0 else math.sqrt(h2)   # the solution below the base
    return (e1x + px * ux + py * wx + pz * nx, e1y + px * uy + py * wy + pz * ny,
            e1z + px * uz + py * wz + pz * nz)


def _forearms_from_z(l2: float, elb: list[Elbow], z: F3) -> Optional[list[F4]]:
    """Per-arm (s2, c2, s3, c3) of the forearm direction reaching wrist z, or None."""
    zx, zy, zz = z
    out: list[F4] = []
    for cr, sr, _, _, ex, ey, ez in elb:
        wx, wy, dz = (zx - ex) / l2, (zy - ey) / l2, (zz - ez) / l2
        dx, dy = cr * wx + sr * wy, cr * wy - sr * wx
        s2 = -math.sqrt(dx * dx + dz * dz)      # branch q2 in (-pi, 0)
        if s2 > -1e-9:
            return None
        out.append((s2, dy, dx / s2, dz / s2))
    return out


def _directions(elb: list[Elbow], fa: list[F4]) -> tuple[list[float], list[float]]:
    """Rows of N (world forearm directions n_i, 9 floats) and D_i = t1 . d per arm, the cosine
    between forearm and elbow velocity (so n_i . b_i = l1 D_i)."""
    n: list[float] = []
    dd: list[float] = []
    for (cr, sr, c1, s1, _, _, _), (s2, c2, s3, c3) in zip(elb, fa):
        dx = s2 * s3
        n += (cr * dx - sr * c2, sr * dx + cr * c2, s2 * c3)
        dd.append(c1 * s2 * c3 - s1 * c2)
    return n, dd


def _newton_fk(l2: float, elb: list[Elbow], x: Sequence[float], tol: float,
               max_iter: int) -> Optional[tuple[F3, list[F4], F6, int]]:
    """Newton on h(x, y) = 0 from the angles x (6 floats).

    Returns (z, forearms, x, iterations), or None when it does not converge. The 6-D step
    dh/dx dx = -h is solved through its structure: the linearised equations are
    w_i + A_i dx_i = zbar (i = 1..3) for a common point zbar; dotting with n_i (orthogonal to
    A_i's columns) gives N zbar = (n_i . w_i), then dx_i = A_i^+ (zbar - w_i), A_i's two
    columns being orthogonal (lengths l2 and l2 |sin q2|).
    """
    sin, cos = math.sin, math.cos
    x0, x1, x2, x3, x4, x5 = x
    for it in range(max_iter + 1):
        fa = [(sin(x0), cos(x0), sin(x1), cos(x1)), (sin(x2), cos(x2), sin(x3), cos(x3)),
              (sin(x4), cos(x4), sin(x5), cos(x5))]
        n: list[float] = []
        w: list[F3] = []
        for (cr, sr, _, _, ex, ey, ez), (s2, c2, s3, c3) in zip(elb, fa):
            dx = s2 * s3
            nx, ny, nz = cr * dx - sr * c2, sr * dx + cr * c2, s2 * c3
            n += (nx, ny, nz)
            w.append((ex + l2 * nx, ey + l2 * ny, ez + l2 * nz))
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = w
        res = max(abs(ax - bx), abs(ay - by), abs(az - bz), abs(ax - cx), abs(ay - cy),
                  abs(az - cz))
        if res <= tol:
            # a far-off guess can converge onto another assembly: keep only the design branch
            # q_i2 in (-pi, 0), q_i3 in (-pi/2, pi/2)
            if any(s2 >= 0.0 or c3 <= 0.0 for s2, _, _, c3 in fa):
                return None
            return ((ax + bx + cx) / 3.0, (ay + by + cy) / 3.0, (az + bz + cz) / 3.0), fa, \
                (x0, x1, x2, x3, x4, x5), it
        ninv = _inv3(n)
        if it == max_iter or ninv is None or not res < 0.5:    # also catches NaN
            return None
        b0 = n[0] * ax + n[1] * ay + n[2] * az
        b1 = n[3] * bx + n[4] * by + n[5] * bz
        b2 = n[6] * cx + n[7] * cy + n[8] * cz
        zb = (ninv[0] * b0 + ninv[1] * b1 + ninv[2] * b2,
              ninv[3] * b0 + ninv[4] * b1 + ninv[5] * b2,
              ninv[6] * b0 + ninv[7] * b1 + ninv[8] * b2)
        dq: list[float] = []
        for (cr, sr, _, _, _, _, _), (s2, c2, s3, c3), (wx, wy, wz) in zip(elb, fa, w):
            gx, gy, gz = zb[0] - wx, zb[1] - wy, zb[2] - wz
            lx, ly = cr * gx + sr * gy, cr * gy - sr * gx
            dq += ((c2 * s3 * lx - s2 * ly + c2 * c3 * gz) / l2, (c3 * lx - s3 * gz) / (l2 * s2))
        x0, x1, x2 = x0 + dq[0], x1 + dq[1], x2 + dq[2]
        x3, x4, x5 = x3 + dq[3], x4 + dq[4], x5 + dq[5]
    return None


def _angles(forearms: list[F4]) -> tuple[float, ...]:
    out: list[float] = []
    for s2, c2, s3, c3 in forearms:
        out += (math.atan2(s2, c2), math.atan2(s3, c3))
    return tuple(out)


def _f3(v: Any) -> F3:
    """Three floats from a sequence; numpy arrays go through tolist (scalar indexing is slow)."""
    a, b, c = v.tolist() if type(v) is np.ndarray else v
    return float(a), float(b), float(c)


# --------------------------------------------------------------------------------------------
# the controller evaluation
# --------------------------------------------------------------------------------------------
def _singular(integral, z=(math.nan,) * 3, x=(math.nan,) * 6, iterations=-1) -> ControlOutput:
    """No torque can be computed: zeros, the integral untouched, status STATUS_SINGULAR."""
    return ControlOutput((0.0, 0.0, 0.0), tuple(integral), tuple(z), (0.0, 0.0, 0.0), tuple(x),
                         (0.0,) * 6, math.inf, STATUS_SINGULAR, iterations)


def evaluate(law: ControlLaw, y: Sequence[float], yd: Sequence[float], r: Sequence[float],
             rd: Sequence[float], rdd: Sequence[float],
             integral: Sequence[float] = (0.0, 0.0, 0.0), dt: float = 0.0,
             x_guess: Optional[Sequence[float]] = None,
             force: Sequence[float] = (0.0, 0.0, 0.0)) -> ControlOutput:
    """One evaluation of the control law; pure (no state is kept).

    ``integral`` is the integral state before this sample and ``dt`` the time it advances
    (0: evaluate only). ``x_guess`` (6 angles) warm-starts the Newton forward kinematics;
    without it, or if Newton fails, the closed form is used. ``force`` is the commanded contact
    force of the impedance mode (N, world; ignored in position mode). Vectors are 3-sequences.
    """
    k = law.model
    l1, l2 = k.l1, k.l2
    y0, y1, y2 = _f3(y)
    if not (math.isfinite(y0) and math.isfinite(y1) and math.isfinite(y2)):
        return _singular(integral)
    elb = _elbows(k, (y0, y1, y2))
    iterations = -1
    fk = None
    if x_guess is not None and law.fk == "newton":
        fk = _newton_fk(l2, elb, x_guess, law.newton_tol, law.newton_max_iter)
    if fk is not None:
        z, fa, x6, iterations = fk
        x: tuple[float, ...] = x6
    else:
        closed = _closed_fk(l2, elb)
        found = None if closed is None else _forearms_from_z(l2, elb, closed)
        if closed is None or found is None:
            return _singular(integral)
        z, fa, x = closed, found, _angles(found)
    n, dd = _directions(elb, fa)
    ninv = _inv3(n)
    d0, d1, d2 = dd
    dmin = min(abs(d0), abs(d1), abs(d2))
    if ninv is None or dmin < 1e-9:
        return _singular(integral, z, x, iterations)
    n00, n01, n02, n10, n11, n12, n20, n21, n22 = ninv
    # Frobenius condition number of Jc = N^-1 diag(l1 D) (l1 cancels); N's rows are unit
    jc2 = (d0 * d0 * (n00 * n00 + n10 * n10 + n20 * n20) + d1 * d1 * (n01 * n01 + n11 * n11
           + n21 * n21) + d2 * d2 * (n02 * n02 + n12 * n12 + n22 * n22))
    cond = math.sqrt(jc2 * (1.0 / (d0 * d0) + 1.0 / (d1 * d1) + 1.0 / (d2 * d2)))
    # Jc -> 0 uniformly when all arms stretch together and cond(Jc) stays ~14 there, so the
    # serial measure D_i = cos(forearm, elbow velocity) is checked against the limit as well
    near = cond > law.cond_limit or dmin * law.cond_limit < 1.0
    status = STATUS_ILL_CONDITIONED if near else STATUS_OK

    # velocities: N zd = (l1 D_i yd_i), then A_i xd_i = zd - b_i yd_i arm by arm
    yd0, yd1, yd2 = _f3(yd)
    q0, q1, q2 = l1 * d0 * yd0, l1 * d1 * yd1, l1 * d2 * yd2
    zdx = n00 * q0 + n01 * q1 + n02 * q2
    zdy = n10 * q0 + n11 * q1 + n12 * q2
    zdz = n20 * q0 + n21 * q1 + n22 * q2
    xd: list[float] = []
    for (cr, sr, c1, s1, _, _, _), (s2, c2, s3, c3), ydi in zip(elb, fa, (yd0, yd1, yd2)):
        rx = cr * zdx + sr * zdy
        ry = cr * zdy - sr * zdx + l1 * ydi * s1
        rz = zdz - l1 * ydi * c1
        xd += ((c2 * s3 * rx - s2 * ry + c2 * c3 * rz) / l2, (c3 * rx - s3 * rz) / (l2 * s2))

    # outer loop in wrist coordinates
    zx, zy, zz = z
    r0, r1, r2 = _f3(r)
    e0, e1, e2 = r0 - zx, r1 - zy, r2 - zz
    if law.impedance:
        return _impedance(law, elb, fa, ninv, dd, (yd0, yd1, yd2), xd, (e0, e1, e2), _f3(rd),
                          rdd, force, integral, z, (zdx, zdy, zdz), x, cond, status, iterations)
    imax = law.integral_max
    i0, i1, i2 = integral
    i0 = min(max(i0 + dt * e0, -imax), imax)
    i1 = min(max(i1 + dt * e1, -imax), imax)
    i2 = min(max(i2 + dt * e2, -imax), imax)
    kI, kP, kD = law.kI, law.kP, law.kD
    if imax > 0.0 and max(abs(i0), abs(i1), abs(i2)) >= imax:
        status |= STATUS_INTEGRAL_CLAMPED
    rd0, rd1, rd2 = _f3(rd)
    acc0 = kI * i0 + kP * e0 + kD * (rd0 - zdx)
    acc1 = kI * i1 + kP * e1 + kD * (rd1 - zdy)
    acc2 = kI * i2 + kP * e2 + kD * (rd2 - zdz)
    if law.feedforward:
        rdd0, rdd1, rdd2 = _f3(rdd)
        acc0, acc1, acc2 = acc0 + rdd0, acc1 + rdd1, acc2 + rdd2
    yds = [yd0, yd1, yd2] if law.coriolis else [0.0] * 3
    xds = xd if law.coriolis else [0.0] * 6
    u = _inverse_dynamics(k, elb, fa, ninv, dd, yds, xds, (acc0, acc1, acc2), (0.0, 0.0, 0.0))
    return _output(law, u, (i0, i1, i2), integral, z, (zdx, zdy, zdz), x, xd, cond, status, iterations)


def _impedance(law: ControlLaw, elb: list[Elbow], fa: list[F4], ninv: F9, dd: list[float], yd: F3,
               xd: list[float], e: F3, rd: F3, rdd: Sequence[float], force: Sequence[float],
               integral: Sequence[float], z: F3, zd: F3, x: tuple, cond: float, status: int,
               iterations: int) -> ControlOutput:
    """The impedance mode's torques: inverse dynamics for zdd = rdd plus Jc^T F with the wrist
    force F = K (r - z) + D (rd - zd) + force (module docstring). The integral is left alone."""
    (k0, k1, k2), (c0, c1, c2) = law.stiffness, law.task_damping
    f0, f1, f2 = _f3(force)
    wrench = (k0 * e[0] + c0 * (rd[0] - zd[0]) + f0, k1 * e[1] + c1 * (rd[1] - zd[1]) + f1,
              k2 * e[2] + c2 * (rd[2] - zd[2]) + f2)
    acc = _f3(rdd) if law.feedforward else (0.0, 0.0, 0.0)
    yds = [yd[0], yd[1], yd[2]] if law.coriolis else [0.0] * 3
    xds = xd if law.coriolis else [0.0] * 6
    u = _inverse_dynamics(law.model, elb, fa, ninv, dd, yds, xds, acc, wrench)
    i0, i1, i2 = _f3(integral)
    return _output(law, u, (i0, i1, i2), integral, z, zd, x, xd, cond, status, iterations)


def _output(law: ControlLaw, u: F3, integral_new: F3, integral_old: Sequence[float], z: F3, zd: F3,
            x: tuple, xd: list[float], cond: float, status: int, iterations: int) -> ControlOutput:
    """The evaluation's result with the torques saturated (or singular if they are not finite)."""
    u0, u1, u2 = u
    if not (math.isfinite(u0) and math.isfinite(u1) and math.isfinite(u2)):
        return _singular(integral_old, z, x, iterations)
    lim = law.torque_limit
    if max(abs(u0), abs(u1), abs(u2)) > lim:
        status |= STATUS_TORQUE_SATURATED
        u = (min(max(u0, -lim), lim), min(max(u1, -lim), lim), min(max(u2, -lim), lim))
    return ControlOutput(u, integral_new, z, zd, x, tuple(xd), cond, status, iterations)


def hold(u: Sequence[float], u_previous: Optional[Sequence[float]], limit: float) -> tuple[F3, bool]:
    """The torque to hold over a sample: the law's u with the half-sample lead
    u + (u - u_previous) / 2 when ``u_previous`` is given (see DeltaController), clipped to
    +-limit; and whether the lead had to be clipped."""
    u0, u1, u2 = u
    if u_previous is None:
        return (u0, u1, u2), False
    p0, p1, p2 = u_previous
    u0, u1, u2 = 1.5 * u0 - 0.5 * p0, 1.5 * u1 - 0.5 * p1, 1.5 * u2 - 0.5 * p2
    if max(abs(u0), abs(u1), abs(u2)) <= limit:
        return (u0, u1, u2), False
    return (min(max(u0, -limit), limit), min(max(u1, -limit), limit), min(max(u2, -limit), limit)), True


def warm_start(x: Sequence[float], xd: Sequence[float], xd_previous: Optional[Sequence[float]],
               ts: float) -> list[float]:
    """Newton's start for the next sample: x + ts xd + ts^2/2 xdd, xdd by a backward
    difference of the rates (first order without previous rates)."""
    if xd_previous is None:
        return [x[i] + ts * xd[i] for i in range(6)]
    return [x[i] + ts * (1.5 * xd[i] - 0.5 * xd_previous[i]) for i in range(6)]


def _inverse_dynamics(k: _Model, elb: list[Elbow], fa: list[F4], ninv: F9, dd: list[float],
                      v1s: list[float], xd: list[float], acc: F3, wrench: F3) -> F3:
    """Servo torques giving wrist acceleration ``acc`` (world) at the state (elb, fa, v1s, xd),
    plus Jc^T ``wrench``: the torques that act on the wrist like that force (N, world).

    Arm by arm in its own frame: the joint accelerations that produce the wrist acceleration,
    the generalised force Q_i = m_i q''_i + c_i + D v_i + g_i from the point-mass form, then
    u_i = Q_i1 - b_i . F_i with the constraint forces F_i (sum F_i = W) balancing rows 2-3,
    W the wrench (zero for pure inverse dynamics).
    """
    _, l1, l2, jrot, m1r1g, s0, s1m, s2m, g, damp = k
    ax, ay, az = acc
    qa: list[float] = []
    bf: list[float] = []
    sx = sy = sz = 0.0
    for i in range(3):
        cr, sr, c1, s1, _, _, _ = elb[i]
        s2, c2, s3, c3 = fa[i]
        v1, v2, v3, di = v1s[i], xd[2 * i], xd[2 * i + 1], dd[i]
        alx, aly = cr * ax + sr * ay, cr * ay - sr * ax
        # velocity-product part of the forearm direction's second derivative
        vv = v2 * v2 + v3 * v3
        cross = 2.0 * v2 * v3
        cen = l1 * v1 * v1                      # elbow centripetal acceleration
        tx = alx + l2 * (s2 * s3 * vv - cross * c2 * c3)
        ty = aly + cen * c1 + l2 * c2 * v2 * v2
        tz = az + cen * s1 + l2 * (s2 * c3 * vv + cross * c2 * s3)
        # dotting l1 t1 q1'' + l2 (d2 q2'' + d3 q3'') = t with d leaves the servo acceleration
        a1 = (s2 * s3 * tx + c2 * ty + s2 * c3 * tz) / (l1 * di)
        ey = -l1 * a1 * s1 - cen * c1            # elbow acceleration (x component is 0)
        ez = l1 * a1 * c1 - cen * s1
        # l2 d'' = a_local - e''; point-mass resultants, gravity folded into the elbow term
        fy, fz = aly - ey, az - ez
        ezg = ez + g
        pmy, pmz = s0 * ey + s1m * fy, s0 * ezg + s1m * fz
        pnx, pny, pnz = s2m * alx, s1m * ey + s2m * fy, s1m * ezg + s2m * fz
        qa.append(jrot * a1 + m1r1g * c1 + l1 * (c1 * pmz - s1 * pmy) + damp * v1)
        # F_perp = d2 Q2 / l2 + d3 Q3 / (l2 s2^2), Q2 = l2 d2 . Pn + c v2, Q3 = l2 d3 . Pn + c v3
        hb = c2 * s3 * pnx - s2 * pny + c2 * c3 * pnz + damp * v2 / l2
        hc = c3 * pnx - s3 * pnz + damp * v3 / (l2 * s2)
        fx, fyl, fzl = c2 * s3 * hb + c3 * hc, -s2 * hb, c2 * c3 * hb - s3 * hc
        sx += cr * fx - sr * fyl
        sy += sr * fx + cr * fyl
        sz += fzl
        bf.append(l1 * (c1 * fzl - s1 * fyl))   # b_i . F_perp_i
    # sum_i (F_perp_i + f_i n_i) = -W (world)  ->  f = -N^-T (s + W);  u_i = Q_i1 - b_i . F_i
    n00, n01, n02, n10, n11, n12, n20, n21, n22 = ninv
    sx, sy, sz = sx + wrench[0], sy + wrench[1], sz + wrench[2]
    f0 = -(n00 * sx + n10 * sy + n20 * sz)
    f1 = -(n01 * sx + n11 * sy + n21 * sz)
    f2 = -(n02 * sx + n12 * sy + n22 * sz)
    d0, d1, d2 = dd
    return (qa[0] - bf[0] - f0 * l1 * d0, qa[1] - bf[1] - f1 * l1 * d1,
            qa[2] - bf[2] - f2 * l1 * d2)


