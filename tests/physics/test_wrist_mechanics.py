"""The spherical wrist (deltafmi.physics.wrist) against closed forms and second formulations.

Integration: DOP853 at rtol 1e-11 (atol 1e-13 on angles and rates of order 1..20); its global
error over the runs below (at most 400 radians of travel) stays below about 1e-9 relative, so
conserved quantities are asserted to 1e-9 and closed-form trajectories to 1e-8 (rates) unless a
test says otherwise. Finite differences are central with h = 1e-6: truncation h^2 |f'''| / 6
~ 1e-13 and rounding eps |f| / h ~ 1e-10 relative, asserted to 1e-8 relative.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import ellipj, ellipk

from deltafmi.physics import wrist as w
from deltafmi.physics.wrist import Body, Tool, WristParams

P = w.WRIST
RTOL, ATOL = 1e-11, 1e-13
FD = 1e-6
MAX_EVALUATIONS = 100_000
MASSLESS = Body(0.0, (0.0, 0.0, 0.0), (0.0,) * 6)


def _simulate(p: WristParams, q0, qd0, t_end: float, extra=None, n_extra: int = 0, **kw):
    """Integrate the torque-free wrist (plus optional integrals extra(q, qd) of size n_extra).

    A wrong model can make the solver crawl; the runs here take at most ~10^4 evaluations, so
    beyond MAX_EVALUATIONS the run fails instead of hanging."""
    calls = iter(range(MAX_EVALUATIONS))

    def rhs(t, x):
        if next(calls, None) is None:
            raise RuntimeError(f"more than {MAX_EVALUATIONS} evaluations")
        q, qd = x[:3], x[3:6]
        out = [qd, w.accelerations(p, q, qd, np.zeros(3))]
        if extra is not None:
            out.append(extra(q, qd))
        return np.concatenate(out)
    x0 = np.concatenate([q0, qd0, np.zeros(n_extra)])
    sol = solve_ivp(rhs, (0.0, t_end), x0, method="DOP853", rtol=RTOL, atol=ATOL, dense_output=True, **kw)
    assert sol.success, sol.message
    return sol


def _free_tool(tool: Tool, eps: float) -> WristParams:
    """Massless gimbals with rotor inertias eps: the tool is a free rigid body about O (the links
    transmit no torque unless the axes are coplanar) up to the gimbals' torque eps qdd, relative
    eps qdd / (I_tool omega^2). Near gimbal lock qdd grows like 1/cos^2 q2 (a first set-up passing
    0.02 rad from it drove the joints to 700 rad/s and the error to 5e-7 at eps = 1e-14), so the
    runs below keep the gimbal angle above 0.6 rad."""
    return WristParams(links=(MASSLESS,) * 3, rotors=(eps,) * 3, tool=tool, g=0.0)


def _body_rates(p: WristParams, q, qd) -> np.ndarray:
    """Tool angular velocity in the tool frame, R_tool^T J_w qd."""
    return w.tool_rotation(q).T @ w.angular_jacobian(q) @ qd


# ------------------------------------------------------------------------ 1. free spin

def test_free_spin_about_the_vertical_axis_under_gravity():
    """q2 = q3 = 0: every body is symmetric enough (principal axes on the link axes, centres of mass
    on z) that joint 1 spins alone at constant rate; T = 1/2 I_zz w^2 with I_zz summed by hand."""
    omega = 12.0
    sol = _simulate(P, np.zeros(3), np.array([omega, 0.0, 0.0]), 2.0)
    t = np.linspace(0.0, 2.0, 41)
    x = sol.sol(t)
    assert np.max(np.abs(x[0] - omega * t)) < 1e-8 * omega * 2.0
    assert np.max(np.abs(x[[1, 2, 4, 5]])) == 0.0  # exactly invariant: the forces are exactly zero
    izz = sum(b.inertia[2] + b.mass * (b.com[0] ** 2 + b.com[1] ** 2) for b in P.links) + P.rotors[0] \
        + P.tool.inertia[2]
    energies = [w.energy(P, x[:3, k], x[3:, k]) for k in range(t.size)]
    expected = 0.5 * izz * omega ** 2 + w.potential_energy(P, np.zeros(3))
    assert np.max(np.abs(np.array(energies) - expected)) < 1e-12 * expected


def test_free_spin_of_the_last_joint_in_zero_gravity():
    omega = -7.0
    p = dataclasses.replace(P, g=0.0)
    sol = _simulate(p, np.zeros(3), np.array([0.0, 0.0, omega]), 2.0)
    x = sol.y[:, -1]
    assert abs(x[2] - omega * 2.0) < 1e-8 * abs(omega) * 2.0 and abs(x[5] - omega) < 1e-10 * abs(omega)
    assert np.max(np.abs(sol.y[[0, 1, 3, 4]])) == 0.0
    link3, t = P.links[2], P.tool
    iyy = link3.inertia[1] + link3.mass * link3.com[2] ** 2 + P.rotors[2] + t.inertia[1] + t.mass * t.com ** 2
    assert w.kinetic_energy(p, x[:3], x[3:]) == pytest.approx(0.5 * iyy * omega ** 2, rel=1e-12)


# ------------------------------------------------------------------------ 2. torque-free precession

def _euler_closed_form(I, w0, t):
    """Body rates of a free rigid body with principal inertias I = (Ia, Ib, Ic), Ia < Ib < Ic,
    axes (a, b, c) right-handed, from w0 = (wa, 0, wc) with wa, wc > 0 (Landau & Lifshitz,
    Mechanics, sec. 37): cn, sn, dn of tau = t sqrt(...), parameter m; the roles of a and c swap
    when L^2 < 2 E Ib (rotation about the axis of least inertia)."""
    Ia, Ib, Ic = I
    e2 = Ia * w0[0] ** 2 + Ic * w0[2] ** 2
    l2 = Ia ** 2 * w0[0] ** 2 + Ic ** 2 * w0[2] ** 2
    swap = l2 < e2 * Ib
    if swap:
        Ia, Ic = Ic, Ia
    A = math.sqrt((e2 * Ic - l2) / (Ia * (Ic - Ia)))
    B = math.sqrt((e2 * Ic - l2) / (Ib * (Ic - Ib)))
    Cc = math.sqrt((l2 - e2 * Ia) / (Ic * (Ic - Ia)))
    rate = math.sqrt((Ic - Ib) * (l2 - e2 * Ia) / (Ia * Ib * Ic))
    m = (Ib - Ia) * (e2 * Ic - l2) / ((Ic - Ib) * (l2 - e2 * Ia))
    sn, cn, dn, _ = ellipj(rate * t, m)
    return np.array([Cc * dn, B * sn, A * cn] if swap else [A * cn, B * sn, Cc * dn])


def _initial_rates(q0, body_omega):
    return np.linalg.solve(w.angular_jacobian(q0), w.tool_rotation(q0) @ body_omega)


def _pose_with_momentum_along(tool_inertia_at_O: np.ndarray, body_omega: np.ndarray, target) -> np.ndarray:
    """Joint angles that turn the body-frame angular momentum I omega onto the world direction
    target (the rotation of least angle, Rodrigues), so the motion's cone is placed at will."""
    l_b = tool_inertia_at_O @ body_omega
    l_b = l_b / np.linalg.norm(l_b)
    v, c = np.cross(l_b, target), float(l_b @ target)
    K = w.kinematics.skew(v)
    return w.inverse_kinematics(np.eye(3) + K + K @ K / (1.0 + c))


@pytest.mark.parametrize("w0, target", [((15.0, 1.5), (0.0, 0.0, -1.0)), ((3.0, 12.0), (1.0, 0.0, 0.0))],
                         ids=["about-least-axis", "about-greatest-axis"])
def test_torque_free_precession_of_an_asymmetric_tool_matches_jacobi_elliptic_functions(w0, target):
    """Tool principal inertias about O: Izz < Ixx + m c^2 < Iyy + m c^2, i.e. (a, b, c) = (z, x, y)
    (a right-handed order). L is placed so that link 3's y axis stays far from the vertical (gimbal
    lock): along the vertical when the tool spins about its axis z, horizontal when about y. The
    gimbals' rotor inertia 1e-16 kg m^2 against the tool's >= 6e-5 perturbs the free-body motion
    by ~1e-12 relative away from gimbal lock (the transmitted torque is eps qdd)."""
    tool = Tool(0.25, 0.02, 0.1, (2.0e-4, 3.0e-4, 6.0e-5, 0.0, 0.0, 0.0))
    p = _free_tool(tool, 1e-16)
    mc2 = tool.mass * tool.com ** 2
    I = (tool.inertia[2], tool.inertia[0] + mc2, tool.inertia[1] + mc2)
    wz, wy = w0
    body0 = np.array([0.0, wy, wz])
    q0 = _pose_with_momentum_along(np.diag([I[1], I[2], I[0]]), body0, np.array(target))
    sol = _simulate(p, q0, _initial_rates(q0, body0), 2.0)
    t = np.linspace(0.0, 2.0, 201)
    x = sol.sol(t)
    body = np.array([_body_rates(p, x[:3, k], x[3:, k]) for k in range(t.size)]).T  # (x, y, z)
    expected = _euler_closed_form(I, (wz, 0.0, wy), t)  # (a, b, c) = (z, x, y)
    scale = math.hypot(wz, wy)
    assert np.max(np.abs(body[[2, 0, 1]] - expected)) < 1e-8 * scale
    assert np.ptp(body[0]) > 0.2 * scale  # the middle axis' rate really swings
    assert min(w.gimbal_distance(x[:3, k]).angle for k in range(t.size)) > 0.8  # far from gimbal lock
    E = [w.energy(p, x[:3, k], x[3:, k]) for k in range(t.size)]
    L = np.array([w.angular_momentum(p, x[:3, k], x[3:, k]) for k in range(t.size)])
    print(f"\nJacobi elliptic: angular velocity {np.max(np.abs(body[[2, 0, 1]] - expected)) / scale:.1e}, energy "
          f"{np.ptp(E) / E[0]:.1e}, world angular momentum {np.max(np.linalg.norm(L - L[0], axis=1)) / np.linalg.norm(L[0]):.1e}")
    assert np.ptp(E) < 1e-9 * E[0]
    assert np.max(np.linalg.norm(L - L[0], axis=1)) < 1e-9 * np.linalg.norm(L[0])


def test_symmetric_top_precesses_at_the_closed_form_rates():
    """Ixx = Iyy: omega_z is constant, (omega_x, omega_y) turns at (I3 - I1) omega_z / I1 in the
    body, and the tool axis turns about L at |L| / I1 in the world (I1 = Ixx + m c^2, I3 = Izz)."""
    tool = Tool(0.25, 0.03, 0.1, (2.0e-4, 2.0e-4, 5.0e-5, 0.0, 0.0, 0.0))
    p = _free_tool(tool, 1e-16)
    I1, I3 = tool.inertia[0] + tool.mass * tool.com ** 2, tool.inertia[2]
    w_body0 = np.array([2.0, -1.0, 20.0])
    q0 = _pose_with_momentum_along(np.diag([I1, I1, I3]), w_body0, np.array([0.0, 0.0, -1.0]))
    sol = _simulate(p, q0, _initial_rates(q0, w_body0), 1.5)
    t = np.linspace(0.0, 1.5, 151)
    x = sol.sol(t)
    L = w.angular_momentum(p, q0, x[3:, 0])
    body_rate, world_rate = (I3 - I1) * w_body0[2] / I1, np.linalg.norm(L) / I1
    axis0, n = w.tool_rotation(q0)[:, 2], L / np.linalg.norm(L)
    for k in range(t.size):
        wb = _body_rates(p, x[:3, k], x[3:, k])
        c, s = math.cos(body_rate * t[k]), math.sin(body_rate * t[k])
        assert np.allclose(wb, [c * 2.0 + s * 1.0, s * 2.0 - c * 1.0, 20.0], rtol=0.0, atol=1e-8 * 20.0)
        c, s = math.cos(world_rate * t[k]), math.sin(world_rate * t[k])
        axis = axis0 * c + np.cross(n, axis0) * s + n * (n @ axis0) * (1.0 - c)  # Rodrigues
        assert np.allclose(w.tool_rotation(x[:3, k])[:, 2], axis, rtol=0.0, atol=1e-8)
        assert w.gimbal_distance(x[:3, k]).angle > 0.6


def test_a_run_through_gimbal_lock_conserves_energy_and_balances_momentum():
    """Default wrist with rotors, under gravity, thrown through |q2| = pi/2. M stays regular, so the
    run crosses the singularity; T + V and L . a_1 (q1 is cyclic, gravity has no moment about the
    vertical) are conserved, and the world momenta change exactly by the base's wrench:
    dL/dt = -torque_base + s x g, dP/dt = -force_base + m g with P = sum_i omega_i x s_i."""
    g_vec = np.array([0.0, 0.0, -P.g])
    m = sum(b.mass for b in P.links) + P.tool.mass

    def impulses(q, qd):
        qdd = w.accelerations(P, q, qd, np.zeros(3))
        force, torque = w.base_wrench(P, q, qd, qdd)
        s = w.wrist_state(P, q, qd).moments.sum(axis=0)
        return np.concatenate([-torque + np.cross(s, g_vec), -force + m * g_vec])

    def momenta(q, qd):
        st = w.wrist_state(P, q, qd)
        return w.angular_momentum(P, q, qd), np.cross(st.omegas, st.moments).sum(axis=0)

    q0, qd0 = np.array([0.2, 1.2, -0.4]), np.array([2.0, 15.0, -1.5])
    sol = _simulate(P, q0, qd0, 0.6, extra=impulses, n_extra=6)
    t = np.linspace(0.0, 0.6, 301)
    x = sol.sol(t)
    dets = np.cos(x[1])
    assert dets.min() < 0.0 < dets.max()  # q2 crossed pi/2
    E = np.array([w.energy(P, x[:3, k], x[3:6, k]) for k in range(t.size)])
    T0 = w.kinetic_energy(P, q0, qd0)
    print(f"\nthrough gimbal lock: energy {np.max(np.abs(E - E[0])) / T0:.1e} of the kinetic energy")
    assert np.max(np.abs(E - E[0])) < 1e-9 * T0
    L0, P0 = momenta(q0, qd0)
    for k in range(t.size):
        L, Pk = momenta(x[:3, k], x[3:6, k])
        assert abs(L[2] - L0[2]) < 1e-9 * np.linalg.norm(L0)
        assert np.allclose(L - L0, x[6:9, k], rtol=0.0, atol=1e-9 * np.linalg.norm(L0))
        assert np.allclose(Pk - P0, x[9:12, k], rtol=0.0, atol=1e-9 * m * P.g)
    L_end, _ = momenta(x[:3, -1], x[3:6, -1])
    assert np.linalg.norm(L_end - L0) > 0.1 * np.linalg.norm(L0)  # the bearing torque is real


# ------------------------------------------------------------------------ 3. gravity

def _pendulum(joint: int):
    """Inertia about the swinging axis (x for joint 2, y for joint 3) and m g d, summed by hand."""
    t = P.tool
    bodies = P.links[joint - 1:]
    col = {2: 0, 3: 1}[joint]
    inertia = sum(b.inertia[col] + b.mass * (b.com[2] ** 2 + b.com[1 - col] ** 2) for b in bodies) \
        + P.rotors[joint - 1] + t.inertia[col] + t.mass * t.com ** 2
    mgd = P.g * (t.mass * t.com - sum(b.mass * b.com[2] for b in bodies))
    return inertia, mgd


@pytest.mark.parametrize("joint", [2, 3])
@pytest.mark.parametrize("amplitude", [1e-3, 0.4])
def test_hanging_tool_swings_with_the_pendulum_period(joint, amplitude):
    """The hanging tool is a physical pendulum about a fixed axis: omega0^2 = m g d / I, and
    exactly (any amplitude theta0) the period 4 K(sin^2(theta0 / 2)) / omega0."""
    inertia, mgd = _pendulum(joint)
    omega0 = math.sqrt(mgd / inertia)
    q0 = np.zeros(3)
    q0[joint - 1] = amplitude

    def upward(t, x):
        return x[joint - 1]
    upward.direction = 1.0
    period = 4.0 * ellipk(math.sin(0.5 * amplitude) ** 2) / omega0
    sol = _simulate(P, q0, np.zeros(3), 3.2 * period, events=upward)
    crossings = sol.t_events[0]
    assert crossings.size == 3
    print(f"\npendulum (joint {joint}, {amplitude} rad): period {np.abs(np.diff(crossings) / period - 1).max():.1e}")
    assert np.diff(crossings) == pytest.approx([period, period], rel=1e-9)
    if amplitude < 0.01:  # the small-oscillation frequency itself, amplitude correction theta0^2/16
        assert 2.0 * math.pi / np.diff(crossings).mean() == pytest.approx(omega0, rel=amplitude ** 2 / 16 + 1e-9)
    others = [k for k in range(6) if k not in (joint - 1, joint + 2)]
    assert np.max(np.abs(sol.y[others])) < 1e-12


# ------------------------------------------------------------------------ 4. structure and Jacobians

ANGLES = np.random.default_rng(27).uniform(-math.pi, math.pi, (12, 3))
SINGULAR = [np.array([0.4, math.pi / 2, -1.1]), np.array([-2.0, -math.pi / 2, 0.3])]
POSES = list(ANGLES) + SINGULAR


@pytest.mark.parametrize("q", POSES)
def test_mass_matrix_is_symmetric_positive_definite_everywhere(q):
    M = w.mass_matrix(P, q)
    assert np.array_equal(M, M.T)
    assert np.linalg.eigvalsh(M).min() > min(P.rotors) * 0.5  # rotors bound it away from zero


def test_at_gimbal_lock_the_rotor_inertias_are_what_keeps_M_invertible():
    """Massless links: at |q2| = pi/2 the tool alone gives a rank-2 M; M's smallest eigenvalue
    is then of the order of the rotors' inertia (scales with it), and away from it the tool's."""
    for eps in (1e-6, 1e-8):
        p = _free_tool(P.tool, eps)
        lam_sing = np.linalg.eigvalsh(w.mass_matrix(p, SINGULAR[0])).min()
        assert 0.1 * eps < lam_sing < 3.0 * eps
        assert np.linalg.eigvalsh(w.mass_matrix(p, ANGLES[0])).min() > 1e-6


@pytest.mark.parametrize("q", POSES)
def test_christoffel_coriolis_is_skew_consistent_and_agrees_with_euler_law(q):
    qd = np.array([1.5, -2.0, 3.0])
    C = w.coriolis_matrix(P, q, qd)
    Mdot = (w.mass_matrix(P, q + FD * qd) - w.mass_matrix(P, q - FD * qd)) / (2 * FD)
    S = Mdot - 2.0 * C
    scale = np.abs(Mdot).max()
    assert np.abs(S + S.T).max() < 1e-8 * scale
    assert np.allclose(C @ qd, w.coriolis(P, q, qd), rtol=0.0, atol=1e-14 * scale * 10)
    dM = w.mass_matrix_derivatives(P, q)
    fd = np.array([(w.mass_matrix(P, q + FD * e) - w.mass_matrix(P, q - FD * e)) / (2 * FD) for e in np.eye(3)])
    assert np.abs(dM - fd).max() < 1e-8 * np.abs(w.mass_matrix(P, q)).max()


@pytest.mark.parametrize("q", POSES)
def test_gravity_is_the_gradient_of_the_potential(q):
    fd = [(w.potential_energy(P, q + FD * e) - w.potential_energy(P, q - FD * e)) / (2 * FD) for e in np.eye(3)]
    assert np.allclose(w.gravity(P, q), fd, rtol=0.0, atol=1e-8 * P.g * P.tool.mass * P.tool.com)


@pytest.mark.parametrize("q", POSES)
def test_jacobians_match_finite_differences_of_the_kinematics(q):
    qd = np.array([0.7, -1.3, 2.1])
    R = w.tool_rotation(q)
    Rdot = (w.tool_rotation(q + FD * qd) - w.tool_rotation(q - FD * qd)) / (2 * FD)
    W = Rdot @ R.T
    assert np.abs(W + W.T).max() < 1e-8
    assert np.allclose([W[2, 1], W[0, 2], W[1, 0]], w.angular_jacobian(q) @ qd, rtol=0.0, atol=1e-8)
    tip_dot = (w.tool_tip(P, q + FD * qd) - w.tool_tip(P, q - FD * qd)) / (2 * FD)
    assert np.allclose(w.tip_jacobian(P, q) @ qd, tip_dot, rtol=0.0, atol=1e-8 * P.tool.tip)
    assert np.linalg.norm(w.tool_tip(P, q)) == pytest.approx(P.tool.tip, rel=1e-15)


def test_tool_points_down_at_home_and_inverse_kinematics_round_trips():
    assert np.allclose(w.tool_tip(P, np.zeros(3)), [0.0, 0.0, -P.tool.tip], rtol=0.0, atol=1e-16)
    for q in ANGLES:
        q = q.copy()
        q[1] = math.remainder(q[1], math.pi) * 0.99  # the |q2| < pi/2 branch
        q_back = w.inverse_kinematics(w.tool_rotation(q))
        assert np.allclose(np.remainder(q_back - q + math.pi, 2 * math.pi) - math.pi, 0.0, atol=1e-12)
    for q in SINGULAR:  # q1 and q3 not separable: the orientation is still met
        assert np.allclose(w.tool_rotation(w.inverse_kinematics(w.tool_rotation(q))), w.tool_rotation(q), atol=1e-12)


@pytest.mark.parametrize("q", POSES)
def test_gimbal_distance_matches_the_singular_values_of_the_angular_jacobian(q):
    d = w.gimbal_distance(q)
    J = w.angular_jacobian(q)
    assert d.sigma_min == pytest.approx(np.linalg.svd(J, compute_uv=False).min(), abs=1e-7)
    assert d.det == pytest.approx(np.linalg.det(J), abs=1e-12)
    a1, a3 = J[:, 0], J[:, 2]
    assert d.angle == pytest.approx(math.acos(min(1.0, abs(a1 @ a3))), abs=1e-7)


def test_damped_joint_rates_are_exact_away_and_bounded_at_gimbal_lock():
    omega = np.array([0.3, -1.0, 2.0])
    q = np.array([0.2, 0.5, -0.3])
    assert np.allclose(w.angular_jacobian(q) @ w.joint_rates(q, omega), omega, atol=1e-14)
    sigma0 = 0.2
    for q2 in np.linspace(math.pi / 2 - 0.05, math.pi / 2, 6):
        qd = w.joint_rates(np.array([0.1, q2, 0.4]), omega, sigma0)
        assert np.linalg.norm(qd) <= np.linalg.norm(omega) / sigma0 * (1 + 1e-12)


def test_plate_load_agrees_with_the_base_wrench_for_any_plate_acceleration():
    """Two routes: (1) qdd from the dynamics with the base accelerating at a, then Newton's law of
    the whole wrist (base_wrench); (2) the eliminated form -Lambda a + f0 of plate_load."""
    rng = np.random.default_rng(5)
    p = dataclasses.replace(P, damping=0.01)
    for q in POSES:
        qd, tau, a = rng.normal(size=3) * 3, rng.normal(size=3) * 0.1, rng.normal(size=3) * 5
        qdd = w.accelerations(p, q, qd, tau, base_accel=a)
        force, _ = w.base_wrench(p, q, qd, qdd, base_accel=a)
        load = w.plate_load(p, q, qd, tau)
        assert np.allclose(force, -load.apparent_mass @ a + load.force, rtol=0.0, atol=1e-12 * 5 * 10)
        eig = np.linalg.eigvalsh(load.apparent_mass)
        assert 0.0 < eig.min() and eig.max() <= sum(b.mass for b in P.links) + P.tool.mass + 1e-12


def test_wrist_on_a_free_falling_base_conserves_energy_and_momentum():
    """The coupling of the 6-DOF plan in miniature: a base of mass mb that only translates (as the
    plate) carries the wrist, mb a = mb g + (-Lambda a + f0), qdd from the wrist dynamics with
    base_accel = a. Closed forms: P = (mb + m) zd + J_s qd follows P(0) + (mb + m) g t (free fall)
    and E = (mb + m)(|zd|^2 / 2 + g z_z) + zd . J_s qd + T + V is constant."""
    mb, m = 3.0, sum(b.mass for b in P.links) + P.tool.mass
    g_vec = np.array([0.0, 0.0, -P.g])

    def rhs(t, x):
        q, qd, zd = x[:3], x[3:6], x[9:12]
        load = w.plate_load(P, q, qd, np.zeros(3))
        a = np.linalg.solve(mb * np.eye(3) + load.apparent_mass, mb * g_vec + load.force)
        return np.concatenate([qd, w.accelerations(P, q, qd, np.zeros(3), base_accel=a), zd, a])

    def invariants(x):
        q, qd, z, zd = x[:3], x[3:6], x[6:9], x[9:12]
        momentum = (mb + m) * zd + w.first_moment_jacobian(P, q) @ qd
        energy = ((mb + m) * (0.5 * zd @ zd + P.g * z[2]) + zd @ w.first_moment_jacobian(P, q) @ qd
                  + w.energy(P, q, qd))
        return momentum, energy

    x0 = np.concatenate([[0.3, 0.8, -0.5], [4.0, -6.0, 9.0], [0.0, 0.0, 0.0], [0.2, -0.1, 0.5]])
    sol = solve_ivp(rhs, (0.0, 1.0), x0, method="DOP853", rtol=RTOL, atol=ATOL, dense_output=True)
    assert sol.success
    P0, E0 = invariants(x0)
    T0 = 0.5 * (mb + m) * x0[9:] @ x0[9:] + w.kinetic_energy(P, x0[:3], x0[3:6])
    swing = 0.0
    for t in np.linspace(0.0, 1.0, 101):
        momentum, energy = invariants(sol.sol(t))
        assert np.allclose(momentum, P0 + (mb + m) * g_vec * t, rtol=0.0, atol=1e-9 * (mb + m) * P.g)
        assert abs(energy - E0) < 1e-9 * (T0 + (mb + m) * P.g)
        swing = max(swing, np.linalg.norm(momentum - (mb + m) * sol.sol(t)[9:]))
    assert swing > 0.01  # the wrist's own momentum J_s qd is not negligible


def test_the_wrists_cross_product_is_numpys_bit_for_bit():
    """dynamics._cross (np.cross without its axis handling) gives np.cross's bits: single
    vectors, rows, one side broadcast against rows, across magnitudes, signed zeros and
    cancellations, so the wrist's results are those of np.cross."""
    from deltafmi.physics.wrist.dynamics import _cross

    rng = np.random.default_rng(3)
    scale = 10.0 ** rng.integers(-20, 20, (500, 3))
    a, b = rng.standard_normal((500, 3)) * scale, rng.standard_normal((500, 3)) * scale[::-1]
    b[::7] = a[::7] * 3.0  # parallel: every component a cancellation
    a[::11, 1] = -0.0
    for x, y in ((a, b), (a[0], b[0]), (a, b[0]), (a[0], b), (a.reshape(5, 100, 3), b.reshape(5, 100, 3))):
        assert _cross(x, y).tobytes() == np.cross(x, y).tobytes()
