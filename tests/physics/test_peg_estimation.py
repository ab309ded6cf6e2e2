"""The peg estimator's mechanics (deltafmi.physics.estimation: wrist_process, peg_contact, peg_ekf):
the reduced process model against the plant's 24-state DAE integrated by solve_ivp (DOP853,
rtol 1e-11), its wrench columns by linearity, the hole locator against a contact in closed form,
the Schmidt update against the scalar formulas, the iterated contact update against the law it
inverts, and the filter finding a known wrench on the
moving robot from its simulated joint angles and the torques alone."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from deltafmi.physics import delta_wrist as dw
from deltafmi.physics.delta.kinematics import forward_kinematics, wrist_position
from deltafmi.physics.delta.params import RL5
from deltafmi.physics.estimation.kalman import joseph_update
from deltafmi.physics.estimation.peg_contact import contact_wrench, locate_hole
from deltafmi.physics.estimation.peg_ekf import PegEKF, PegEKFSettings
from deltafmi.physics.estimation.wrist_process import derivative, full_state, process_jacobian, propagate, tool_pose
from deltafmi.physics.peg import Hole, Peg, PegContact, peg_wrench
from deltafmi.physics.peg.plant import tool_pose as plant_tool_pose
from deltafmi.physics.wrist.kernels import tip_position, wrist_constants

W_CONST = wrist_constants(dw.wrist_params((3e-4, 2e-4, 1e-4), dw.peg_tool(0.25, 0.1, 0.01, 0.13), 9.81, 0.0))
MOUNT = dw.MOUNT
T = 1e-3
#: a moving state: plate at (0.02, -0.01, -1.0) m, wrist tilted, rates of a typical insertion
S0 = np.array([0.02, -0.01, -1.0, 0.05, -0.1, 0.08, 0.03, -0.02, 0.05, 0.2, -0.1, 0.3])
WRENCH = np.array([1.0, -0.5, 2.0, 0.002, -0.001, 0.0005])  # N at the tip, N m about it


def inputs(s):
    """The torques holding the plant still at s's pose, slightly off (N m)."""
    x, _ = full_state(RL5, s)
    u, tau = dw.holding_torques(RL5, W_CONST, x)
    return u + np.array([3.0, -2.0, 1.0]), tau + np.array([0.01, -0.02, 0.005])


def dae_run(s, u, tau, W, times):
    """The plant's 24-state DAE (delta_wrist.state_derivative) by DOP853 from the full state of s."""
    x0, _ = full_state(RL5, s)
    sol = solve_ivp(lambda t, x: dw.state_derivative(RL5, W_CONST, MOUNT, x, list(u), list(tau), list(W[:3]),
                                                     list(W[3:]), 5.0),
                    (times[0], times[-1]), x0, method="DOP853", rtol=1e-11, atol=1e-13, t_eval=times)
    return sol.y.T


def test_full_state_and_tool_pose_are_the_plants():
    """The reduced state's full state lies on the loops (wrist_position = z to 1e-12 m) and its tool
    pose is the plant's own (peg.plant.tool_pose of the full state, to 1e-12)."""
    x, _ = full_state(RL5, S0)
    np.testing.assert_allclose(wrist_position(RL5, x[:9]), S0[:3], atol=1e-12)
    for mine, plants in zip(tool_pose(W_CONST, MOUNT, S0), plant_tool_pose(RL5, W_CONST, MOUNT, x)):
        np.testing.assert_allclose(mine, plants, atol=1e-12)


def test_reduced_model_follows_the_24_state_dae():
    """20 samples of propagate (RK4 at 1 ms) against the DAE by DOP853 (rtol 1e-11): plate and wrist
    positions to 1e-10 m / rad, rates to 1e-8. RK4's global error is ~ T^4 |x^(5)| t ~ 1e-12 x 10 x
    0.02 here; the bounds leave room for the DAE's Baumgarte drift (|h| ~ 1e-12 m)."""
    u, tau = inputs(S0)
    times = np.arange(21) * T
    truth = dae_run(S0, u, tau, WRENCH, times)[-1]
    s = S0.copy()
    for _ in range(20):
        s = propagate(RL5, W_CONST, MOUNT, s, u, tau, WRENCH, T)
    np.testing.assert_allclose(s[:3], wrist_position(RL5, truth[:9]), atol=1e-10)
    np.testing.assert_allclose(s[3:6], truth[9:12], atol=1e-10)
    x_end, _ = full_state(RL5, s)
    np.testing.assert_allclose(s[9:12], truth[21:24], atol=1e-8)
    np.testing.assert_allclose(x_end[12:21], truth[12:21], atol=1e-8)


def test_process_jacobian_wrench_columns_are_exact_and_state_columns_match_central_differences():
    """Accelerations are affine in the wrench: a(W) - a(0) = G W to round-off (1e-9 of |a|); the
    forward-difference state columns against central differences of step 1e-5 (the two differ by
    O(step) ~ 1e-5 relative: bound 1e-3 of the column scale)."""
    u, tau = inputs(S0)
    J = process_jacobian(RL5, W_CONST, MOUNT, S0, u, tau, np.zeros(6))
    a0 = derivative(RL5, W_CONST, MOUNT, S0, u, tau, np.zeros(6))
    aW = derivative(RL5, W_CONST, MOUNT, S0, u, tau, WRENCH)
    np.testing.assert_allclose(aW - a0, J[:, 12:] @ WRENCH, atol=1e-9 * np.abs(aW).max())
    for k in range(12):
        h = 1e-5
        e = np.eye(12)[k] * h
        central = (derivative(RL5, W_CONST, MOUNT, S0 + e, u, tau, np.zeros(6))
                   - derivative(RL5, W_CONST, MOUNT, S0 - e, u, tau, np.zeros(6))) / (2 * h)
        np.testing.assert_allclose(J[:, k], central, atol=1e-3 * max(np.abs(central).max(), 1.0))


def chamfer_contact():
    """The peg upright, 0.31 mm below the top plane of a hole 1.8 mm off along +x: its rim point
    opposite the offset (tool angle pi, one of the 32) lies on the 45-degree chamfer, whose radius at
    that depth is 12.1 - 0.31 = 11.79 mm < 10 + 1.8: penetration (0.01 mm) cos(45 deg)."""
    hole = Hole(x=0.0018, y=0.0, z=-1.2)
    peg, law = Peg(), PegContact()
    tip = (0.0, 0.0, -1.2 - 0.00031)
    qw = np.zeros(3)
    z = np.array(tip) - np.array(tip_position(W_CONST, (0.0, 0.0, 0.0))) - np.array([0.0, 0.0, -0.05])
    s = np.concatenate([z, qw, np.zeros(6)])
    return hole, peg, law, s


def test_locator_finds_the_hole_behind_a_chamfer_contact():
    """The contact is symmetric about the x axis, so the felt force points along +x exactly and
    the hole lies on that line: from the nominal hole (0, 0) the locator finds x = 1.8 mm to 0.1 um
    (its scalar search stops at 1e-8 m; the grid's 20 um cell holds the minimum) and y = 0."""
    hole, peg, law, s = chamfer_contact()
    c = contact_wrench(hole, peg, law, W_CONST, MOUNT, s, [hole.x, hole.y, 0.0, 0.0])
    assert c.active >= 1 and c.force[0] > 0.1 and abs(c.force[1]) < 1e-9
    nominal = Hole(x=0.0, y=0.0, z=-1.2)
    felt = np.array(c.force + c.moment)
    found = locate_hole(nominal, peg, law, W_CONST, MOUNT, s, [0.0, 0.0, 0.0, 0.0], felt, [0.05] * 3 + [0.005] * 3)
    assert found is not None
    np.testing.assert_allclose(found[:2], [0.0018, 0.0], atol=1e-7)
    assert peg_wrench(hole, peg, law, *tool_pose(W_CONST, MOUNT, s)).potential > 0.0


def test_locator_knows_a_flat_push_says_nothing_of_the_hole():
    """A purely axial felt force (the peg on the top face) has no lateral direction: no location."""
    _, peg, law, s = chamfer_contact()
    assert locate_hole(Hole(), peg, law, W_CONST, MOUNT, s, [0.0] * 4, [0.0, 0.0, 5.0, 0.0, 0.0, 0.0],
                       [0.05] * 3 + [0.005] * 3) is None


def test_schmidt_update_corrects_only_the_updated_states():
    """x = [h, w], z = h + w, R = r, w considered: K_h = (a + c) / S, S = a + b + 2c + r, K_w = 0,
    P_hh = a - (a + c)^2 / S, P_ww = b (unchanged), P_hw = c - K_h (b + c) (closed forms)."""
    a, b, c, r, res = 4.0, 2.0, 0.5, 1.0, 3.0
    S = a + b + 2 * c + r
    dx, P = joseph_update(np.array([[a, c], [c, b]]), np.array([[1.0, 1.0]]), np.array([res]), np.array([[r]]),
                          slice(0, 1))
    K = (a + c) / S
    np.testing.assert_allclose(dx, [K * res, 0.0], rtol=1e-14)
    np.testing.assert_allclose(P, [[a - (a + c) ** 2 / S, c - K * (b + c)], [c - K * (b + c), b]], rtol=1e-14)


def test_the_filter_finds_a_constant_wrench_on_the_moving_robot():
    """The plant moving freely from S0 under constant torques and the wrench WRENCH (truth: DOP853
    of the 24-state DAE), the filter sees y, qw at 1 kHz and the torques: after 0.25 s its force is
    within 2e-3 N and its moment within 1e-4 N m (measured 2e-8 N and 1e-9 N m: the model is the
    plant's, and a constant is what the random walk tracks without lag). The 2.3 N exceed the
    contact threshold, so the filter takes them for a contact, but no hole along the felt lateral
    force makes the contact law explain this wrench better than no contact at all (the locator's
    test): the hole keeps its prior mean, and its standard deviations grow by its random walk alone,
    sqrt(std0^2 + drift^2 t) over the 250 predictions."""
    u, tau = inputs(S0)
    times = np.arange(251) * T
    truth = dae_run(S0, u, tau, WRENCH, times)
    settings = PegEKFSettings(velocity_std0=0.1, rate_std0=1.0, force_std0=5.0)
    ekf = PegEKF(RL5, W_CONST, MOUNT, Hole(x=0.5), Peg(), PegContact(), settings, truth[0, [0, 3, 6]], truth[0, 9:12])
    for x in truth:
        est = ekf.step(x[[0, 3, 6]], x[9:12], u, tau)
    np.testing.assert_allclose(est.force, WRENCH[:3], atol=2e-3)
    np.testing.assert_allclose(est.moment, WRENCH[3:], atol=1e-4)
    np.testing.assert_allclose(est.tip, plant_tool_pose(RL5, W_CONST, MOUNT, truth[-1])[0], atol=1e-8)
    assert est.in_contact  # any wrench above contact_threshold is taken for a contact ...
    np.testing.assert_array_equal(est.hole, [0.5, 0.0, 0.0, 0.0])  # ... but the law puts no hole here
    walk = 250 * T * np.array([settings.hole_drift_std] * 2 + [settings.tilt_drift_std] * 2) ** 2
    np.testing.assert_allclose(est.hole_std, np.sqrt(np.array([0.002, 0.002, 0.02, 0.02]) ** 2 + walk), rtol=1e-12)
    assert forward_kinematics(RL5, truth[-1, [0, 3, 6]]) == pytest.approx(ekf.x[:3], abs=1e-8)


def test_process_jacobian_columns_in_turn_are_the_full_ones():
    """Evaluating some columns into a kept matrix gives those columns of the full Jacobian, bit for
    bit (the same differences), and leaves the others as they were."""
    u, tau = inputs(S0)
    full = process_jacobian(RL5, W_CONST, MOUNT, S0, u, tau, WRENCH)
    kept = np.full((12, 18), 7.0)
    process_jacobian(RL5, W_CONST, MOUNT, S0, u, tau, WRENCH, 5.0, [16, 17, 0, 5], kept)
    np.testing.assert_array_equal(kept[6:, [16, 17, 0, 5]], full[6:, [16, 17, 0, 5]])
    np.testing.assert_array_equal(kept[0:6, 6:12], np.eye(6))
    assert np.all(kept[6:, [1, 2, 3, 4, 6, 12, 15]] == 7.0)


def contact_update(iterations: int, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """The chamfer contact of :func:`chamfer_contact` felt exactly (W the law's wrench at the true
    hole, s and W known to 1e-9), the hole's prior ``offset`` m off along x (standard deviations
    200 um and 2 mrad; no law error considered: the felt wrench is the law's): (the law's wrench at the
    updated hole - the felt one, the updated hole)."""
    hole, peg, law, s = chamfer_contact()
    truth = [hole.x, hole.y, 0.0, 0.0]
    felt = np.array(contact_wrench(hole, peg, law, W_CONST, MOUNT, s, truth).force
                    + contact_wrench(hole, peg, law, W_CONST, MOUNT, s, truth).moment)
    exact = PegEKFSettings(contact_iterations=iterations, law_hole_std=0.0, law_tilt_std=0.0)  # the law is the truth's
    ekf = PegEKF(RL5, W_CONST, MOUNT, Hole(z=-1.2), peg, law, exact, [0.0] * 3, [0.0] * 3)
    ekf.x[:12], ekf.x[12:18], ekf.x[18:22] = s, felt, [hole.x + offset, hole.y, 0.0, 0.0]
    ekf.P = np.diag([1e-18] * 18 + [2e-4 ** 2] * 2 + [2e-3 ** 2] * 2 + [1e-18] * 6)
    ekf._contact_update()
    h = ekf.x[18:22]
    c = contact_wrench(hole, peg, law, W_CONST, MOUNT, s, h)
    return np.array(c.force + c.moment) - felt, h


def test_the_iterated_contact_update_explains_the_felt_wrench():
    """The penalty law is linear over micrometres only (2e5 N/m a contact point; the felt force is
    1.4 N, 7 um of penetration). From a hole prior 20 um off along the contact's normal (x: the
    contact is symmetric about the x axis), the iterated update (Gauss-Newton) moves the hole to
    where the law gives the felt wrench to 1e-3 N (the law's noise contact_force_std is 0.05 N;
    measured 3e-5 N) and within 1 um of the truth (measured 0.26 um: the prior's pull, 200 um
    against the law's micrometres); the extended filter's single linearisation overshoots: 14 um off,
    the law 1.3 N from the felt wrench (measured; bounds 5 um and 0.1 N)."""
    residual, h = contact_update(10, 20e-6)
    assert np.abs(residual[:3]).max() < 1e-3
    assert abs(h[0] - 0.0018) < 1e-6 and abs(h[1]) < 1e-6
    single, h1 = contact_update(1, 20e-6)
    assert np.abs(single[:3]).max() > 0.1 and abs(h1[0] - 0.0018) > 5e-6


def test_the_manoeuvre_gate_is_the_chi_square_quantile():
    """The detector's gate, Wilson-Hilferty's chi-square quantile at z = 3.090, against scipy's
    chi2.ppf(0.999, dof): within 2e-3 relative from 30 degrees of freedom (measured 1.7e-3 at 30,
    7e-4 at 60; the detector sums 6 x manoeuvre_samples of them: 60 by default)."""
    from scipy.stats import chi2

    from deltafmi.physics.estimation.peg_ekf import MANOEUVRE_Z, chi_square_quantile

    for dof in (30, 60, 120, 600):
        assert chi_square_quantile(dof, MANOEUVRE_Z) == pytest.approx(chi2.ppf(0.999, dof), rel=2e-3)


def test_a_wrench_the_steady_walk_cannot_explain_is_a_manoeuvre():
    """The filter sure there is no wrench (force_std0 1e-3 N, moment 1e-4 N m) on the moving robot
    of the test above: with no wrench no manoeuvre is detected in 0.25 s; with WRENCH (2.3 N, there
    from the start, which the steady walks, 0.01 N/s/sqrt(Hz) on the force and 0.7 N/s^2/sqrt(Hz) on
    its rate, would take seconds to reach) the sum of the joint angles' normalised innovations
    exceeds its gate at the first full window (sample 9 of 10 samples), once, and the fast walk then
    finds the wrench (to 1e-4 N; measured 2.6e-5 at 0.25 s: the wrench's rate, reopened at the
    manoeuvre to force_ramp_std, 5 N/s, is learned to be zero over the samples after it; 3e-8
    with the wrench a plain random walk)."""
    u, tau = inputs(S0)
    times = np.arange(251) * T
    for wrench, detected in ((np.zeros(6), None), (WRENCH, 9)):
        truth = dae_run(S0, u, tau, wrench, times)
        ekf = PegEKF(RL5, W_CONST, MOUNT, Hole(x=0.5), Peg(), PegContact(),
                     PegEKFSettings(velocity_std0=0.1, rate_std0=1.0, force_std0=1e-3, moment_std0=1e-4),
                     truth[0, [0, 3, 6]], truth[0, 9:12])
        first = None
        for k, x in enumerate(truth):
            est = ekf.step(x[[0, 3, 6]], x[9:12], u, tau)
            first = k if first is None and ekf.manoeuvre else first
        assert first == detected and ekf.manoeuvres == (detected is not None)
        np.testing.assert_allclose(est.force, wrench[:3], atol=1e-4)


def correlated_filter() -> tuple[PegEKF, np.ndarray]:
    """A filter at :func:`chamfer_contact` (force felt: the law's at the true hole; its hole 2 um off
    along x) with a dense covariance of the state and the law's offset b: a random correlation
    matrix (seeded) scaled by standard deviations of the filter's orders. (filter, [P, P_xb; P_xb^T, P_bb])."""
    hole, peg, law, s = chamfer_contact()
    c = contact_wrench(hole, peg, law, W_CONST, MOUNT, s, [hole.x, hole.y, 0.0, 0.0])
    ekf = PegEKF(RL5, W_CONST, MOUNT, Hole(z=-1.2), peg, law, PegEKFSettings(contact_iterations=1), [0.0] * 3,
                 [0.0] * 3)
    ekf.x[:12], ekf.x[12:18], ekf.x[18:22] = s, c.force + c.moment, [hole.x + 2e-6, hole.y, 0.0, 0.0]
    rng = np.random.default_rng(3)
    root = rng.standard_normal((32, 32))
    cov = root @ root.T + 32 * np.eye(32)
    std = np.array([1e-7] * 6 + [1e-4] * 6 + [0.05] * 3 + [0.005] * 3 + [2e-4] * 2 + [2e-3] * 2 + [0.5] * 3
                   + [0.01] * 3 + [3e-5] * 2 + [3e-3] * 2)
    Pa = cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov))) * np.outer(std, std)
    ekf.P, ekf._Pxb, ekf._Pbb = Pa[:28, :28].copy(), Pa[:28, 28:].copy(), Pa[28:, 28:].copy()
    return ekf, Pa


def assert_covariances(ekf: PegEKF, Pa: np.ndarray, prior: np.ndarray) -> None:
    """The filter's [P, P_xb] equal to Pa's to 1e-11 of the prior's correlation scale sqrt(P_ii P_jj):
    round-off of sums of terms of the prior's size (measured 1e-15 to 2e-12; the dense form's own
    error against long double is 3e-13 in the contact update)."""
    scale = np.sqrt(np.outer(np.diag(prior), np.diag(prior)))[:28]
    assert np.max(np.abs(np.hstack([ekf.P, ekf._Pxb]) - Pa[:28]) / scale) < 1e-11


def assert_correction(updated: np.ndarray, x: np.ndarray, dx: np.ndarray, prior: np.ndarray) -> None:
    """updated = x + dx to 1e-11 prior standard deviations, beside x + dx's own round-off."""
    error = np.abs(updated - (x + dx)) - 4 * np.finfo(float).eps * np.abs(x + dx)
    assert np.max(error / np.sqrt(np.diag(prior)[:28])) < 1e-11


def test_the_covariance_algebra_by_blocks_is_the_dense_one():
    """The filter forms its covariance algebra by blocks (the transition matrix's nonzero rows, the
    Joseph products as low-rank corrections); against the dense forms on the 32 x 32 covariance of
    the state (with the wrench's rate) and the considered law offset b, with every entry correlated:
    Phi P Phi^T + Q with Phi = exp(A T) (kalman.transition_matrix); the angles' update, joseph_update of the 28 states
    (b's rows of the gain zero); the contact law's, joseph_update of the hole's 4 (law seeing h + b).
    To round-off (:func:`assert_covariances`, :func:`assert_correction`)."""
    from deltafmi.physics.estimation.kalman import transition_matrix

    ekf, Pa = correlated_filter()  # the prediction, from the torques holding the pose
    u, tau = inputs(ekf.x[:12])
    ekf.predict(list(u), list(tau))
    A = np.zeros((24, 24))  # over z = [s, W, V]: s' = A [s, W], W' = V
    A[:12, :18] = ekf._A
    A[12:18, 18:24] = np.eye(6)
    z = np.r_[0:18, 22:28]
    Phi = np.eye(32)
    Phi[np.ix_(z, z)] = transition_matrix(A, T)
    predicted = Phi @ Pa @ Phi.T
    predicted[:28, :28] += ekf._Q_steady
    assert_covariances(ekf, predicted, Pa)

    ekf, Pa = correlated_filter()  # the angles' update, out of contact
    ekf.x[12:18] = 0.0
    servo = ekf.functions.servo_kinematics(ekf.p, ekf.x[0:3].tolist())
    y, qw = servo[:3] + [1e-6, -2e-6, 0.5e-6], ekf.x[3:6] + [1e-6, 0.0, -1e-6]  # innovations of a few std
    H = np.zeros((6, 32))
    H[:3, :3], H[3:, 3:6] = servo[3:12].reshape(3, 3), np.eye(3)
    residual = np.concatenate([y - servo[:3], qw - ekf.x[3:6]])
    x = ekf.x.copy()
    ekf.update(y, qw)
    dx, updated = joseph_update(Pa, H, residual, ekf._R, slice(0, 28))
    assert not ekf.in_contact
    assert_covariances(ekf, updated, Pa)
    assert_correction(ekf.x, x, dx[:28], Pa)

    ekf, Pa = correlated_filter()  # the contact law's update, one linearisation
    c, J, active = ekf._wrench_jacobian(ekf.x[18:22])
    H = np.hstack([-J[:, :12], np.eye(6), -J[:, 12:], np.zeros((6, 6)), -J[:, 12:]])  # over [s, W, h, V, b]
    x = ekf.x.copy()
    ekf._contact_update()
    dx, updated = joseph_update(Pa, H, c - x[12:18], ekf._Rc, slice(18, 22))
    assert active > 0.0 and ekf.consistency <= ekf.settings.contact_gate
    assert_covariances(ekf, updated, Pa)
    assert_correction(ekf.x, x, dx[:28], Pa)
