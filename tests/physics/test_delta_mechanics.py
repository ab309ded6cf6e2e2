"""Delta robot plant (deltafmi.physics.delta) against physics and independent formulations.

The reference paths live here, not in the library: a dense KKT solve for the DAE, a dense
projection onto the closed loops, body-point kinetic energy for the mass matrix, and a
minimal-coordinate Lagrangian model in the three servo angles (its own forward kinematics,
forearm energy from the rod end points, derivatives by complex step and central differences)
for whole trajectories.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from deltafmi.physics import delta as d
from delta_reference import CASES, MinimalModel, fk_minimal

P = d.RL5
SERVO = [0, 3, 6]
ROT = np.stack(d.ARM_ROTATIONS)  # (3, 3, 3)
B = np.zeros((9, 3))
B[SERVO, [0, 1, 2]] = 1.0


def workspace_grid() -> list[tuple[float, float, float]]:
    pts = []
    for z in (-0.75, -0.9, -1.05, -1.2):
        pts.append((0.0, 0.0, z))
        for r in (0.25, 0.5):
            for k in range(6):
                a = k * math.pi / 3 + 0.3
                pts.append((r * math.cos(a), r * math.sin(a), z))
    return pts


def perturbed_state(rng, z=(0.15, -0.2, -1.0), dq=0.0):
    q = d.inverse_kinematics(P, z) + dq * rng.normal(size=9)
    return q, rng.normal(size=9)


# ------------------------------------------------------------------------------------ kinematics

@pytest.mark.parametrize("z", workspace_grid())
def test_ik_fk_round_trip_and_closure(z):
    q = d.inverse_kinematics(P, z)
    assert np.max(np.abs(d.constraint(P, q))) < 1e-12
    assert np.allclose(d.forward_kinematics(P, q[SERVO]), z, rtol=0, atol=1e-12)
    assert np.allclose(d.wrist_position(P, q), z, rtol=0, atol=1e-12)
    for i, r in enumerate(d.ARM_ROTATIONS):
        assert np.allclose(r @ d.arm_psi(P, q[3 * i:3 * i + 3]), z, rtol=0, atol=1e-12)
    assert np.all((q[[1, 4, 7]] > -math.pi) & (q[[1, 4, 7]] < 0.0))
    assert np.all(np.abs(q[[2, 5, 8]]) < math.pi / 2)
    # elbows out: the elbow lies outside the line from the servo axis to the wrist joint
    for i in range(3):
        q1, q2 = q[3 * i], q[3 * i + 1]
        assert q1 > q2  # forearm polar angle below the upper arm's: knee points outwards


def test_stretched_height_is_where_all_arms_straighten():
    zs = d.stretched_height(P)
    assert zs == pytest.approx(-1.4607, abs=1e-4)
    q = d.inverse_kinematics(P, (0.0, 0.0, zs + 1e-12))
    assert np.allclose(q[[1, 4, 7]], q[SERVO], atol=2e-5)  # upper arm in line with forearm
    assert np.allclose(q[[2, 5, 8]], 0.0, atol=1e-12)


def test_out_of_reach_messages():
    with pytest.raises(ValueError) as err:
        d.inverse_kinematics(P, (0.0, 0.0, -1.5))
    msg = str(err.value)
    assert "-1.5000" in msg and "out of reach" in msg and "arm 1" in msg
    assert "-1.4607 <= z" in msg  # the reachable span on the axis
    with pytest.raises(ValueError) as err:
        d.inverse_kinematics(P, (0.9, 0.0, -1.0))
    msg = str(err.value)
    assert "0.9000" in msg and "r <= " in msg
    rmax = float(msg.split("r <= ")[1].split()[0])
    assert 0.5 < rmax < 0.9
    d.inverse_kinematics(P, (rmax - 1e-3, 0.0, -1.0))  # just inside: reachable
    with pytest.raises(ValueError):
        d.inverse_kinematics(P, (rmax + 1e-3, 0.0, -1.0))


def test_forward_kinematics_picks_platform_below_and_rejects_open_loops():
    z = d.forward_kinematics(P, [-0.3, 0.1, -0.5])
    assert z[2] < -0.5
    q = d.inverse_kinematics(P, z)
    assert np.allclose(q[SERVO], [-0.3, 0.1, -0.5], atol=1e-12)
    with pytest.raises(ValueError, match="cannot close"):
        d.forward_kinematics(d.DeltaParams(l2=0.3), [0.0, 0.0, 0.0])


def test_constraint_jacobian_and_bias_against_finite_differences():
    rng = np.random.default_rng(0)
    q, v = perturbed_state(rng, dq=0.05)  # off the manifold on purpose
    eps = 1e-6
    H_fd = np.column_stack([(d.constraint(P, q + eps * e) - d.constraint(P, q - eps * e))
                            / (2 * eps) for e in np.eye(9)])
    assert np.allclose(d.constraint_jacobian(P, q), H_fd, rtol=0, atol=1e-8)
    Hv = lambda qq: d.constraint_jacobian(P, qq) @ v  # noqa: E731
    bias_fd = (Hv(q + eps * v) - Hv(q - eps * v)) / (2 * eps)
    assert np.allclose(d.constraint_bias(P, q, v), bias_fd, rtol=0, atol=1e-7)


def test_wrist_velocity_is_derivative_of_wrist_position():
    rng = np.random.default_rng(1)
    q, v = perturbed_state(rng, dq=0.05)
    eps = 1e-6
    fd = (d.wrist_position(P, q + eps * v) - d.wrist_position(P, q - eps * v)) / (2 * eps)
    assert np.allclose(d.wrist_velocity(P, q, v), fd, rtol=0, atol=1e-8)
    Jv = d.virtual_jacobian(P, q)
    assert Jv.shape == (3, 9)
    assert np.allclose(Jv[:, 0:3], d.arm_jacobian(P, q[0:3]) / 3)
    assert np.allclose(Jv[:, 3:6], d.R2 @ d.arm_jacobian(P, q[3:6]) / 3)


# ------------------------------------------------------------------------- dynamics, pointwise

def body_kinetic_energy(p, q, v):
    """Kinetic energy from body-point velocities: upper arm, rod from end points, plate thirds."""
    mpa = (p.mp + p.payload) / 3
    T = 0.0
    for i in range(3):
        qi, vi = q[3 * i:3 * i + 3], v[3 * i:3 * i + 3]
        e_dot = p.l1 * vi[0] * np.array([0.0, -math.sin(qi[0]), math.cos(qi[0])])
        end_dot = d.arm_jacobian(p, qi) @ vi
        T += 0.5 * (p.J1 + p.Jm) * vi[0] ** 2
        T += p.m2 / 6 * (e_dot @ e_dot + e_dot @ end_dot + end_dot @ end_dot)
        T += 0.5 * mpa * end_dot @ end_dot
    return T


def test_mass_matrix_spd_and_matches_body_kinetic_energy():
    rng = np.random.default_rng(2)
    p = d.DeltaParams(payload=2.0)
    for _ in range(5):
        q, v = perturbed_state(rng, dq=0.3)
        M = d.mass_matrix(p, q)
        assert np.array_equal(M, M.T)
        assert np.min(np.linalg.eigvalsh(M)) > 0
        assert 0.5 * v @ M @ v == pytest.approx(body_kinetic_energy(p, q, v), rel=1e-13)
        assert np.count_nonzero(M[0:3, 3:9]) == 0 and np.count_nonzero(M[3:6, 6:9]) == 0


def test_coriolis_and_gravity_against_lagrangian_finite_differences():
    rng = np.random.default_rng(3)
    q, v = perturbed_state(rng, dq=0.3)
    eps = 1e-6
    Mdot = (d.mass_matrix(P, q + eps * v) - d.mass_matrix(P, q - eps * v)) / (2 * eps)
    dTdq = np.array([v @ (d.mass_matrix(P, q + eps * e) - d.mass_matrix(P, q - eps * e)) @ v
                     for e in np.eye(9)]) / (4 * eps)
    assert np.allclose(d.coriolis(P, q, v), Mdot @ v - dTdq, rtol=0, atol=1e-7)
    V = lambda qq: d.energy(P, qq, np.zeros(9))  # noqa: E731
    dVdq = np.array([(V(q + eps * e) - V(q - eps * e)) / (2 * eps) for e in np.eye(9)])
    assert np.allclose(d.gravity(P, q), dVdq, rtol=0, atol=1e-7)


def dense_kkt(p, q, v, u, f, pole):
    """Reference: the full 15x15 KKT system of the stabilised index-1 DAE."""
    M, H = d.mass_matrix(p, q), d.constraint_jacobian(p, q)
    rhs = (B @ u + d.virtual_jacobian(p, q).T @ f - d.coriolis(p, q, v) - p.damping * v
           - d.gravity(p, q))
    K = np.block([[M, -H.T], [H, np.zeros((6, 6))]])
    r2 = -(d.constraint_bias(p, q, v) + 2 * pole * H @ v + pole ** 2 * d.constraint(p, q))
    sol = np.linalg.solve(K, np.concatenate([rhs, r2]))
    return sol[:9], sol[9:]


def test_accelerations_match_dense_kkt_solve():
    rng = np.random.default_rng(4)
    p = d.DeltaParams(payload=1.5, damping=0.7)
    for dq in (0.0, 0.02):  # on and off the constraint manifold (Baumgarte terms active)
        q, v = perturbed_state(rng, z=(-0.3, 0.25, -1.1), dq=dq)
        u, f = rng.normal(size=3) * 20, rng.normal(size=3) * 50
        vdot, lam = d.accelerations(p, q, v, u, f, 7.0)
        vdot_ref, lam_ref = dense_kkt(p, q, v, u, f, 7.0)
        assert np.allclose(vdot, vdot_ref, rtol=1e-10, atol=1e-10)
        assert np.allclose(lam, lam_ref, rtol=1e-10, atol=1e-9)


def test_holding_torque_equals_virtual_work_gradient():
    p = d.DeltaParams(payload=3.0)
    for z in [(0.0, 0.0, -1.0), (0.3, -0.25, -0.85), (-0.4, 0.1, -1.15)]:
        q = d.inverse_kinematics(p, z)
        tau, lam = d.holding_torque(p, q)
        y = q[SERVO]
        U = lambda yy: d.energy(p, d.inverse_kinematics(p, d.forward_kinematics(p, yy)),  # noqa
                                np.zeros(9))
        eps = 1e-5
        dUdy = np.array([(U(y + eps * e) - U(y - eps * e)) / (2 * eps) for e in np.eye(3)])
        assert np.allclose(tau, dUdy, rtol=1e-7, atol=1e-7)
        # holding it still: the DAE's accelerations vanish under these torques
        vdot, lam_dyn = d.accelerations(p, q, np.zeros(9), tau, np.zeros(3), 5.0)
        assert np.max(np.abs(vdot)) < 1e-10
        assert np.allclose(lam_dyn, lam, rtol=1e-9, atol=1e-9)


def simulate_dae(p, z0, u, f, t_end, t_eval, pole=5.0, **kw):
    q0 = d.inverse_kinematics(p, z0)

    def rhs(t, x):
        vd, _ = d.accelerations(p, x[:9], x[9:], u, f, pole)
        return np.concatenate([x[9:], vd])

    return solve_ivp(rhs, (0, t_end), np.concatenate([q0, np.zeros(9)]), method="DOP853",
                     rtol=1e-10, atol=1e-12, t_eval=t_eval, **kw)


@pytest.mark.parametrize("case", sorted(CASES))
def test_trajectory_matches_minimal_coordinate_model(case):
    z0, u, f = CASES[case]
    p = d.DeltaParams(payload=1.0)
    t_end = 0.5
    ts = np.linspace(0.0, t_end, 51)
    dae = simulate_dae(p, z0, u, f, t_end, ts)
    assert dae.success
    y0 = d.inverse_kinematics(p, z0)[SERVO]
    assert np.allclose(fk_minimal(p, y0), z0, atol=1e-12)
    mini = solve_ivp(MinimalModel(p, u, f).rhs, (0, t_end), np.concatenate([y0, np.zeros(3)]),
                     method="DOP853", rtol=1e-10, atol=1e-12, t_eval=ts)
    assert mini.success
    Q, V = dae.y[:9].T, dae.y[9:].T
    z_dae = np.array([d.wrist_position(p, q) for q in Q])
    z_min = fk_minimal(p, mini.y[:3].T)
    assert np.max(np.linalg.norm(z_dae - z_min, axis=1)) < 1e-6
    assert np.max(np.abs(Q[:, SERVO] - mini.y[:3].T)) < 1e-6
    assert np.max(z_dae[:, 2]) < -0.6 and np.ptp(z_dae[:, 2]) > 0.05  # it really moved
    h = np.array([np.max(np.abs(d.constraint(p, q))) for q in Q])
    assert np.max(h) < 1e-9
    # energy balance: E(t) - E(0) = u . (y(t) - y(0)) + f . (z(t) - z(0)) (constant loads)
    E = np.array([d.energy(p, q, v) for q, v in zip(Q, V)])
    work = (Q[:, SERVO] - Q[0, SERVO]) @ np.asarray(u) + (z_dae - z_dae[0]) @ np.asarray(f)
    kinetic_scale = np.max([0.5 * v @ d.mass_matrix(p, q) @ v for q, v in zip(Q, V)])
    assert np.max(np.abs(E - E[0] - work)) < 1e-6 * kinetic_scale


def test_damping_dissipates_exactly_d_v_squared():
    p = d.DeltaParams(damping=2.0)
    q0 = d.inverse_kinematics(p, (0.1, 0.2, -0.95))

    def rhs(t, x):
        vd, _ = d.accelerations(p, x[:9], x[9:18], np.zeros(3), np.zeros(3), 5.0)
        return np.concatenate([x[9:18], vd, [p.damping * x[9:18] @ x[9:18]]])

    sol = solve_ivp(rhs, (0, 0.3), np.concatenate([q0, np.zeros(10)]), method="DOP853",
                    rtol=1e-10, atol=1e-12)
    x = sol.y[:, -1]
    e0, e1 = d.energy(p, q0, np.zeros(9)), d.energy(p, x[:9], x[9:18])
    assert x[18] > 1.0  # joules dissipated: a real test
    assert e1 - e0 == pytest.approx(-x[18], rel=1e-7)


def test_passes_through_stretched_arm_singularity():
    """Symmetric free fall: all three arms straighten at once (the workspace floor) and the
    elbows fold through it; the DAE in nine angles does not notice."""
    z0 = (0.0, 0.0, -1.0)

    def straight(t, x):  # q_12 - q_11 crosses zero when arm 1 is stretched
        return x[1] - x[0]

    ts = np.linspace(0.0, 1.0, 201)
    sol = simulate_dae(P, z0, np.zeros(3), np.zeros(3), 1.0, ts, events=straight)
    assert sol.success and np.all(np.isfinite(sol.y))
    assert len(sol.t_events[0]) >= 1
    q_star = sol.y_events[0][0][:9]
    dist = np.linalg.norm(d.wrist_position(P, q_star) - [0.0, 0.0, d.stretched_height(P)])
    assert dist < 1e-6  # within micrometres of the all-stretched pose
    Q, V = sol.y[:9].T, sol.y[9:].T
    assert np.max([np.max(np.abs(d.constraint(P, q))) for q in Q]) < 1e-9
    E = np.array([d.energy(P, q, v) for q, v in zip(Q, V)])
    kinetic_scale = np.max([0.5 * v @ d.mass_matrix(P, q) @ v for q, v in zip(Q, V)])
    assert np.ptp(E) < 1e-6 * kinetic_scale
    rel = Q[:, 1] - Q[:, 0]
    assert rel.min() < -0.1 and rel.max() > 0.1  # elbow really folded through straight


def test_evaluate_plant_agrees_with_the_separate_functions():
    rng = np.random.default_rng(5)
    p = d.DeltaParams(payload=0.5, damping=0.3)
    q, v = perturbed_state(rng, dq=0.01)
    u, f = rng.normal(size=3), rng.normal(size=3)
    ev = d.evaluate_plant(p, q, v, u, f, 4.0)
    vdot, lam = d.accelerations(p, q, v, u, f, 4.0)
    assert np.array_equal(ev.vdot, vdot) and np.array_equal(ev.lam, lam)
    assert np.allclose(ev.z, d.wrist_position(p, q), rtol=0, atol=1e-15)
    assert np.allclose(ev.zd, d.wrist_velocity(p, q, v), rtol=0, atol=1e-14)
    assert ev.residual == pytest.approx(np.linalg.norm(d.constraint(p, q)), rel=1e-12)
    assert ev.residual > 1e-4  # off the manifold: a real comparison
    assert ev.energy == pytest.approx(d.energy(p, q, v), rel=1e-13)


# ------------------------------------------------------------- projection onto the closed loops

def dense_projection(p, q, v):
    """Reference: Gauss-Newton dq = -M^-1 H^T (H M^-1 H^T)^-1 h with dense numpy, the velocity
    corrected by the same operator with H v at both ends of each step."""
    q, v = np.array(q, dtype=float), np.array(v, dtype=float)
    for _ in range(8):  # the library's defaults: 8 steps at most, tol 1e-13 m
        H = d.constraint_jacobian(p, q)
        A = np.linalg.solve(d.mass_matrix(p, q), H.T)
        S = H @ A
        q = q - A @ np.linalg.solve(S, d.constraint(p, q))
        v = v - A @ np.linalg.solve(S, H @ v)
        if np.linalg.norm(d.constraint(p, q)) <= 1e-13:
            break
    return q, v - A @ np.linalg.solve(S, d.constraint_jacobian(p, q) @ v)


@pytest.mark.parametrize("dq", [1e-9, 1e-5, 1e-2])
@pytest.mark.parametrize("p, z", [(P, (0.15, -0.2, -1.0)),
                                  (d.DeltaParams(payload=1.5), (-0.3, 0.25, -1.1))])
def test_projection_closes_loops_with_the_mass_weighted_correction(p, z, dq):
    rng = np.random.default_rng(6)
    q0 = d.inverse_kinematics(p, z) + dq * rng.normal(size=9)
    v0 = rng.normal(size=9)  # far off the tangent space
    assert d.loop_residual(p, q0) == pytest.approx(np.linalg.norm(d.constraint(p, q0)), rel=1e-9, abs=1e-15)
    q, v = d.project_to_constraints(p, q0, v0)
    assert np.max(np.abs(d.constraint(p, q))) < 1e-13
    assert d.loop_residual(p, q) < 1e-13
    assert np.max(np.abs(d.constraint_jacobian(p, q) @ v)) < 1e-11
    q_ref, v_ref = dense_projection(p, q0, v0)
    assert np.max(np.abs(q - q_ref)) < 1e-12
    assert np.max(np.abs(v - v_ref)) < 1e-12


def test_the_mpc_press_holding_torques_with_and_without_its_payload():
    # scenarios/mpc_press.yaml's figures: the servo torque holding the robot at the touching height
    # (wrist at z = -1.05 m), without and with the scenario's 0.5 kg payload, as the virtual-work
    # gradient of the potential energy (torque per servo; the three equal on the axis)
    for payload, expected in ((0.0, 18.27), (0.5, 19.09)):
        p = d.DeltaParams(payload=payload)
        y = d.inverse_kinematics(p, (0.0, 0.0, -1.05))[SERVO]
        U = lambda yy: d.energy(p, d.inverse_kinematics(p, d.forward_kinematics(p, yy)), np.zeros(9))  # noqa
        eps = 1e-5
        dUdy = np.array([(U(y + eps * e) - U(y - eps * e)) / (2 * eps) for e in np.eye(3)])
        print(f"payload {payload} kg: holding torque {dUdy[0]:.3f} N m per servo")
        assert np.allclose(dUdy, expected, atol=0.005)
