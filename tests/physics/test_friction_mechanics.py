"""Coulomb friction as STICK / SLIP modes (deltafmi.physics.friction) against closed forms.

Tolerances: the motions of the block are piecewise polynomial, which DOP853 integrates exactly;
what is left is round-off (1e-15 m) and the event offset EPS = 1e-12 (a stop located
EPS v_ref / |a| ~ 1e-13 s late): hence 1e-10 relative on positions. The stick-slip cycle is
harmonic (not polynomial): rtol 1e-12 over ~15 cycles leaves ~1e-11, checked to 1e-8.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hybrid_sim import simulate
from friction_belt import make_belt_oscillator, stick_slip_cycle
from friction_incline import (incline_position, incline_viscous_position,
                                                 make_incline, make_plane_incline,
                                                 plane_path_invariant, plane_stop_time)
from deltafmi.physics.friction.law import (SLIP_NEGATIVE, SLIP_POSITIVE, STICK, FrictionParams,
                                             after_stop, regularisation_error_bound,
                                             regularised_force, slip_force)
from deltafmi.physics.friction.peg import (cone_edge_wrenches, jammed, jamming_facets,
                                             two_point_tilt, wedged, whitney_jammed, whitney_wedged)
from deltafmi.physics.friction.peg_statics import peg_outcome
from deltafmi.physics.friction.system import FrictionModel, FrictionSystem

G = 9.81
FRICTION = FrictionParams(mu_s=0.5, mu_k=0.4)
STEEP, SHALLOW = 0.6, 0.3             # tan = 0.684 > mu_s, tan = 0.309 < mu_k
TIGHT = dict(rtol=1e-12, atol=1e-14)


class WorldIncline(FrictionModel):
    """The same block in world coordinates (x horizontal, y up), the slope descending along +x:
    normal and tangent rows mix both coordinates, so every multiplier couples (an independent
    formulation of :func:`make_incline`)."""

    n_q, n_c = 2, 1

    def __init__(self, theta: float, friction: FrictionParams, mass: float = 1.0) -> None:
        self.mass, self.friction = mass, friction
        self.n = np.array([math.sin(theta), math.cos(theta)])      # outward normal
        self.t = np.array([math.cos(theta), -math.sin(theta)])     # down the slope

    def mass_matrix(self, q):
        return self.mass * np.eye(2)

    def applied_forces(self, t, q, v):
        return np.array([0.0, -self.mass * G])

    def gaps(self, q):
        return np.array([self.n @ q])

    def gap_jacobian(self, q):
        return self.n[None, :]

    def tangent_jacobian(self, q):
        return self.t[None, :]


class SlidingBox(FrictionModel):
    """A rigid box (x, y, phi) on an incline, slope frame, two bottom corners in contact: the
    contacts couple through the rotation (E_i != H_i when slipping; redundant rows when sticking)."""

    n_q, n_c = 3, 2

    def __init__(self, theta: float, friction: FrictionParams, mass=1.0, width=0.4, height=0.2):
        self.mass, self.friction, self.width, self.height = mass, friction, width, height
        self.inertia = mass * (width ** 2 + height ** 2) / 12.0
        self.corners = np.array([[-width / 2, -height / 2], [width / 2, -height / 2]])
        self.gravity = mass * G * np.array([math.sin(theta), -math.cos(theta), 0.0])

    def mass_matrix(self, q):
        return np.diag([self.mass, self.mass, self.inertia])

    def applied_forces(self, t, q, v):
        return self.gravity

    def _arms(self, phi):
        """Rotated corner offsets and their derivatives d/dphi."""
        c, s = math.cos(phi), math.sin(phi)
        return self.corners @ np.array([[c, s], [-s, c]]), self.corners @ np.array([[-s, c], [-c, -s]])

    def gaps(self, q):
        return q[1] + self._arms(q[2])[0][:, 1]

    def gap_jacobian(self, q):
        return np.column_stack([np.zeros(2), np.ones(2), self._arms(q[2])[1][:, 1]])

    def tangent_jacobian(self, q):
        return np.column_stack([np.ones(2), np.zeros(2), self._arms(q[2])[1][:, 0]])


def run(system, x0, t_end=1.0):
    return simulate(system, (0.0, t_end), x0, **TIGHT)


def test_a_block_below_the_friction_angle_sticks_forever_with_the_static_force():
    system, x0 = make_incline(SHALLOW, FRICTION)
    r = run(system, x0)
    assert system.log == [] and set(r.modes[:, 0]) == {STICK}
    assert np.abs(r.x[:, :2]).max() < 1e-15
    lam_n, lam_t = r.forces[-1]
    assert lam_t == pytest.approx(-G * math.sin(SHALLOW), rel=1e-13)
    assert lam_n == pytest.approx(G * math.cos(SHALLOW), rel=1e-13)


@pytest.mark.parametrize("frame", ["surface", "world"])
def test_a_block_above_the_friction_angle_slides_with_the_kinetic_acceleration(frame):
    if frame == "surface":
        system, x0 = make_incline(STEEP, FRICTION)
        along = lambda x: x[0]                                    # noqa: E731
    else:
        model = WorldIncline(STEEP, FRICTION)
        system, x0 = FrictionSystem(model, f_ref=G), np.zeros(4)
        along = lambda x: model.t @ x[:2]                         # noqa: E731
    r = run(system, x0)
    assert [(tr.before, tr.after) for tr in system.log] == [(STICK, SLIP_POSITIVE)]
    exact = np.array([incline_position(t, STEEP, FRICTION) for t in r.t])
    got = np.array([along(x) for x in r.x])
    print(f"\nincline ({frame}): position {np.abs(got - exact).max() / exact[-1]:.1e} of the closed form's")
    assert got[-1] == pytest.approx(exact[-1], rel=1e-10)
    assert np.abs(got - exact).max() < 1e-10 * exact[-1]
    lam_n, lam_t = r.forces[-1]
    assert lam_t == pytest.approx(-FRICTION.mu_k * G * math.cos(STEEP), rel=1e-12)


@pytest.mark.parametrize("theta, then", [(SHALLOW, STICK), (0.45, STICK), (STEEP, SLIP_POSITIVE)])
def test_a_block_launched_up_the_slope_stops_then_sticks_or_slides_down(theta, then):
    # 0.45: tan = 0.483 between mu_k and mu_s: it would keep sliding if it were not for static friction
    v0 = -1.0
    system, x0 = make_incline(theta, FRICTION, v0=v0)
    r = run(system, x0)
    stop = v0 / -(G * (math.sin(theta) + FRICTION.mu_k * math.cos(theta)))
    assert [(tr.before, tr.after) for tr in system.log] == [(SLIP_NEGATIVE, then)]
    assert system.log[0].t == pytest.approx(stop, rel=1e-10)
    exact = np.array([incline_position(t, theta, FRICTION, v0=v0) for t in r.t])
    assert np.abs(r.x[:, 0] - exact).max() < 1e-10 * abs(exact[-1])
    if then == STICK:
        assert r.x[-1][2] == 0.0 and r.forces[-1][1] == pytest.approx(-G * math.sin(theta), rel=1e-12)


@pytest.mark.parametrize("theta", [SHALLOW, STEEP])
def test_a_box_on_two_corners_shares_the_load_by_moment_balance(theta):
    """Moments about the centre of mass, tangential forces at depth h/2 below it:
    N1 + N2 = m g cos th, (w/2) (N2 - N1) + (h/2) (F1 + F2) = 0 with F1 + F2 = -m g sin th
    (sticking: shared equally, the minimum-norm choice of an indeterminate split) or
    -mu_k (N1 + N2) (sliding, at the block's acceleration)."""
    model = SlidingBox(theta, FRICTION)
    system = FrictionSystem(model, f_ref=G)
    r = run(system, np.array([0.0, model.height / 2, 0.0, 0.0, 0.0, 0.0]))
    normal = G * math.cos(theta)
    tangential = -G * math.sin(theta) if theta == SHALLOW else -FRICTION.mu_k * normal
    diff = -model.height / model.width * tangential
    n1, n2, f1, f2 = r.forces[-1]
    np.testing.assert_allclose([n1, n2], [(normal - diff) / 2, (normal + diff) / 2], rtol=1e-12)
    assert f1 + f2 == pytest.approx(tangential, rel=1e-12)
    assert abs(r.x[-1][2]) < 1e-14                        # no tipping
    if theta == SHALLOW:
        assert system.log == [] and f1 == pytest.approx(f2, rel=1e-12)
        assert np.abs(r.x[:, 0]).max() < 1e-15
    else:
        assert {(tr.t, tr.after) for tr in system.log} == {(0.0, SLIP_POSITIVE)} and len(system.log) == 2
        assert r.x[-1][0] == pytest.approx(incline_position(1.0, theta, FRICTION), rel=1e-10)


def test_viscous_friction_approaches_the_terminal_speed():
    friction = FRICTION._replace(c_v=2.0)
    system, x0 = make_incline(STEEP, friction, mass=1.0)
    r = run(system, x0, t_end=2.0)
    exact = np.array([incline_viscous_position(t, STEEP, friction, 1.0) for t in r.t])
    assert np.abs(r.x[:, 0] - exact).max() < 1e-10 * exact[-1]


def test_the_stick_slip_oscillator_settles_on_the_closed_form_limit_cycle():
    m, k, vb = 1.0, 100.0, 0.1
    system, x0 = make_belt_oscillator(FRICTION, mass=m, stiffness=k, belt_speed=vb)
    r = simulate(system, (0.0, 10.0), x0, **TIGHT)
    cycle = stick_slip_cycle(m, k, m * G, vb, FRICTION)
    log = system.log
    assert [tr.after for tr in log] == [STICK, SLIP_NEGATIVE] * (len(log) // 2) + [STICK] * (len(log) % 2)
    sticks = np.array([tr.t for tr in log if tr.after == STICK])
    releases = np.array([tr.t for tr in log if tr.after == SLIP_NEGATIVE])
    assert len(sticks) >= 14
    # after the transient (the first stick lands on the cycle)
    np.testing.assert_allclose(np.diff(sticks[1:]), cycle.period, rtol=1e-8)
    np.testing.assert_allclose(sticks[1:] - releases[:len(sticks) - 1], cycle.slip_duration, rtol=1e-8)
    x_at = {t: x for t, x in zip(r.t, r.x)}               # the sample after each event is the last
    np.testing.assert_allclose([x_at[t][0] for t in releases], cycle.release, rtol=1e-8)
    np.testing.assert_allclose([x_at[t][0] for t in sticks[1:]], cycle.capture, rtol=1e-8)
    # amplitude: while slipping, (x - x_k)^2 + (x'/omega)^2 = R^2 (harmonic about x_k)
    omega = math.sqrt(k / m)
    slipping = (r.modes[:, 0] == SLIP_NEGATIVE) & (r.t > sticks[0])
    radius = np.hypot(r.x[slipping, 0] - cycle.centre, r.x[slipping, 2] / omega)
    print(f"\nstick-slip: period {np.abs(np.diff(sticks[1:]) / cycle.period - 1).max():.1e}, amplitude "
          f"{np.abs(radius / cycle.amplitude - 1).max():.1e}")
    np.testing.assert_allclose(radius, cycle.amplitude, rtol=1e-8)
    assert r.x[r.t > sticks[0], 0].max() <= cycle.centre + cycle.amplitude * (1 + 1e-8)
    assert r.x[r.t > sticks[0], 0].max() > cycle.centre + cycle.amplitude * 0.99


def test_after_a_stop_the_static_cone_decides():
    p = FrictionParams(mu_s=0.5, mu_k=0.4)
    assert after_stop(np.array([4.9]), 10.0, p) is None and after_stop(np.array([-5.0]), 10.0, p) is None
    assert after_stop(np.array([5.01]), 10.0, p) == [-1.0]
    assert after_stop(np.array([-5.01]), 10.0, p) == [1.0]
    assert after_stop(np.array([3.0, 4.0]), 10.0, p) is None                    # |lambda_t| = 5
    slip_axis = after_stop(np.array([3.0, 4.01]), 10.0, p)
    np.testing.assert_allclose(slip_axis, np.array([-3.0, -4.01]) / math.hypot(3.0, 4.01), rtol=1e-15)


def test_the_regularised_law_creeps_and_errs_within_its_bound():
    """tanh(v/v_eps) for comparison. Its force deviation is <= 2 mu_k N exp(-2|v|/v_eps); sliding
    from rest at v >= a t that integrates to a speed error <= mu_k g cos(theta) v_eps / a and a
    position error <= that times t. Below the friction angle it creeps at
    v_eps artanh(tan(theta) / mu_k) where the mode machine holds x = 0 exactly."""
    v_eps, m = 1e-3, 1.0

    def slope(theta):
        def rhs(t, y):
            lam_n = m * G * math.cos(theta)
            return [y[1], G * math.sin(theta) + regularised_force(lam_n, y[1], FRICTION, v_eps) / m]
        return solve_ivp(rhs, (0.0, 1.0), [0.0, 0.0], method="LSODA", rtol=1e-10, atol=1e-13)

    for v in (1e-4, 1e-3, 1e-2):
        exact = slip_force(G, np.array([v]), np.array([1.0]), FRICTION)[0]
        dev = abs(regularised_force(G, v, FRICTION, v_eps) - exact)
        # the bound is tight to (1 + exp(-2 v / v_eps)): allow the round-off of subtracting ~4 N forces
        assert dev <= regularisation_error_bound(G, v, FRICTION, v_eps) + 1e-14 * G
    a = G * (math.sin(STEEP) - FRICTION.mu_k * math.cos(STEEP))
    err = slope(STEEP).y[0, -1] - incline_position(1.0, STEEP, FRICTION)
    bound = FRICTION.mu_k * G * math.cos(STEEP) * v_eps / a * 1.0
    assert 0.0 < err <= bound
    assert err > 0.3 * bound                              # the bound is not loose
    creep = slope(SHALLOW).y[1, -1]
    assert creep == pytest.approx(v_eps * math.atanh(math.tan(SHALLOW) / FRICTION.mu_k), rel=1e-6)


# --- a tangential plane (2-D friction) ------------------------------------------------------
def test_on_a_level_plane_a_block_slides_straight_and_stops_at_the_closed_form_time():
    v0 = np.array([0.6, 0.8])                    # 1 m/s at an angle: both tangent rows carry it
    system, x0 = make_plane_incline(0.0, FRICTION, v0)
    r = run(system, x0)
    stop = 1.0 / (FRICTION.mu_k * G)
    assert [(tr.before, tr.after) for tr in system.log] == [(SLIP_POSITIVE, STICK)]
    print(f"\nlevel plane: stop time {abs(system.log[0].t / stop - 1):.1e}")
    assert system.log[0].t == pytest.approx(stop, rel=1e-11)
    np.testing.assert_allclose(r.x[-1][:2], v0 * stop / 2, rtol=1e-12)
    assert not r.x[-1][3:].any() and not r.forces[-1][1:].any()


@pytest.mark.parametrize("theta, velocity, stops", [
    (SHALLOW, (0.0, 1.0), True),      # n = mu_k / tan = 1.29: curves down the slope and stops
    (SHALLOW, (-1.0, 0.8), True),     # thrown up and across: turns past 90 deg (re-anchored), stops
    (STEEP, (-1.5, 0.8), False),      # n = 0.58: turns and keeps sliding down
])
def test_sliding_across_an_incline_keeps_the_closed_form_invariant(theta, velocity, stops):
    system, x0 = make_plane_incline(theta, FRICTION, velocity)
    r = run(system, x0)
    invariant = plane_path_invariant(*velocity, theta, FRICTION.mu_k)
    # I = |v_y|^(1-n) (v + v_x)^n; the solver's absolute error (atol 1e-14) is relative to v_y,
    # which decays like tan^n(phi/2): checked while |v_y| > 1e-4 m/s
    sliding = (r.modes[:, 0] != STICK) & (np.abs(r.x[:, 4]) > 1e-4)
    got = np.array([plane_path_invariant(x[3], x[4], theta, FRICTION.mu_k) for x in r.x[sliding]])
    np.testing.assert_allclose(got, invariant, rtol=1e-10)
    turned = velocity[0] < 0.0
    reanchors = [ev for ev in r.events if ev.indicator == 0 and ev.modes_before == ev.modes_after]
    assert len(reanchors) == turned
    if stops:
        assert [(tr.before, tr.after) for tr in system.log] == [(SLIP_POSITIVE, STICK)]
        assert system.log[0].t == pytest.approx(plane_stop_time(*velocity, theta, FRICTION.mu_k), rel=1e-10)
        np.testing.assert_allclose(r.forces[-1][1:], [-G * math.sin(theta), 0.0], rtol=1e-12, atol=1e-14)
    else:
        assert system.log == []


# --- peg in hole ------------------------------------------------------------------------
D_PEG, D_HOLE, MU = 0.010, 0.0101, 0.3     # 10 mm peg, 1 % clearance


@pytest.mark.parametrize("side", [1 - 1e-6, 1 + 1e-6])
def test_wedging_happens_exactly_below_l_over_d_equal_mu(side):
    l = MU * D_PEG * side
    expected = side < 1.0
    assert whitney_wedged(l, D_PEG, MU) == expected
    assert wedged(l, D_PEG, D_HOLE, MU) == expected
    # the quasi-static model: a wedged peg holds with no load, so it never slides in
    outcome = peg_outcome((0.0, -1.0, 0.0), l, D_PEG, D_HOLE, MU)
    assert (outcome == "wedged") == expected
    if not expected:
        assert outcome == "jammed"            # just above: the pure push is still inside the huge jam region


def _boundary_points(l, d, D, mu):
    """A point on each facet line of the jamming region at F_z = -1 (a positive combination of
    the facet's two edge wrenches) and the facet normal without its F_z part."""
    G_edges = cone_edge_wrenches(l, d, D, mu)
    for i, j, n in jamming_facets(l, d, D, mu):
        gi, gj = G_edges[i][1], G_edges[j][1]
        if max(gi, gj) <= 0.0:
            continue                              # this facet does not meet F_z = -1
        if gi > 0 and gj > 0:
            a = b = 1.0 / (gi + gj)
        elif gi > 0:
            b, a = 1.0, (1.0 + abs(gj)) / gi
        else:
            a, b = 1.0, (1.0 + abs(gi)) / gj
        contact = a * G_edges[i] + b * G_edges[j]
        assert contact[1] == pytest.approx(1.0)
        yield -contact, np.array([n[0], 0.0, n[2]])


@pytest.mark.parametrize("l", [0.004, 0.02, 0.05])
def test_jamming_boundaries_match_the_quasi_static_model_on_both_sides(l):
    n_lines = 0
    for w, n in _boundary_points(l, D_PEG, D_HOLE, MU):
        step = 1e-6 * np.linalg.norm(w) / np.linalg.norm(n)
        inside, outside = w - step * n, w + step * n     # contact wrench c = -w: n . c grows inside
        assert jammed(inside, l, D_PEG, D_HOLE, MU) and peg_outcome(inside, l, D_PEG, D_HOLE, MU) == "jammed"
        assert not jammed(outside, l, D_PEG, D_HOLE, MU)
        assert peg_outcome(outside, l, D_PEG, D_HOLE, MU) == "moves"
        n_lines += 1
    assert n_lines == 3                                   # Whitney: two rays and a segment


def test_whitney_small_angle_diagram_matches_the_exact_geometry():
    r_peg = D_PEG / 2
    l, hole = 0.02, D_PEG * (1 + 1e-7)
    assert two_point_tilt(l, D_PEG, hole) < 1e-6
    rng = np.random.default_rng(27)
    agree = 0
    for f, m in rng.uniform([-8.0, -20.0], [8.0, 40.0], size=(400, 2)):
        w = (f, -1.0, m * r_peg)
        exact = jammed(w, l, D_PEG, hole, MU)
        assert exact == (peg_outcome(w, l, D_PEG, hole, MU) == "jammed")
        assert exact == whitney_jammed(f, m, l, D_PEG, MU)
        agree += exact
    assert 50 < agree < 350                                   # both outcomes sampled
    # a pure axial push slides in; a moment pressing the peg into its lean jams it
    assert not jammed((0.0, -1.0, 0.0), l, D_PEG, D_HOLE, MU)
    assert jammed((0.0, -1.0, 10 * r_peg), l, D_PEG, D_HOLE, MU)


def test_a_contact_pulled_off_separates_and_the_block_flies_freely():
    from deltafmi.physics.friction.law import SEPARATED
    from deltafmi.physics.friction.planar_block import PlanarBlock

    system = FrictionSystem(PlanarBlock(2.0, (1.0, 3.0), FRICTION), f_ref=2.0 * G)
    r = simulate(system, (0.0, 1.0), np.zeros(4), **TIGHT)
    assert [(tr.before, tr.after) for tr in system.log] == [(STICK, SEPARATED)]
    assert r.x[-1][:2] == pytest.approx([0.25, 0.75], rel=1e-12)   # F t^2 / (2 m)
    assert not r.forces[-1].any()


def test_every_mode_change_is_an_fmi_event_and_is_logged():
    system, x0 = make_belt_oscillator(FRICTION)
    r = simulate(system, (0.0, 2.0), x0, **TIGHT)
    switches = [(ev.t, ev.modes_before[0], ev.modes_after[0]) for ev in r.events
                if ev.modes_before != ev.modes_after and ev.indicator >= 0]
    assert switches == [(tr.t, tr.before, tr.after) for tr in system.log]   # initial modes: not logged
    assert all(ev.indicator == 0 for ev in r.events[1:])        # z1: stop or cone, never release
