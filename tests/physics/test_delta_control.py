"""The delta controller math against the plant library (an independent formulation: dense
mass matrix, constraint Jacobian, the plant's own DAE solve) and against physics, plus short
closed loops of plant + controller at 1 kHz with a zero-order hold (no FMU involved)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from deltafmi.physics import delta as d
from deltafmi.physics.delta import control as dc
from deltafmi.physics.delta.trajectory import CirclePath, MinimumJerkPath

P = d.RL5
IY, IX = [0, 3, 6], [1, 2, 4, 5, 7, 8]
TS = 1e-3
# wrist positions spread over the nominal workspace (r <= 0.5 m, -1.2 <= z <= -0.75 m)
POINTS = [(0.0, 0.0, -1.0), (0.3, -0.2, -0.8), (-0.45, 0.1, -1.15), (0.1, 0.48, -0.9),
          (-0.2, -0.35, -0.76)]


def servo_state(p, z, zd=(0.0, 0.0, 0.0)):
    """Consistent plant state (q, v) at wrist position z moving with velocity zd."""
    q = d.inverse_kinematics(p, z)
    jc = dc.control_jacobian(p, q[IY])
    yd = np.linalg.solve(jc, zd)
    # xd from H v = 0: hx xd = -hy yd
    H = d.constraint_jacobian(p, q)
    v = np.zeros(9)
    v[IY] = yd
    v[IX] = np.linalg.solve(H[:, IX], -H[:, IY] @ yd)
    return q, v


def wrist_acceleration(p, q, v, vdot):
    """zdd of arm 1's wrist point: dpsi/dq vdot + (d/dt dpsi/dq) v."""
    return d.arm_jacobian(p, q[:3]) @ vdot[:3] + d.arm_bias(p, q[:3], v[:3])


# ------------------------------------------------------------------------------ kinematics
@pytest.mark.parametrize("z", POINTS)
def test_newton_fk_matches_closed_form(z):
    q = d.inverse_kinematics(P, z)
    y = q[IY]
    x0 = q[IX] + np.array([0.05, -0.04, 0.03, 0.05, -0.05, 0.02])   # a cold-ish start
    zn, xn, iters = dc.forward_kinematics_newton(P, y, x0)
    assert np.max(np.abs(zn - d.forward_kinematics(P, y))) < 1e-10
    assert np.max(np.abs(xn - q[IX])) < 1e-9
    assert iters <= 6                                  # quadratic convergence
    zc, xc = dc.forward_kinematics_closed(P, y)
    assert np.max(np.abs(zc - np.asarray(z))) < 1e-12
    assert np.max(np.abs(xc - q[IX])) < 1e-12


def test_warm_started_newton_needs_one_or_two_iterations():
    # the controller predicts x one sample ahead; along a fast circle Newton then converges
    # to 1e-12 m in one step almost always
    path = CirclePath((0.0, 0.0, -1.0), 0.15, 1.0, ramp_time=0.5)
    ctl = dc.DeltaController(P)
    iters = []
    for k in range(300):
        r, rd, rdd = path.evaluate(0.5 + k * TS)
        q, v = servo_state(P, r, rd)
        ctl.step(q[IY], v[IY], r, rd, rdd)
        iters.append(ctl.last.iterations)
        assert np.max(np.abs(np.array(ctl.last.z) - r)) < 1e-10
    assert max(iters[2:]) <= 2 and np.mean(iters[2:]) < 1.2


@pytest.mark.parametrize("z", POINTS)
def test_control_jacobian_matches_finite_differences_of_closed_form_fk(z):
    y = d.inverse_kinematics(P, z)[IY]
    h = 1e-6
    fd = np.column_stack([(d.forward_kinematics(P, y + h * e) - d.forward_kinematics(P, y - h * e))
                          / (2 * h) for e in np.eye(3)])
    # central differences: truncation ~h^2 * |z'''| ~ 1e-12, round-off ~1e-16 / h = 1e-10
    assert np.max(np.abs(dc.control_jacobian(P, y) - fd)) < 1e-8


@pytest.mark.parametrize("z", POINTS)
def test_inverse_kinematics_matches_plant(z):
    y, x = dc.inverse_kinematics_servo(P, z)
    q = d.inverse_kinematics(P, z)
    assert np.max(np.abs(y - q[IY])) < 1e-12 and np.max(np.abs(x - q[IX])) < 1e-12


# ------------------------------------------------------------------------------ dynamics
def potential(p, y):
    q = d.inverse_kinematics(p, d.forward_kinematics(p, y))
    return d.energy(p, q, np.zeros(9))


@pytest.mark.parametrize("z", POINTS)
def test_gravity_torque_is_the_gradient_of_the_potential(z):
    # virtual work: the servo torques holding the robot still are dV(y)/dy
    p = d.DeltaParams(payload=2.0)
    y = d.inverse_kinematics(p, z)[IY]
    h = 1e-5
    grad = np.array([(potential(p, y + h * e) - potential(p, y - h * e)) / (2 * h)
                     for e in np.eye(3)])
    tau = dc.gravity_torque(p, y)
    assert np.max(np.abs(tau - grad)) < 1e-6 * np.max(np.abs(tau))
    hold, _ = d.holding_torque(p, d.inverse_kinematics(p, z))   # the seed's 9x9 solve
    assert np.max(np.abs(tau - hold)) < 1e-10


@pytest.mark.parametrize("z", POINTS[:3])
def test_reduced_inertia_is_the_projected_mass_matrix(z):
    q = d.inverse_kinematics(P, z)
    H = d.constraint_jacobian(P, q)
    T = np.zeros((9, 3))
    T[IY] = np.eye(3)
    T[IX] = -np.linalg.solve(H[:, IX], H[:, IY])                    # dg/dy
    expected = T.T @ d.mass_matrix(P, q) @ T
    My = dc.reduced_inertia(P, q[IY])
    assert np.max(np.abs(My - expected)) < 1e-10 * np.max(np.abs(expected))
    assert np.all(np.linalg.eigvalsh(My) > 0)
    # the seed's slide formula M11 - M12 hx^-1 hy differs: it drops the constraint force on
    # the servo rows, is not even symmetric, and is off by tens of percent
    Mr = d.mass_matrix(P, q)
    seed = Mr[np.ix_(IY, IY)] + Mr[np.ix_(IY, IX)] @ T[IX]
    assert np.max(np.abs(seed - expected)) > 0.1 * np.max(np.abs(expected))


@pytest.mark.parametrize("damping,payload", [(0.0, 0.0), (0.4, 3.0)])
def test_inverse_dynamics_gives_the_commanded_wrist_acceleration(damping, payload):
    p = d.DeltaParams(damping=damping, payload=payload)
    rng = np.random.default_rng(7)
    for z in POINTS:
        q, v = servo_state(p, z, rng.uniform(-0.8, 0.8, 3))
        a = rng.uniform(-5.0, 5.0, 3)
        u = dc.inverse_dynamics(p, q[IY], v[IY], a)
        vdot, _ = d.accelerations(p, q, v, u, np.zeros(3), pole=20.0)
        assert np.max(np.abs(wrist_acceleration(p, q, v, vdot) - a)) < 1e-9


def test_seed_law_is_reduced_inertia_times_jc_inverse_plus_gravity():
    y = d.inverse_kinematics(P, POINTS[1])[IY]
    a = np.array([0.7, -1.3, 2.1])
    law = dc.make_law(P, kI=0.0, kP=0.0, kD=0.0, coriolis=False, fk="closed")
    u = dc.evaluate(law, y, [0.9, -0.4, 0.3], [0.0] * 3, [0.0] * 3, a).u   # velocities ignored
    expected = (dc.reduced_inertia(P, y) @ np.linalg.solve(dc.control_jacobian(P, y), a)
                + dc.gravity_torque(P, y))
    assert np.max(np.abs(np.array(u) - expected)) < 1e-10


# ------------------------------------------------------------------------------ the law
def test_gains_from_pole_and_overrides():
    law = dc.make_law(P)
    assert (law.kI, law.kP, law.kD) == (343.0, 147.0, 21.0)
    law = dc.make_law(P, pole=10.0, kP=50.0, kD=-1.0)
    assert (law.kI, law.kP, law.kD) == (1000.0, 50.0, 30.0)
    assert law.integral_max == pytest.approx(1.0 / 1000.0)


def test_pd_and_feedforward_terms_in_wrist_coordinates():
    # at rest, on target, with no integral: the law must produce exactly rdd at the wrist
    z = np.array(POINTS[2])
    q, v = servo_state(P, z)
    law = dc.make_law(P, fk="closed")
    e, ed, rdd = np.array([1e-3, -2e-3, 5e-4]), np.array([0.01, 0.02, -0.03]), np.array([1, 2, 3.0])
    out = dc.evaluate(law, q[IY], v[IY], z + e, ed, rdd)
    vdot, _ = d.accelerations(P, q, v, out.u, np.zeros(3), pole=20.0)
    expected = law.kP * e + law.kD * ed + rdd
    assert np.max(np.abs(wrist_acceleration(P, q, v, vdot) - expected)) < 1e-9
    off = dc.evaluate(dc.make_law(P, fk="closed", feedforward=False), q[IY], v[IY], z + e, ed, rdd)
    vdot, _ = d.accelerations(P, q, v, off.u, np.zeros(3), pole=20.0)
    assert np.max(np.abs(wrist_acceleration(P, q, v, vdot) - (expected - rdd))) < 1e-9


def test_integral_is_clamped_at_the_limit():
    z = np.array(POINTS[0])
    y = d.inverse_kinematics(P, z)[IY]
    law = dc.make_law(P, integral_limit=0.5)
    out = dc.evaluate(law, y, [0.0] * 3, z + [0.1, -0.1, 0.0], [0.0] * 3, [0.0] * 3,
                      integral=(0.0, 0.0, 0.0), dt=1.0)
    assert out.status & dc.STATUS_INTEGRAL_CLAMPED
    assert law.kI * np.array(out.integral) == pytest.approx([0.5, -0.5, 0.0])


def test_integral_frozen_while_the_torque_saturates():
    # conditional integration: a torque limit below the holding torque saturates every sample
    z = np.array(POINTS[0])
    y = d.inverse_kinematics(P, z)[IY]
    ctl = dc.DeltaController(P, torque_limit=5.0)
    target = z + [1e-3, 0.0, 0.0]
    u = ctl.step(y, [0.0] * 3, target, [0.0] * 3, [0.0] * 3)
    assert ctl.status & dc.STATUS_TORQUE_SATURATED and np.allclose(np.abs(u), 5.0)
    first = ctl.integral
    assert first[0] == pytest.approx(TS * 1e-3)
    for _ in range(5):
        ctl.step(y, [0.0] * 3, target, [0.0] * 3, [0.0] * 3)
    assert ctl.integral == first


def test_near_singularity_no_nan_saturated_torque_status_and_one_warning():
    zs = d.stretched_height(P)
    y = d.inverse_kinematics(P, (0.0, 0.0, zs + 1e-6))[IY]      # all arms almost stretched
    ctl = dc.DeltaController(P, torque_limit=250.0)
    u = ctl.step(y, [0.0] * 3, (0.0, 0.0, zs + 0.01), [0.0] * 3, [0.0] * 3)
    assert np.all(np.isfinite(u)) and np.max(np.abs(u)) <= 250.0
    assert ctl.status & dc.STATUS_ILL_CONDITIONED and ctl.status & dc.STATUS_TORQUE_SATURATED
    assert math.isfinite(ctl.cond)
    assert "ill-conditioned" in ctl.pending_warning()
    ctl.step(y, [0.0] * 3, (0.0, 0.0, zs + 0.01), [0.0] * 3, [0.0] * 3)
    assert ctl.pending_warning() is None                        # warned once
    # a measurement with no assembly (NaN) holds the last torque and reports singular
    held = ctl.step([math.nan, 0.0, 0.0], [0.0] * 3, [0.0] * 3, [0.0] * 3, [0.0] * 3)
    assert np.array_equal(held, u) and ctl.status == dc.STATUS_SINGULAR
    assert "singular" in ctl.pending_warning()
    # inside the nominal workspace the status stays clean
    ok = dc.DeltaController(P)
    for z in POINTS:
        ok.step(d.inverse_kinematics(P, z)[IY], [0.0] * 3, z, [0.0] * 3, [0.0] * 3)
        assert ok.status == dc.STATUS_OK and ok.cond < 10.0


# ------------------------------------------------------------------------------ closed loop
def rk4_sample(p, q, v, u, h=TS, pole=30.0):
    """One zero-order-hold sample of the plant: classical RK4 over h with u held."""
    f = np.zeros(3)

    def rhs(s):
        vd, _ = d.accelerations(p, s[:9], s[9:], u, f, pole)
        return np.concatenate([s[9:], vd])
    s = np.concatenate([q, v])
    k1 = rhs(s)
    k2 = rhs(s + 0.5 * h * k1)
    k3 = rhs(s + 0.5 * h * k2)
    k4 = rhs(s + h * k3)
    s = s + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return s[:9], s[9:]


def closed_loop(plant, ctl, reference, z0, duration):
    """Plant + controller at 1 kHz; returns times and the true wrist error r - z per sample."""
    q, v = servo_state(plant, z0)
    n = int(round(duration / TS))
    err = np.empty((n, 3))
    for k in range(n):
        r, rd, rdd = reference(k * TS)
        err[k] = r - d.wrist_position(plant, q)
        u = ctl.step(q[IY], v[IY], r, rd, rdd)
        q, v = rk4_sample(plant, q, v, u)
    return np.arange(n) * TS, err


def test_rk4_sample_matches_solve_ivp():
    # the harness integrator against an adaptive high-order one over a sample with big torques
    q, v = servo_state(P, POINTS[1], (0.3, -0.2, 0.1))
    u = d.holding_torque(P, q)[0] + [30.0, -20.0, 10.0]
    q1, v1 = rk4_sample(P, q, v, u)

    def rhs(t, s):
        return np.concatenate([s[9:], d.accelerations(P, s[:9], s[9:], u, np.zeros(3), 30.0)[0]])
    ref = solve_ivp(rhs, (0.0, TS), np.concatenate([q, v]), method="DOP853", rtol=1e-12,
                    atol=1e-14).y[:, -1]
    assert np.max(np.abs(q1 - ref[:9])) < 1e-12 and np.max(np.abs(v1 - ref[9:])) < 1e-9


@pytest.mark.parametrize("fk", ["newton", "closed"])
def test_step_move_tracked_to_a_micrometre(fk):
    z0 = np.array([0.05, -0.03, -1.0])
    path = MinimumJerkPath([z0, z0 + [0.02, 0.0, -0.01]], [0.4], dwell=0.1)
    t, err = closed_loop(P, dc.DeltaController(P, fk=fk), path.evaluate, z0, 1.0)
    assert np.max(np.abs(err)) < 1e-6                   # during the move as well
    assert np.max(np.abs(err[t > 0.7])) < 1e-7          # settled


def test_circle_tracked_to_a_micrometre():
    path = CirclePath((0.0, 0.0, -1.0), 0.05, 1.0, ramp_time=0.5)
    z0 = path.evaluate(0.0)[0]
    t, err = closed_loop(P, dc.DeltaController(P), path.evaluate, z0, 1.5)
    steady = np.linalg.norm(err[t > 0.8], axis=1)
    assert np.max(steady) < 1e-6
    # the seed's law (no velocity terms, no hold compensation) misses by tens of micrometres:
    # the Coriolis/centripetal torques it drops act as an unmodelled disturbance
    t, err = closed_loop(P, dc.DeltaController(P, coriolis=False, zoh_lead=False),
                         path.evaluate, z0, 1.5)
    assert np.max(np.linalg.norm(err[t > 0.8], axis=1)) > 1e-5


@pytest.mark.parametrize("pole", [7.0, 12.0])
def test_error_decays_with_the_designed_triple_pole(pole):
    # a static target 2 mm away, no feed-forward: in wrist coordinates the loop is
    # E''' + 3p E'' + 3p^2 E' + p^3 E = 0 for E = int(r - z), E(0) = 0, E'(0) = e0, E''(0) = 0,
    # hence e(t) = e0 (1 + p t - p^2 t^2) exp(-p t). Sampling at 1 ms perturbs it by O(p Ts).
    z0 = np.array([0.05, -0.03, -1.0])
    e0 = np.array([1e-3, -5e-4, 2e-3])
    ctl = dc.DeltaController(P, pole=pole, feedforward=False)
    t, err = closed_loop(P, ctl, lambda t: (z0 + e0, np.zeros(3), np.zeros(3)), z0, 1.0)
    analytic = np.outer((1 + pole * t - (pole * t) ** 2) * np.exp(-pole * t), e0)
    assert np.max(np.abs(err - analytic)) < 0.01 * np.max(np.abs(e0))


def test_integral_clamp_keeps_the_loop_stable_with_an_unmodelled_payload():
    # the controller does not know about 4 kg on the plate; the integral action needed to hold
    # it exceeds integral_limit in z, so z settles as a PD loop with a bias: kP e = a - limit
    plant = d.DeltaParams(payload=4.0)
    z0 = np.array([0.1, 0.05, -0.95])
    ctl = dc.DeltaController(P, integral_limit=1.0)
    t, err = closed_loop(plant, ctl, lambda t: (z0, np.zeros(3), np.zeros(3)), z0, 2.5)
    assert ctl.status & dc.STATUS_INTEGRAL_CLAMPED
    # wrist acceleration demand that balances the payload through the controller's model
    y = d.inverse_kinematics(plant, z0 - err[-1])[IY]
    need = dc.control_jacobian(P, y) @ np.linalg.solve(
        dc.reduced_inertia(P, y), dc.gravity_torque(plant, y) - dc.gravity_torque(P, y))
    law = ctl.law
    integral_action = law.kI * np.array(ctl.integral)
    assert list(np.isclose(np.abs(integral_action), 1.0)) == [False, False, True]
    # z: PD with the integral stuck at the limit; 8 mm of droop, held to 1e-6 relative
    assert need[2] > 2.0
    assert err[-1, 2] == pytest.approx((need[2] - 1.0) / law.kP, rel=1e-6)
    # x, y: the free integrators still remove the error (more slowly: the controller's
    # inertia is wrong by the payload, which moves the closed-loop poles)
    assert np.all(np.abs(err[-1, :2]) < 1e-6)
    assert np.all(np.abs(err[-1, :2]) < 0.1 * np.abs(err[t > 1.0][0, :2]))


# ------------------------------------------------------------------------------ the FMUs
@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_controller_fmu_samples_like_the_library(build_fmu_from_src, fmi_type):
    # servo angles drifting along a line of wrist positions, fed as a continuous input signal:
    # the output must be the library controller's torque of the latest sample instant k Ts,
    # computed from the inputs at k Ts, and constant in between
    from fmpy import simulate_fmu

    fmu = build_fmu_from_src("delta_controller.py")
    z0, vz = np.array([0.05, -0.03, -1.0]), np.array([0.02, 0.01, -0.02])
    r = z0 + [1e-3, 0.0, -1e-3]
    t_in = np.linspace(0.0, 0.02, 41)
    ys = np.array([d.inverse_kinematics(P, z0 + vz * t)[IY] for t in t_in])
    names = [f"{n}[{i}]" for n in ("y", "yd", "r", "rd", "rdd") for i in (1, 2, 3)]
    signal = np.zeros(len(t_in), dtype=[("time", float)] + [(n, float) for n in names])
    signal["time"] = t_in
    for i in range(3):
        signal[f"y[{i + 1}]"] = ys[:, i]
        signal[f"r[{i + 1}]"] = r[i]
    res = simulate_fmu(fmu, fmi_type=fmi_type, stop_time=0.0199, output_interval=2.5e-4,
                       input=signal, output=["u[1]", "u[2]", "u[3]", "status", "z_est[3]"])
    ctl = dc.DeltaController(P)
    expected = []
    for k in range(20):
        y = [np.interp(k * TS, t_in, ys[:, i]) for i in range(3)]
        expected.append(ctl.step(y, [0.0] * 3, r, [0.0] * 3, [0.0] * 3))
    seen = set()
    for row in res:
        t = row["time"]
        k = int(math.floor(t / TS + 1e-6))
        if k and abs(t - k * TS) < 1e-9 and (fmi_type == "CoSimulation" or t not in seen):
            # at a sample instant: CS reports the end of doStep(t - h, h), which took the
            # samples in [t - h, t); ME reports the left limit first, then the event's result
            k -= 1
        seen.add(t)
        got = np.array([row["u[1]"], row["u[2]"], row["u[3]"]])
        assert np.max(np.abs(got - expected[k])) < 1e-9, t
        assert row["status"] == 0 and -1.01 < row["z_est[3]"] < -0.99
    assert len(seen) > 75


def test_three_fmus_in_closed_loop_track_a_step(build_fmu_from_src):
    # trajectory -> controller -> plant (the DeltaRobot FMU), Gauss-Seidel at the sample period:
    # the same zero-order-hold loop as closed_loop() above, so the same micrometre tracking
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    def load(name):
        path = build_fmu_from_src(name)
        md = read_model_description(path)
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), instanceName=name,
                        modelIdentifier=md.coSimulation.modelIdentifier)
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0, tolerance=1e-10)   # the plant's CVODE tolerance
        refs = {v.name: v.valueReference for v in md.modelVariables}
        return fmu, lambda *names: [refs[n] for n in names]

    def vec(*names):
        return [f"{n}[{i}]" for n in names for i in (1, 2, 3)]

    plant, pv = load("delta_robot.py")
    ctl, cv = load("delta_controller.py")
    traj, tv = load("trajectory.py")
    z0, z1 = [0.05, -0.03, -1.0], [0.07, -0.03, -1.01]
    plant.setReal(pv(*vec("z0")), z0)
    traj.setInteger(tv("mode", "n_waypoints"), [0, 2])
    traj.setReal(tv("wp_x[1]", "wp_x[2]", "wp_y[1]", "wp_y[2]", "wp_z[1]", "wp_z[2]", "wp_T[1]",
                    "dwell"),
                 [z0[0], z1[0], z0[1], z1[1], z0[2], z1[2], 0.4, 0.1])
    for fmu in (plant, traj, ctl):
        fmu.enterInitializationMode()
    plant.exitInitializationMode()
    traj.exitInitializationMode()

    def wire():
        ctl.setReal(cv(*vec("y", "yd", "r", "rd", "rdd")),
                    plant.getReal(pv(*vec("y", "yd"))) + traj.getReal(tv(*vec("r", "rd", "rdd"))))
    wire()
    ctl.exitInitializationMode()          # takes the sample at t = 0 with these inputs
    err = []
    for k in range(1000):
        if k:
            wire()
        ctl.doStep(k * TS, TS)            # the sample at k Ts
        plant.setReal(pv(*vec("u")), ctl.getReal(cv(*vec("u"))))
        err.append(np.subtract(traj.getReal(tv(*vec("r"))), plant.getReal(pv(*vec("z")))))
        plant.doStep(k * TS, TS)
        traj.doStep(k * TS, TS)
    for fmu in (plant, ctl, traj):
        fmu.terminate()
        fmu.freeInstance()
    err = np.array(err)
    assert np.max(np.abs(err)) < 1e-6 and np.max(np.abs(err[700:])) < 2e-7


def test_controller_fmu_warns_once_when_the_step_is_longer_than_its_sample_period(tmp_path):
    # --step 0.002 against the controller's 1 ms sample period changes the closed loop: the
    # controller FMU says so once (fmi2Warning, logStatusWarning), -q hides it, the 1 ms step
    # of the shipped scenario says nothing
    import subprocess
    import sys
    from pathlib import Path

    deltafmi = Path(sys.executable).parent / "deltafmi"

    def run(*options):
        return subprocess.run([str(deltafmi), "run", "delta_tracking", "--stop", "0.05", "-o", "r.csv", *options],
                              cwd=tmp_path, capture_output=True, text=True, timeout=600)

    expected = "communication step 0.002 s is longer than sample_period 0.001 s"
    long = run("--step", "0.002")
    assert long.returncode == 0, long.stderr
    assert long.stderr.count(expected) == 1
    assert f"warning: controller: {expected}" in long.stderr
    verbose = run("--step", "0.002", "-v")
    assert f"warning: controller: [logStatusWarning] {expected}" in verbose.stderr
    quiet = run("--step", "0.002", "-q")
    assert (quiet.returncode, quiet.stdout, quiet.stderr) == (0, "", "")
    shipped = run()
    assert shipped.returncode == 0 and "sample_period" not in shipped.stderr


def test_a_deep_copy_continues_as_the_original_and_apart_from_it():
    """A deep copy (what an FMU state holds) samples on exactly as the controller it was taken
    from, and neither sees the other's samples; a mutable attribute is not shared."""
    import copy

    z = np.array(POINTS[1])
    y = d.inverse_kinematics(P, z)[IY]
    target = z + [2e-3, -1e-3, 1e-3]
    ctl = dc.DeltaController(P, pole=9.0, stiffness=[0.0, 0.0, 0.0])
    for _ in range(3):
        ctl.step(y, [0.0] * 3, target, [0.0] * 3, [0.0] * 3)
    saved = copy.deepcopy(ctl)
    assert saved is not ctl and saved.stiffness is not ctl.stiffness  # a list: copied
    before = ctl.state
    u_original = [ctl.step(y, [0.0] * 3, target, [0.0] * 3, [0.0] * 3) for _ in range(4)]
    assert saved.state == before  # untouched by the original's samples
    u_copy = [saved.step(y, [0.0] * 3, target, [0.0] * 3, [0.0] * 3) for _ in range(4)]
    assert all(np.array_equal(a, b) for a, b in zip(u_original, u_copy))
    assert saved.state == ctl.state and saved.integral != before.integral
