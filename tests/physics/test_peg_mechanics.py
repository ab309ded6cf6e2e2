"""Issue 27 item 3: the peg-in-hole contact (deltafmi/physics/peg) against closed forms and a free
rigid peg integrated with scipy (deltafmi.physics.peg.rigid_peg).

Closed forms: free flight down a centred bore (no contact at all), the force ratio of a point
sliding on a chamfer, Whitney's wedging condition l/d <= mu (deltafmi.physics.friction.peg);
second formulations: the wrench of a rigidly moved scene, energy through elastic contacts, and the
generated C of the kernel (bit for bit).
"""
from __future__ import annotations

import math
import struct
from functools import partial

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

from deltafmi.builder.codegen import Entry, Obj, Vec
from deltafmi.builder.codegen.build import compile_unit
from deltafmi.toolchain import NoCompilerError
from deltafmi.physics.friction import peg as whitney
from deltafmi.physics.friction.law import FrictionParams, regularisation_error_bound
from deltafmi.physics.peg import Hole, Peg, PegContact, RigidPeg, contact, hole_rotation, peg_wrench, validate
from deltafmi.physics.wrist.kinematics import _basis_rotation as rot  # rotation about e_axis

#: tool rotation with the peg pointing straight down (tool z = -world z)
DOWN = np.diag([1.0, -1.0, -1.0])


def matrix(R9) -> np.ndarray:
    return np.array(R9).reshape(3, 3)


def integrate(rigid: RigidPeg, wrench, y0: np.ndarray, T: float, **options):
    return solve_ivp(lambda t, y: rigid.derivative(y, wrench), (0.0, T), y0, dense_output=True, **options)


def test_centred_peg_slides_down_a_tilted_bore_without_touching_it():
    """Peg on the (tilted) hole's axis, spinning about its own, pushed along the axis with no gravity:
    no contact anywhere in the chamfer or the bore, so depth(t) = d0 + F t^2 / (2 m) exactly. The
    clearance (0.1 mm) is twice the rim polygon's radial error (48 um), so a false contact would show.
    Tolerance: the integrator's (rtol 1e-10 on positions of 1e-2 m) -> 1e-9 m."""
    hole = Hole(x=0.1, y=-0.05, z=-1.1, tilt_x=0.05, tilt_y=-0.03)
    peg, law, F = Peg(), PegContact(), 5.0
    Rh = matrix(hole_rotation(hole))
    axis = Rh[:, 2]
    rigid = RigidPeg(peg, g=0.0, applied=tuple(-F * axis))
    d0 = -0.003
    tip = np.array([hole.x, hole.y, hole.z]) - d0 * axis
    y0 = rigid.state(tip, Rh @ DOWN, omega_body=(0.0, 0.0, 20.0))
    wrench = partial(peg_wrench, hole, peg, law)
    T = math.sqrt(2.0 * (0.035 - d0) * rigid.mass / F)  # until 35 mm deep (bottom at 40 mm)
    sol = integrate(rigid, wrench, y0, T, method="DOP853", rtol=1e-10, atol=1e-12)
    for t in np.linspace(0.0, T, 60):
        cw = rigid.contact(sol.sol(t), wrench)
        assert cw.active == 0 and cw.force == (0.0, 0.0, 0.0)
        assert cw.depth == pytest.approx(d0 + 0.5 * F / rigid.mass * t * t, abs=1e-9)
        assert cw.lateral < 1e-9 and cw.angular < 1e-9


@pytest.mark.parametrize("mu", [0.0, 0.2, 0.5])
@pytest.mark.parametrize("alpha_deg", [30.0, 45.0, 60.0])
def test_point_sliding_down_the_chamfer_force_ratio(mu, alpha_deg):
    """One rim point pressed delta0 into the chamfer, sliding down it at V: lateral / axial force =
    (sin a - mu cos a) / (cos a + mu sin a) (quasi-static Coulomb sliding) and f_n = k delta0
    (no normal velocity, so no damping force). The regularised friction differs from mu f_n by at
    most e = regularisation_error_bound(f_n, V); the ratio's derivative in the friction force is
    -f_n / den^2 with den >= f_n cos a, so the ratio is within e / (f_n cos^2 a) (+ rounding)."""
    a = math.radians(alpha_deg)
    hole = Hole(z=0.0, chamfer_angle=a)
    peg, law = Peg(), PegContact(mu=mu)
    rho0 = hole.bore_radius + 0.5 * hole.chamfer_width
    normal = np.array([-math.sin(a), 0.0, math.cos(a)])
    surface = np.array([rho0, 0.0, -0.5 * hole.chamfer_width * math.tan(a)])
    delta0, V = 5e-6, 0.01
    tip = surface - delta0 * normal - np.array([peg.radius, 0.0, 0.0])  # rim point 0 is tool x = world x
    down_slope = np.array([-math.cos(a), 0.0, -math.sin(a)])
    cw = peg_wrench(hole, peg, law, tuple(tip), tuple(DOWN.ravel()), tuple(V * down_slope), (0.0, 0.0, 0.0))
    assert cw.active == 1
    fn = law.stiffness * delta0
    assert cw.max_normal == pytest.approx(fn, rel=1e-12)
    ratio = -cw.force[0] / cw.force[2]
    closed = (math.sin(a) - mu * math.cos(a)) / (math.cos(a) + mu * math.sin(a))
    e = regularisation_error_bound(fn, V, FrictionParams(mu, mu), law.v_eps)
    print(f"\nchamfer {alpha_deg:g} deg, mu {mu}: force ratio off the closed form by {abs(ratio - closed):.1e}")
    assert abs(ratio - closed) <= e / (fn * math.cos(a) ** 2) + 1e-12
    assert abs(cw.force[1]) < 1e-9 * fn


def test_viscous_term_adds_c_v_times_the_sliding_speed():
    """The same point sliding down a 45-degree chamfer at V with a viscous coefficient c_v: the
    tangential force grows by exactly c_v V along the slope (the Coulomb part is unchanged), and a
    point that does not touch gets none (rounding only)."""
    a, V, c_v = math.radians(45.0), 0.01, 40.0
    hole, peg = Hole(z=0.0, chamfer_angle=a), Peg()
    rho0 = hole.bore_radius + 0.5 * hole.chamfer_width
    normal = np.array([-math.sin(a), 0.0, math.cos(a)])
    surface = np.array([rho0, 0.0, -0.5 * hole.chamfer_width * math.tan(a)])
    tip = surface - 5e-6 * normal - np.array([peg.radius, 0.0, 0.0])
    slope = np.array([-math.cos(a), 0.0, -math.sin(a)])
    dry, wet = (np.array(peg_wrench(hole, peg, law, tuple(tip), tuple(DOWN.ravel()), tuple(V * slope),
                                    (0.0, 0.0, 0.0)).force) for law in (PegContact(), PegContact(viscous=c_v)))
    assert (wet - dry) @ slope == pytest.approx(-c_v * V, rel=1e-12)
    assert (wet - dry) @ normal == pytest.approx(0.0, abs=1e-12)
    above = tuple(tip + 1e-3 * normal)
    assert peg_wrench(hole, peg, PegContact(viscous=c_v), above, tuple(DOWN.ravel()), tuple(V * slope),
                      (0.0, 0.0, 0.0)).force == (0.0, 0.0, 0.0)


def test_wrench_of_a_rigidly_moved_scene_is_the_rotated_wrench():
    """Second formulation of the frames: a tilted, displaced hole with the peg moved with it gives the
    untilted hole's wrench turned by R_h (moment about the tip, a free vector), the same
    diagnostics. Random contact states (tilted peg in the chamfer and in the bore, moving).
    Tolerance: rounding of a few rotations, 1e-9 of the force scale."""
    rng = np.random.default_rng(27)
    peg, law = Peg(), PegContact()
    base = Hole(z=0.0)
    moved = Hole(x=0.2, y=-0.1, z=-1.0, tilt_x=0.07, tilt_y=-0.04)
    Rh, H = matrix(hole_rotation(moved)), np.array([moved.x, moved.y, moved.z])
    touching = 0
    for _ in range(30):
        tip = np.array([rng.uniform(-1.5e-3, 1.5e-3), rng.uniform(-1.5e-3, 1.5e-3), rng.uniform(-6e-3, 1e-3)])
        tilt = rot(0, rng.uniform(-0.05, 0.05)) @ rot(1, rng.uniform(-0.05, 0.05))
        R = rot(2, rng.uniform(-math.pi, math.pi)) @ tilt @ DOWN
        v, w = rng.normal(0.0, 0.05, 3), rng.normal(0.0, 1.0, 3)
        ref = peg_wrench(base, peg, law, tuple(tip), tuple(R.ravel()), tuple(v), tuple(w))
        got = peg_wrench(moved, peg, law, tuple(H + Rh @ tip), tuple((Rh @ R).ravel()), tuple(Rh @ v), tuple(Rh @ w))
        scale = 1e-9 * max(1.0, float(np.abs(ref.force).max()))
        np.testing.assert_allclose(got.force, Rh @ np.array(ref.force), atol=scale)
        np.testing.assert_allclose(got.moment, Rh @ np.array(ref.moment), atol=scale * peg.length)
        assert got.active == ref.active
        assert (got.depth, got.lateral, got.angular) == pytest.approx((ref.depth, ref.lateral, ref.angular), abs=1e-12)
        touching += ref.active > 0
    assert touching >= 10  # the sample exercises the contacts, not only free space


@pytest.mark.parametrize("edge_radius", [2e-4, 0.0])
@pytest.mark.parametrize("sweep", ["across the top edge", "down past the bore edge"])
def test_force_is_continuous_over_rounded_edges(edge_radius, sweep):
    """The peg pressed 50 um into the fixture slides (in steps dx) across the top/chamfer edge, or
    down the bore wall past the chamfer/bore edge. Each contact's force k delta n changes by at
    most k (|grad delta| + delta |grad n|) dx <= k e / (e - delta) dx (the normal turns at 1 / (e - delta)
    about a fillet of radius e), so the resultant by at most active * k e / (e - delta) dx. With
    sharp edges (e = 0) the normal flips at the edge: a jump over k delta, whatever dx."""
    hole, peg, law = Hole(z=0.0, edge_radius=edge_radius), Peg(), PegContact(damping=0.0, mu=0.0)
    delta = 50e-6
    if sweep == "across the top edge":  # rim point 0 (tool x) moves in at 50 um under the top plane
        path = [(x - peg.radius, 0.0, -delta)
                for x in np.linspace(hole.bore_radius + hole.chamfer_width + 5e-4, hole.bore_radius - 3e-4, 4001)]
    else:  # rim point 0 moves down 50 um inside the bore's wall
        path = [(hole.bore_radius + delta - peg.radius, 0.0, z) for z in np.linspace(-1.2e-3, -3.5e-3, 4001)]
    dx = float(np.linalg.norm(np.subtract(path[1], path[0])))
    results = [peg_wrench(hole, peg, law, tip, tuple(DOWN.ravel()), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)) for tip in path]
    forces = np.array([r.force for r in results])
    jumps = np.linalg.norm(np.diff(forces, axis=0), axis=1)
    active = np.maximum([r.active for r in results[:-1]], [r.active for r in results[1:]])
    assert max(r.max_normal for r in results) > 5.0  # it pressed through both faces of the edge
    print(f"\nedge radius {edge_radius * 1e3:g} mm, {sweep}: largest force jump between steps {jumps.max():.2f} N")
    if edge_radius > 0.0:
        assert np.all(jumps <= active * law.stiffness * edge_radius / (edge_radius - delta) * dx * (1 + 1e-9))
    else:
        assert jumps.max() > law.stiffness * delta  # ~15 N in one step; rounded: under 0.4 N


def test_ring_contact_takes_the_ring_point_nearest_a_tilted_axis():
    """The edge contact's ring point is the nearest to the peg axis of all the ring's points,
    checked against a scan of 3601 ring angles refined by Brent's method, for tilted peg poses in
    and over the hole (tilt to 0.3 rad, tip within 2.5 mm of the axis, from 2 mm above the top
    to 30 mm deep). A tilted axis has a local minimum of distance on each side of the ring;
    Newton from where the axis crosses the ring's plane alone stopped in the farther one (a 7 deg
    peg 3.3 mm deep missed a 22 um, 4.4 N penetration of the bore edge). Tolerance 1e-7 m on the
    penetration (0.02 N at 2e5 N/m): 3 Newton steps leave under 8e-8 m in the distance
    (measured over 20000 poses), the bounded scalar minimisation 1e-12 rad in the angle."""
    hole, peg = Hole(z=0.0), Peg()
    sa, ca = math.sin(hole.chamfer_angle), math.cos(hole.chamfer_angle)
    V = contact._corners(hole, sa, ca)
    psi = np.linspace(0.0, 2.0 * np.pi, 3601)
    step = psi[1]
    rng = np.random.default_rng(2)
    touching = 0
    for _ in range(1500):
        tilt, azimuth = rng.uniform(0.0, 0.3), rng.uniform(0.0, 2.0 * np.pi)
        a = np.array([math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), -math.cos(tilt)])
        c = np.array([rng.uniform(-2.5e-3, 2.5e-3), rng.uniform(-2.5e-3, 2.5e-3), rng.uniform(-0.03, 0.002)])
        for radius, height in ((V[0], V[1]), (V[2], V[3])):
            _, delta, _ = contact._ring_contact(peg, hole.edge_radius, radius, height, tuple(c), tuple(a))
            def arm(angle):  # (ring point - tip, its distance from the axis, its height along it)
                w = np.stack([radius * np.cos(angle), radius * np.sin(angle), np.full_like(angle, height)], -1) - c
                along = w @ a
                return w, np.linalg.norm(w - along[..., None] * a, axis=-1), along
            _, dist, along = arm(psi)
            best = np.argmin(dist)
            if delta <= 0.0 and min(peg.radius + hole.edge_radius - dist[best], -along[best],
                                    peg.length + along[best]) < -1e-5:
                continue  # apart by more than the grid's error: no contact either way
            best = minimize_scalar(lambda angle: arm(np.array(angle))[1], bounds=(psi[best] - step, psi[best] + step),
                                   method="bounded", options={"xatol": 1e-12}).x
            _, dist, along = arm(np.array(best))
            expected = min(peg.radius + hole.edge_radius - dist, -along, peg.length + along)
            if expected > 0.0 or delta > 0.0:
                touching += 1
                assert delta == pytest.approx(expected, abs=1e-7)
    assert touching > 100


def _two_point(mu: float, squeeze: float):
    """A peg of d = 20 mm in a bore of D = 20.4 mm at depth l = 5 mm (l/d = 0.25), tilted into
    two-point contact with the chamfer/bore ring (Whitney's lip) and the wall, then squeezed by
    `squeeze` (m) at both contacts: the internal force pair that wedging holds. Pressed along the
    hole axis through the tip centre (no moment), no gravity."""
    r, D, l = 0.010, 0.0204, 0.005
    hole = Hole(z=0.0, bore_radius=D / 2.0, chamfer_width=5e-4, edge_radius=0.0)  # Whitney's sharp lip
    peg, law = Peg(r, 0.1), PegContact(stiffness=1e6, damping=0.0, mu=mu, v_eps=1e-5)
    geo = whitney.contacts(l, 2.0 * r, D + 2.0 * squeeze)  # too wide a tilt by `squeeze` a side
    lip = np.array([-D / 2.0 - squeeze, 0.0, -hole.chamfer_width * math.tan(hole.chamfer_angle)])
    tip = lip - np.array([geo.points[1][0], 0.0, geo.points[1][1]])
    rigid = RigidPeg(peg, g=0.0, applied=(0.0, 0.0, -10.0))
    return rigid, partial(peg_wrench, hole, peg, law), rigid.state(tip, rot(1, -geo.tilt) @ DOWN), (l, 2 * r, D)


def test_wedged_peg_does_not_go_in():
    """l/d = 0.25 <= mu = 0.5 (and friction.peg.wedged): the squeezed two-point contact holds
    under a 10 N axial push (measured: the depth changes by 14 um). Inside the friction cones the
    contact points do not slide, beyond the regularised law's creep (v_eps artanh(l / (d mu)) <
    v_eps, under 0.4 um here): the peg moves only as the contacts deflect, each point by at most
    f_max / k, a rotation by at most 2 f_max / (k |C1 L|) with |C1 L| = sqrt(d^2 + l^2) > d, so the
    tip (d/2 from the contacts' line) by at most 2 f_max / k."""
    rigid, wrench, y0, (l, d, D) = _two_point(0.5, 50e-6)
    assert whitney.wedged(l, d, D, 0.5)
    T = 0.04
    sol = integrate(rigid, wrench, y0, T, method="LSODA", rtol=1e-8, atol=1e-10)
    start, mid, end = (rigid.contact(sol.sol(t), wrench) for t in (0.0, 0.5 * T, T))
    f_max = max(rigid.contact(sol.sol(t), wrench).max_normal for t in np.linspace(0.0, T, 41))
    assert end.active >= 2 and f_max > 10.0
    print(f"\nwedged: the depth changes by {abs(end.depth - start.depth) * 1e6:.1f} um in {T * 1e3:g} ms")
    assert abs(end.depth - start.depth) <= 2.0 * f_max / 1e6
    assert abs(end.depth - mid.depth) <= 1e-5 * 0.5 * T  # creep, v_eps = 1e-5 m/s


def test_same_squeeze_below_the_wedging_bound_slides_in():
    """mu = 0.15 < l/d = 0.25 (not wedged): the squeeze cannot hold, the peg turns upright and the
    push drives it in: over 2 mm within 30 ms, more than ten times the wedged case's bound (0.17 mm)."""
    rigid, wrench, y0, (l, d, D) = _two_point(0.15, 50e-6)
    assert not whitney.wedged(l, d, D, 0.15)
    T = 0.03
    sol = integrate(rigid, wrench, y0, T, method="LSODA", rtol=1e-7, atol=1e-10)
    start, end = rigid.contact(y0, wrench), rigid.contact(sol.sol(T), wrench)
    print(f"\nnot wedged: in by {(end.depth - start.depth) * 1e3:.2f} mm in {T * 1e3:g} ms")
    assert end.depth - start.depth > 2e-3
    assert end.angular < 0.6 * start.angular


def _dropped(mu: float, damping: float, depth: float = 0.04):
    """A vertical peg released 2 mm above the hole, off-centre by the clearance plus 60 % of the
    chamfer width (its rim over the chamfer), turned 0.1 rad about its axis, under gravity."""
    hole, peg = Hole(z=0.0, depth=depth), Peg()
    law = PegContact(stiffness=2e5, damping=damping, mu=mu)
    rigid = RigidPeg(peg)
    off = hole.bore_radius - peg.radius + 0.6 * hole.chamfer_width
    y0 = rigid.state((off * math.cos(0.3), off * math.sin(0.3), 0.002), DOWN @ rot(2, 0.1))
    return hole, peg, rigid, partial(peg_wrench, hole, peg, law), y0


def test_dropped_peg_falls_in_and_centres():
    """With friction (mu 0.2) and damping the peg slides off the chamfer into the bore, to its bottom,
    where it keeps wobbling on its rim (little damping): its tip is then within the clearance of
    the axis, plus the rim polygon's radial error and the contacts' deflection f_max / k, and its
    tilt within the bore's play, (2 clearance + polygon + 2 f_max / k) over the length in the bore."""
    hole, peg, rigid, wrench, y0 = _dropped(0.2, 20.0, depth=0.012)
    T = 0.15
    sol = integrate(rigid, wrench, y0, T, method="LSODA", rtol=1e-7, atol=1e-10)
    start, end = rigid.contact(y0, wrench), rigid.contact(sol.sol(T), wrench)
    clearance = hole.bore_radius - peg.radius
    polygon = peg.radius * (1.0 - math.cos(math.pi / contact.RIM_POINTS))
    deflection = end.max_normal / 2e5
    assert start.lateral > clearance + hole.chamfer_width / 2.0
    assert end.depth > hole.depth - peg.radius * math.sin(end.angular) - deflection
    assert end.lateral <= clearance + polygon + deflection
    in_bore = end.depth - hole.chamfer_width * math.tan(hole.chamfer_angle)
    assert end.angular <= (2.0 * clearance + polygon + 2.0 * deflection) / in_bore


def test_elastic_frictionless_drop_conserves_energy():
    """mu = 0, c = 0: the contact forces are the gradient of sum 1/2 k delta^2 (material rim points,
    on the rounded fixture), so kinetic + gravity + elastic energy stays constant through the chamfer
    impact, to the integrator's error: DOP853 at rtol 1e-10 leaves 5e-10 of the impact energy
    (6e-6 at rtol 1e-8: it scales with the tolerance, no drift of its own); bound 1e-8."""
    hole, peg, rigid, wrench, y0 = _dropped(0.0, 0.0)
    T = 0.045
    sol = integrate(rigid, wrench, y0, T, method="DOP853", rtol=1e-10, atol=1e-12)
    E0 = rigid.energy(y0, wrench)
    impact = rigid.mass * rigid.g * 0.003  # kinetic energy at the chamfer, ~7 mJ
    samples = [sol.sol(t) for t in np.linspace(0.0, T, 200)]
    assert max(rigid.contact(y, wrench).max_normal for y in samples) > 10.0  # it hit the chamfer
    print(f"\nelastic drop: energy {max(abs(rigid.energy(y, wrench) - E0) for y in samples) / impact:.1e} of the impact's")
    assert max(abs(rigid.energy(y, wrench) - E0) for y in samples) <= 1e-8 * impact


def _bits(value) -> list:
    if isinstance(value, (tuple, list)):
        return [b for v in value for b in _bits(v)]
    return [struct.unpack("<q", struct.pack("<d", value))[0] if isinstance(value, float) else value]


def test_generated_c_gives_the_kernels_bits(tmp_path):
    """deltafmi/builder/codegen translates peg_wrench; the C returns the Python's bits (-ffp-contract=off)."""
    entry = Entry("peg_wrench", peg_wrench, [Obj(Hole), Obj(Peg), Obj(PegContact), Vec(3), Vec(9), Vec(3), Vec(3)])
    try:
        lib = compile_unit([entry], tmp_path)
    except NoCompilerError as exc:
        pytest.skip(f"no C compiler: {exc}")
    rng = np.random.default_rng(3)
    hole, peg, law = Hole(tilt_x=0.02, tilt_y=-0.01), Peg(), PegContact()
    H = np.array([hole.x, hole.y, hole.z])
    for _ in range(40):
        tip = H + [rng.uniform(-2e-3, 2e-3), rng.uniform(-2e-3, 2e-3), rng.uniform(-8e-3, 1e-3)]
        R = rot(2, rng.uniform(-3.0, 3.0)) @ rot(0, rng.normal(0.0, 0.05)) @ DOWN
        args = (hole, peg, law, tuple(tip), tuple(R.ravel()), tuple(rng.normal(0, 0.05, 3)), tuple(rng.normal(0, 1, 3)))
        assert _bits(tuple(lib.call("peg_wrench", *args))) == _bits(tuple(peg_wrench(*args)))


@pytest.mark.parametrize("bad, word", [
    (dict(hole=Hole(bore_radius=0.009)), "bore_radius"),
    (dict(hole=Hole(chamfer_angle=2.0)), "chamfer_angle"),
    (dict(hole=Hole(depth=0.001, chamfer_width=0.002)), "depth"),
    (dict(contact=PegContact(v_eps=0.0)), "v_eps"),
    (dict(hole=Hole(chamfer_width=1e-4, edge_radius=1e-3)), "edge_radius .* does not fit the chamfer"),
    (dict(peg=Peg(radius=-0.01)), "peg radius"),
])
def test_bad_parameters_name_themselves(bad, word):
    args = dict(hole=Hole(), peg=Peg(), contact=PegContact()) | bad
    with pytest.raises(ValueError, match=word):
        validate(**args)
