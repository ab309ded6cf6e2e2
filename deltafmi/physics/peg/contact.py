"""The contact wrench on a cylindrical peg in a chamfered hole: penalty normal forces, regularised
Coulomb friction, in plain floats (the kernel subset of deltafmi/builder/codegen/translate.py).

Geometry (hole frame of :mod:`.params`, cylindrical coordinates rho, z about the hole axis, bore
radius R_b, chamfer outer radius R_c = R_b + w, chamfer angle alpha, depth H, edge radius e). In
the meridian plane (rho, z) the fixture is the wall W = {z <= 0, below the chamfer cone,
rho >= R_b} with its two convex edges (top/chamfer, chamfer/bore) rounded by fillets of radius e,
together with the bottom slab {z <= -H}. W rounded is E + disc(e), E the wall with every face
moved in by e (corners V1 = (R_c + e tan(alpha/2), -e) and V2 = (R_b + e, -((w - e) sin(alpha) + e)
/ cos(alpha))), so a point's penetration is

    delta = max(e - dist(p, E),  -H - z)          (wall, bottom; the corner between them is concave)

with the normal (p - nearest point of E) / dist: the nearest point moves continuously over E's
faces and corners, so the normal turns continuously around the rounded edges (with e = 0 the
edges are sharp and the normal jumps there). A point deeper than e into the wall (inside E)
exits through its nearest face: min(-z, (rho - R_c) sin(alpha) - z cos(alpha), rho - R_b).

Contacts, each a penalty spring-damper at one point (force on the peg f_n nu + f_t):

(a) RIM_POINTS = 32 points of the peg's bottom rim, fixed in the peg (tool angles 2 pi k / 32),
    against the fixture. Material points make the normal forces the gradient of
    sum 1/2 k delta_k^2: energy is conserved with c = 0, mu = 0 (a rim set turning with the state
    would not be). 32 is the count for which the inscribed polygon's radial error
    r (1 - cos(pi/32)) = 0.48 % of r (48 um for r = 10 mm) stays below a typical clearance, and
    a tilted face's lowest point is missed by at most r sin(theta) (1 - cos(pi/32)) (4.2 um at
    5 deg); the tool's x and y axes carry rim points, so a tilt about them is resolved exactly.
(b) The two rounded edges (tori about the fillet-centre circles V1, V2) against the peg's side:
    the centre-circle point nearest the peg axis (Newton on the ring angle, 3 steps from each of
    three starts: where the axis crosses the ring's plane and the two azimuths of its tilt; the
    distance has a local minimum on either side of a tilted axis) at distance dist from the axis
    and height s above the tip along it penetrates the side by r + e - dist; the contact acts
    radially to the peg axis, with delta = min(r + e - dist, s, L - s): it ramps in from zero as
    the edge passes the peg's bottom (top) face, where the rim points (a) hand it over. This is
    the second point of two-point contact, the one that wedges. Its side force is the gradient
    of 1/2 k delta^2 too (at the nearest point, by the envelope theorem); the ramp, only as high
    as the contact's own deflection, is not.

Per contact: f_n = max(k delta + c delta', 0) (>= 0 always), friction
f_t = -mu f_n tanh(|v_t| / v_eps) v_t / |v_t| - c_v v_t (a viscous term while f_n > 0) with v_t
the tangential velocity of the peg's material point. Its deviation from Coulomb's mu f_n while sliding is
deltafmi.physics.friction.law.regularisation_error_bound: mu f_n (1 - tanh(|v_t|/v_eps))
<= 2 mu f_n exp(-2 |v_t| / v_eps); below the static limit the law creeps at
|v_t| = v_eps artanh(|f_t| / (mu f_n)) instead of sticking. The force is continuous in the
state except where a contact opens with delta' > 0 (the damper's onset), where sharp edges
(e = 0) turn a normal, and where a point goes deeper than e into the wall (inside E).
"""
from __future__ import annotations

import math
from typing import NamedTuple

from .params import Hole, Peg, PegContact

__all__ = ["RIM_POINTS", "PegWrench", "peg_wrench", "placed_peg_wrench", "hole_rotation"]

F3 = tuple[float, float, float]
F7 = tuple[float, float, float, float, float, float, float]
F9 = tuple[float, float, float, float, float, float, float, float, float]
F4 = tuple[float, float, float, float]

#: rim points of the peg's bottom edge, equally spaced in the tool frame (module docstring)
RIM_POINTS = 32
RIM_COS = tuple(math.cos(2.0 * math.pi * k / RIM_POINTS) for k in range(RIM_POINTS))
RIM_SIN = tuple(math.sin(2.0 * math.pi * k / RIM_POINTS) for k in range(RIM_POINTS))
_NEWTON_STEPS = 3


class PegWrench(NamedTuple):
    """The contact's resultant on the peg and what an insertion is judged by."""

    force: F3  #: total contact force on the peg, world (N)
    moment: F3  #: its moment about the tool tip, world (N m)
    depth: float  #: tip below the hole's top plane along the hole axis (m)
    lateral: float  #: distance of the tip from the hole axis (m)
    angular: float  #: angle between the peg axis and the hole axis (rad)
    max_normal: float  #: largest normal force of one contact (N)
    active: float  #: number of contacts with penetration > 0
    potential: float  #: elastic energy sum 1/2 k delta^2 of the contacts (J)


def hole_rotation(hole: Hole) -> F9:
    """R_h = Ry(tilt_y) Rx(tilt_x), row-major: the hole frame's axes as columns in the world."""
    return _tilt_rotation(hole.tilt_x, hole.tilt_y)


def _tilt_rotation(tilt_x: float, tilt_y: float) -> F9:
    ca, sa = math.cos(tilt_x), math.sin(tilt_x)
    cb, sb = math.cos(tilt_y), math.sin(tilt_y)
    return (cb, sb * sa, sb * ca, 0.0, ca, -sa, -sb, cb * sa, cb * ca)


def _to_local(Rh: F9, x: float, y: float, z: float) -> F3:
    """R_h^T v."""
    return (Rh[0] * x + Rh[3] * y + Rh[6] * z, Rh[1] * x + Rh[4] * y + Rh[7] * z,
            Rh[2] * x + Rh[5] * y + Rh[8] * z)


def _to_world(Rh: F9, v: F3) -> F3:
    """R_h v."""
    return (Rh[0] * v[0] + Rh[1] * v[1] + Rh[2] * v[2], Rh[3] * v[0] + Rh[4] * v[1] + Rh[5] * v[2],
            Rh[6] * v[0] + Rh[7] * v[1] + Rh[8] * v[2])


def _contact(c: PegContact, rx: float, ry: float, rz: float, nx: float, ny: float, nz: float, delta: float,
             v: F3, w: F3) -> F7:
    """One contact at r (from the tip) with unit normal n pushing the peg and penetration delta > 0,
    the peg moving with tip velocity v and angular velocity w: (force (3), moment about the tip (3), f_n)."""
    px = v[0] + w[1] * rz - w[2] * ry
    py = v[1] + w[2] * rx - w[0] * rz
    pz = v[2] + w[0] * ry - w[1] * rx
    vn = px * nx + py * ny + pz * nz
    fn = max(c.stiffness * delta - c.damping * vn, 0.0)
    tx, ty, tz = px - vn * nx, py - vn * ny, pz - vn * nz
    speed = math.sqrt(tx * tx + ty * ty + tz * tz)
    x = speed / c.v_eps
    # tanh(x) / |v_t| without 0/0: tanh(x)/x = 1 - x^2/3 + O(x^4), below 1e-8 exact in doubles
    gain = math.tanh(x) / speed if x > 1e-8 else 1.0 / c.v_eps
    ft = c.mu * fn * gain + (c.viscous if fn > 0.0 else 0.0)
    fx, fy, fz = fn * nx - ft * tx, fn * ny - ft * ty, fn * nz - ft * tz
    return fx, fy, fz, ry * fz - rz * fy, rz * fx - rx * fz, rx * fy - ry * fx, fn


def _corners(hole: Hole, sa: float, ca: float) -> F4:
    """(rho, z) of E's corners V1 (top/chamfer) and V2 (chamfer/bore): the fillet centres."""
    e = hole.edge_radius
    return (hole.bore_radius + hole.chamfer_width + e * (1.0 - ca) / sa, -e, hole.bore_radius + e,
            -((hole.chamfer_width - e) * sa + e) / ca)


def _nearer(best: F3, rho: float, z: float, nr: float, nz: float) -> F3:
    """(distance, rho, z) of the nearer of best and the point (nr, nz) to (rho, z)."""
    d = math.sqrt((rho - nr) * (rho - nr) + (z - nz) * (z - nz))
    return (d, nr, nz) if d < best[0] else best


def _rim_penetration(hole: Hole, sa: float, ca: float, V: F4, x: float, y: float, z: float) -> tuple[float, F3]:
    """A point's penetration into the fixture (hole frame) and the unit normal pushing it out
    (module docstring; sa, ca: sine and cosine of the chamfer angle, V: E's corners)."""
    rho = math.sqrt(x * x + y * y)
    ex, ey = (x / rho, y / rho) if rho > 0.0 else (1.0, 0.0)
    e = hole.edge_radius
    top = -z
    cone = (rho - hole.bore_radius - hole.chamfer_width) * sa - z * ca
    bore = rho - hole.bore_radius
    bottom = -hole.depth - z
    wall = min(top, cone, bore)
    nr, nz = (0.0, 1.0) if wall == top else ((-sa, ca) if wall == cone else (-1.0, 0.0))
    # outside the sharp wall W (wall <= 0) the rounded wall, inside W, is not touched either;
    # deeper than e (inside E) the point leaves through W's nearest face
    if wall > 0.0 and wall < e:  # nearest point of E: on its top face, chamfer face or bore face (corners included)
        dr, dz = V[2] - V[0], V[3] - V[1]
        t = ((rho - V[0]) * dr + (z - V[1]) * dz) / (dr * dr + dz * dz) if dr * dr + dz * dz > 0.0 else 0.0
        t = min(max(t, 0.0), 1.0)
        best = _nearer((math.inf, 0.0, 0.0), rho, z, max(rho, V[0]), V[1])
        best = _nearer(best, rho, z, V[0] + t * dr, V[1] + t * dz)
        best = _nearer(best, rho, z, V[2], min(z, V[3]))
        wall = e - best[0]
        nr, nz = (rho - best[1]) / best[0], (z - best[2]) / best[0]
    if bottom > wall:
        return bottom, (0.0, 0.0, 1.0)
    return wall, (nr * ex, nr * ey, nz)


def _ring_newton(radius: float, height: float, c: F3, a: F3, psi: float) -> float:
    """Newton on dist^2(psi), the squared distance of the ring point at psi from the peg axis
    through c along a, from psi (a step only where dist^2 is convex)."""
    for _ in range(_NEWTON_STEPS):
        cs, sn = math.cos(psi), math.sin(psi)
        wx, wy, wz = radius * cs - c[0], radius * sn - c[1], height - c[2]
        wa = wx * a[0] + wy * a[1] + wz * a[2]
        dx, dy = -radius * sn, radius * cs  # dq/dpsi; d2q/dpsi2 = (-radius cs, -radius sn, 0)
        da = dx * a[0] + dy * a[1]
        d2a = -radius * (cs * a[0] + sn * a[1])
        g1 = wx * dx + wy * dy - wa * da
        g2 = radius * radius - radius * (wx * cs + wy * sn) - da * da - wa * d2a
        if g2 > 0.0:
            psi = psi - g1 / g2
    return psi


def _ring_point(radius: float, height: float, c: F3, a: F3) -> tuple[float, float, float]:
    """The point of the ring (radius, height) nearest the peg axis through c along a (hole frame).
    dist^2 along the ring has up to two local minima (a tilted axis passes nearer the ring on
    the side it leans to and on the opposite one), so Newton starts three times: where the axis
    crosses the ring's plane, and at the azimuth of the axis' tilt and its opposite (where
    (q - c) . a, whose square dist^2 subtracts, is extreme); the nearest result wins."""
    t = (height - c[2]) / a[2] if abs(a[2]) > 1e-9 else 0.0
    lean = math.atan2(a[1], a[0])
    best, best_psi = math.inf, 0.0
    for start in (math.atan2(c[1] + t * a[1], c[0] + t * a[0]), lean, lean + math.pi):
        psi = _ring_newton(radius, height, c, a, start)
        wx, wy, wz = radius * math.cos(psi) - c[0], radius * math.sin(psi) - c[1], height - c[2]
        wa = wx * a[0] + wy * a[1] + wz * a[2]
        d2 = wx * wx + wy * wy + wz * wz - wa * wa
        if d2 < best:
            best, best_psi = d2, psi
    return radius * math.cos(best_psi), radius * math.sin(best_psi), height


def _ring_contact(peg: Peg, e: float, radius: float, height: float, c: F3, a: F3) -> tuple[F3, float, F3]:
    """A rounded edge (fillet tube of radius e about the circle (radius, height)) against the peg's
    side (hole frame): the contact point on the peg relative to the tip, the penetration and the
    unit normal pushing the peg (module docstring, (b))."""
    qx, qy, qz = _ring_point(radius, height, c, a)
    rx, ry, rz = qx - c[0], qy - c[1], qz - c[2]
    along = rx * a[0] + ry * a[1] + rz * a[2]
    px, py, pz = rx - along * a[0], ry - along * a[1], rz - along * a[2]
    dist = math.sqrt(px * px + py * py + pz * pz)
    delta = min(peg.radius + e - dist, -along, peg.length + along)
    if not dist > 0.0:
        return (rx, ry, rz), 0.0, (0.0, 0.0, 1.0)
    ux, uy, uz = px / dist, py / dist, pz / dist
    return ((along * a[0] + peg.radius * ux, along * a[1] + peg.radius * uy, along * a[2] + peg.radius * uz),
            delta, (-ux, -uy, -uz))


def _accumulate(acc: F9, c: PegContact, rx: float, ry: float, rz: float, n: F3, delta: float, v: F3,
                w: F3) -> F9:
    """acc = (force (3), moment about the tip (3), largest f_n, elastic energy, active contacts) with
    the contact at r (from the tip), normal n, penetration delta added if delta > 0."""
    if not delta > 0.0:
        return acc
    f = _contact(c, rx, ry, rz, n[0], n[1], n[2], delta, v, w)
    return (acc[0] + f[0], acc[1] + f[1], acc[2] + f[2], acc[3] + f[3], acc[4] + f[4], acc[5] + f[5],
            max(acc[6], f[6]), acc[7] + 0.5 * c.stiffness * delta * delta, acc[8] + 1.0)


def peg_wrench(hole: Hole, peg: Peg, contact: PegContact, tip: F3, R: F9, v_tip: F3, omega: F3) -> PegWrench:
    """The fixture's contact wrench on the peg (module docstring).

    Args:
        hole, peg, contact: the geometry and the law (:mod:`.params`).
        tip: tool tip = centre of the peg's bottom face, world (m).
        R: tool rotation, row-major (columns: tool x, y, z in the world; tool z = peg axis
            pointing from the peg into its tip, down at R = diag(1, -1, -1)).
        v_tip: velocity of the tip, world (m/s); omega: the peg's angular velocity, world (rad/s).
    """
    return placed_peg_wrench(hole, (hole.x, hole.y, hole.tilt_x, hole.tilt_y), peg, contact, tip, R, v_tip, omega)


def placed_peg_wrench(hole: Hole, placed: F4, peg: Peg, contact: PegContact, tip: F3, R: F9, v_tip: F3,
                      omega: F3) -> PegWrench:
    """:func:`peg_wrench` of the hole moved to x, y and tilted by tilt_x, tilt_y (``placed``), its
    height and geometry ``hole``'s (an estimator's hole under test, without a new Hole)."""
    Rh = _tilt_rotation(placed[2], placed[3])
    c = _to_local(Rh, tip[0] - placed[0], tip[1] - placed[1], tip[2] - hole.z)
    e1 = _to_local(Rh, R[0], R[3], R[6])
    e2 = _to_local(Rh, R[1], R[4], R[7])
    a = _to_local(Rh, R[2], R[5], R[8])
    v = _to_local(Rh, v_tip[0], v_tip[1], v_tip[2])
    w = _to_local(Rh, omega[0], omega[1], omega[2])
    r = peg.radius
    acc = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    sa, ca = math.sin(hole.chamfer_angle), math.cos(hole.chamfer_angle)
    V = _corners(hole, sa, ca)
    # the rim's lowest point is r |a x e_z| below the tip: above the top plane no rim point touches
    below = c[2] - r * math.sqrt(a[0] * a[0] + a[1] * a[1]) <= 0.0
    for ck, sk in zip(RIM_COS, RIM_SIN):
        rx = r * (ck * e1[0] + sk * e2[0])
        ry = r * (ck * e1[1] + sk * e2[1])
        rz = r * (ck * e1[2] + sk * e2[2])
        delta, n = _rim_penetration(hole, sa, ca, V, c[0] + rx, c[1] + ry, c[2] + rz) if below else (0.0, e1)
        acc = _accumulate(acc, contact, rx, ry, rz, n, delta, v, w)
    for radius, height in ((V[0], V[1]), (V[2], V[3])):
        rel, delta, n = _ring_contact(peg, hole.edge_radius, radius, height, c, a)
        acc = _accumulate(acc, contact, rel[0], rel[1], rel[2], n, delta, v, w)
    angular = math.atan2(math.sqrt(a[0] * a[0] + a[1] * a[1]), -a[2])
    return PegWrench(_to_world(Rh, (acc[0], acc[1], acc[2])), _to_world(Rh, (acc[3], acc[4], acc[5])), -c[2],
                     math.sqrt(c[0] * c[0] + c[1] * c[1]), angular, acc[6], acc[8], acc[7])
