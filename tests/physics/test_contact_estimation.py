"""The contact estimator's mechanics (deltafmi.physics.estimation): its Jacobians against finite
differences, its Kalman algebra against closed forms, and the filter against a closed-loop robot
simulated independently (solve_ivp, DOP853, rtol 1e-11) with a known wrist force or a spring table."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from deltafmi.physics import delta as d
from deltafmi.physics.estimation import (ContactEKF, ContactEKFSettings, joseph_update, process_jacobian,
                                           propagate, tangent_basis, transition_matrix, wrist_jacobians)

P = d.RL5
T = 1e-3
SERVOS = [0, 3, 6]


def on_manifold(z, zd):
    q = d.inverse_kinematics(P, z)
    return q, d.joint_rates(P, q, zd)


def test_wrist_velocity_derivative_is_the_jacobian_rate():
    """D = d(Jv v)/dq against central differences of wrist_velocity (step 1e-6: truncation
    ~ h^2 |psi'''| |v| ~ 1e-12, rounding ~ eps |Jv v| / h ~ 1e-10)."""
    q, v = on_manifold([0.1, -0.05, -1.0], [0.3, 0.2, -0.5])
    Jv, D = wrist_jacobians(P, q, v)
    h = 1e-6
    fd = np.column_stack([(d.wrist_velocity(P, q + h * e, v) - d.wrist_velocity(P, q - h * e, v)) / (2 * h)
                          for e in np.eye(9)])
    np.testing.assert_allclose(D, fd, atol=1e-8)
    np.testing.assert_allclose(Jv, d.virtual_jacobian(P, q), atol=1e-15)


def test_tangent_basis_moves_the_wrist_with_the_loops_closed():
    """dq/dz: Jv dq/dz = I (the wrist moves by dz) and H dq/dz = 0 (the loops stay closed)."""
    q, _ = on_manifold([0.2, 0.1, -1.1], [0.0, 0.0, 0.0])
    Tz = tangent_basis(P, q)
    np.testing.assert_allclose(d.virtual_jacobian(P, q) @ Tz, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(d.constraint_jacobian(P, q) @ Tz, 0.0, atol=1e-12)


def test_transition_matrix_is_the_sampled_dae_derivative():
    """Phi = exp(A T) from the exact DAE Jacobian against central differences of one sample of
    propagate (RK4 + projection) along tangent directions and the force. Phi freezes A at the
    sample's start; the sampled map sees A change along the motion, an error of order
    T |dA/dt| / (2 |A|) ~ T |v| / 2 ~ 3e-4 of the increment (Phi - I) delta at |v| ~ 0.5 rad/s
    (RK4's O(T^5) and the differences' O(h^2) are far below): 2e-3 of the largest increment."""
    z, zd, f = np.array([0.05, -0.1, -1.05]), np.array([0.2, -0.1, 0.3]), np.array([3.0, -1.0, -10.0])
    q, v = on_manifold(z, zd)
    u = d.holding_torque(P, q)[0] + np.array([5.0, -3.0, 2.0])
    Phi = transition_matrix(process_jacobian(P, q, v, u, f), T)
    h = 1e-6
    for k in range(9):
        dz, dzd, df = np.zeros(3), np.zeros(3), np.zeros(3)
        (dz, dzd, df)[k // 3][k % 3] = h
        plus, minus = on_manifold(z + dz, zd + dzd), on_manifold(z - dz, zd - dzd)
        start = (np.r_[plus] - np.r_[minus]) / 2.0
        after = (np.r_[propagate(P, *plus, u, f + df, T)] - np.r_[propagate(P, *minus, u, f - df, T)]) / 2.0
        increment = after - start
        np.testing.assert_allclose(Phi[:18] @ np.r_[start, df] - start, increment,
                                   rtol=0, atol=2e-3 * np.abs(increment).max())


def test_joseph_update_is_the_scalar_kalman_filter():
    """Scalar prior variance 4, noise variance 1: gain 4/5, posterior variance 4/5 (closed form)."""
    dx, Pn = joseph_update(np.array([[4.0]]), np.array([[1.0]]), np.array([2.5]), np.array([[1.0]]))
    assert dx[0] == pytest.approx(2.0, rel=1e-15) and Pn[0, 0] == pytest.approx(0.8, rel=1e-15)


def closed_loop(ekf: ContactEKF, q, steps: int, force, noise: float = 0.0, seed: int = 1, push: float = 0.0):
    """Run the robot (truth: the DAE by DOP853) under a joint PD about its start with gravity
    compensation, sampled at 1 kHz, with the unknown wrist force force(t, z, zd) (N); feed the
    filter the servo angles (plus seeded noise) and torques. After 50 ms the servos also push the
    wrist down with ``push`` (N): the holding torque of a payload of -push / g, exact since the
    holding torque is linear in the payload. Returns rows (t, true wrist force, estimate)."""
    rng = np.random.default_rng(seed)
    y_ref, x = q[SERVOS].copy(), np.r_[q, np.zeros(9)]
    rows = []

    def rhs(t, s, u):
        qs, vs = s[:9], s[9:]
        return d.state_derivative(P, s, u, force(t, d.wrist_position(P, qs), d.wrist_velocity(P, qs, vs)))

    for k in range(steps):
        t, y = k * T, x[SERVOS]
        carried = replace(P, payload=-push / P.g if t >= 0.05 else 0.0)
        u = d.holding_torque(carried, x[:9])[0] + 800.0 * (y_ref - y) - 40.0 * x[[9, 12, 15]]
        est = ekf.step(y + noise * rng.standard_normal(3), u)
        rows.append((t, force(t, d.wrist_position(P, x[:9]), d.wrist_velocity(P, x[:9], x[9:])), est))
        x = solve_ivp(rhs, (t, t + T), x, args=(u,), method="DOP853", rtol=1e-11, atol=1e-13).y[:, -1]
    return rows


@pytest.mark.parametrize("noise", [0.0, 1e-5])
def test_a_constant_wrist_force_is_recovered(noise):
    """A 15.5 N wrist force switched on at 0.2 s. Noise-free, the model is the plant: the estimate
    settles to 1e-3 N within 0.1 s and to round-off after. With servo noise 1e-5 rad (the
    filter's y_std) the steady error is the filter's noise, measured 2.3 N rms per axis with
    force_rate_std 100: bounded by its own standard deviation (which also counts the random walk
    the truth lacks)."""
    f_true = np.array([3.0, -2.0, -15.0])
    q = d.inverse_kinematics(P, [0.05, 0.0, -1.0])
    ekf = ContactEKF(P, ContactEKFSettings(contact_threshold=1e9), q[SERVOS])
    rows = closed_loop(ekf, q, 600, lambda t, z, zd: f_true if t >= 0.2 else np.zeros(3), noise)
    err = np.array([est.force - f for _, f, est in rows])
    std = np.array([est.force_std for _, _, est in rows])
    late = slice(300, None)
    if noise == 0.0:
        assert np.abs(err[late]).max() < 1e-3  # measured 1.9e-4 N 0.1 s after the step
        assert np.abs(err[-100:]).max() < 1e-6  # measured 1e-10 N
        assert np.abs(err[:200]).max() < 1e-6  # no force before it is applied
    else:
        rms, bias = np.sqrt(np.mean(err[late] ** 2, axis=0)), err[late].mean(axis=0)
        assert np.all(rms < 3.5) and np.all(np.abs(bias) < 1.5)  # 1.5 N: ~3 sigma of a 0.3 s mean
        assert np.all(np.abs(err[late]) < 3.0 * std[late])


def test_a_force_ramp_is_followed_without_lag_by_the_force_rate():
    """A wrist force ramping at 10 N/s along z from 0.1 s (truth: the DOP853 closed loop), noise-free.
    The force a random walk (force_rate_std 1 N/s per sqrt(Hz)) lags a ramp: its estimate trails
    the truth by a constant error once the filter is in steady state. With the force's rate as a
    random walk too (force_acceleration_std 100 N/s^2 per sqrt(Hz): an integrated random walk) the
    ramp is in the model: the error over the last 0.1 s at least 1000 times smaller (measured
    0.3 N against 2.7e-6 N) and the rate estimate the ramp's slope (to 1e-4; measured 3e-10
    relative). With both rate levels 0 the rate states stay zero with zero covariance: the force
    a random walk alone."""
    slope = 10.0
    q = d.inverse_kinematics(P, [0.0, 0.0, -1.0])
    walk = ContactEKFSettings(contact_threshold=1e9, force_rate_std=1.0, acceleration_std=1e-3)
    ramp = replace(walk, force_acceleration_std=100.0)
    errors = {}
    for name, settings in (("walk", walk), ("ramp", ramp)):
        ekf = ContactEKF(P, settings, q[SERVOS])
        rows = closed_loop(ekf, q, 400, lambda t, z, zd: np.array([0.0, 0.0, slope * max(t - 0.1, 0.0)]))
        errors[name] = max(abs(est.force[2] - f[2]) for _, f, est in rows[-100:])
        if name == "walk":
            assert not ekf.x[22:].any() and not ekf.P[22:].any()
        else:
            np.testing.assert_allclose(ekf.x[22:25], [0.0, 0.0, slope], rtol=1e-4, atol=1e-6)
    print(f"largest force error over the last 0.1 s: walk {errors['walk']:.2g} N, with the rate {errors['ramp']:.2g} N")
    assert errors["ramp"] < errors["walk"] / 1000.0


def spring_table(height: float, k: float = 2e5, c: float = 2e3, tool: float = -0.1):
    """The plant's CONTACT law, a table at height: fn = (k pen + c pen')_+, pen = height - tip."""
    def force(t, z, zd):
        return np.array([0.0, 0.0, max(k * (height - z[2] - tool) - c * zd[2], 0.0)])
    return force


@pytest.mark.parametrize("k_est", [2e5, 1e5])
def test_surface_height_from_a_press(k_est):
    """The robot starts 0.5 mm above a table and its servos push the wrist down with 40 N (a
    known torque). Closed forms: at rest the tip sits fn / k below the
    table, and the estimator's contact law puts the table fn / k_est above the tip, so its
    height is off by fn (1 / k_est - 1 / k): zero with the true stiffness, 168 um for the 33.6 N
    reached and half the stiffness. The filter must find the force (to 1 % of it) and the height
    to 2 um: at 0.7 s the press still moves (fn by 0.5 %, 0.15 N / k ~ 1 um; measured 0.8 and
    1.1 um)."""
    k, height = 2e5, -1.1505
    table = spring_table(height, k)
    q = d.inverse_kinematics(P, [0.0, 0.0, -1.05])
    settings = ContactEKFSettings(contact_stiffness=k_est, surface_height0=-1.12, surface_std0=0.03)
    ekf = ContactEKF(P, settings, q[SERVOS])
    rows = closed_loop(ekf, q, 700, table, push=40.0)
    t, f, est = rows[-1]
    fn = f[2]
    assert fn > 30.0 and est.in_contact
    assert est.fn == pytest.approx(fn, rel=0.01)
    assert est.surface_height - height == pytest.approx(fn * (1.0 / k_est - 1.0 / k), abs=2e-6)
    assert est.surface_std < 1e-4


@pytest.mark.parametrize("change, name", [({"y_std": 0.0}, "y_std"), ({"substeps": 0}, "substeps"),
                                          ({"normal": (1.0, 0.0, 0.0)}, "normal"),
                                          ({"force_rate_std": -1.0}, "force_rate_std")])
def test_bad_settings_name_the_setting(change, name):
    with pytest.raises(ValueError, match=name):
        ContactEKFSettings(**change)
