"""The assembly controller's law at the mechanics level (deltafmi/physics/assembly), against an
independent plant: the numpy delta DAE (delta/dynamics.py) carrying the numpy wrist
(wrist/dynamics.py), coupled through the wrist's plate load (wrist/coupling.py) by an exact
affine elimination, integrated by DOP853 between the 1 kHz samples with the torques held.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from deltafmi.physics import wrist as W
from deltafmi.physics.assembly import (PHASE_APPROACH, PHASE_DESCENT, PHASE_HOLD, STATUS_GIMBAL_DAMPED,
                                         AssemblySettings, evaluate, gains, initial_state, make_assembly_law,
                                         make_program, reference, sample)
from deltafmi.physics.assembly.program import hole_frame
from deltafmi.physics.assembly.rotation import (TOOL_DOWN, matmul, orientation_reference, rotation_from_vector,
                                                  rotation_vector)
from deltafmi.physics.assembly.wrist_model import inverse_dynamics, wrist_state
from deltafmi.physics.delta import dynamics as D
from deltafmi.physics.delta import kinematics as K
from deltafmi.physics.delta.params import ARM_ROTATIONS, DeltaParams
from deltafmi.physics.delta_wrist import dynamics as delta_wrist_dynamics
from deltafmi.physics.delta_wrist.params import WristMount
from deltafmi.physics.wrist.kernels import wrist_constants

T = 1e-3  # the controller's sample period (s)
MOUNT = (0.0, 0.0, -0.05)
TILT = (0.03, -0.02)  # a tilted nominal hole frame: the impedance axes are not the world's
DELTA = DeltaParams()


class Plant:
    """The 6-DOF plant, assembled here from the numpy modules (state [q 9, qw 3, v 9, qwd 3])."""

    def __init__(self, wrist: W.WristParams) -> None:
        self.pw = wrist

    @staticmethod
    def _arms(q: np.ndarray, v: np.ndarray) -> list:
        """Per arm, its rotation, Jacobian and bias acceleration at (q, v)."""
        return [(r, K.arm_jacobian(DELTA, q[3 * i:3 * i + 3]),
                 K.arm_bias(DELTA, q[3 * i:3 * i + 3], v[3 * i:3 * i + 3])) for i, r in enumerate(ARM_ROTATIONS)]

    def _zdd(self, q: np.ndarray, v: np.ndarray, vdot: np.ndarray, arms: list | None = None) -> np.ndarray:
        """The plate's acceleration, the mean of the three arms' (``arms``: :meth:`_arms` at (q, v))."""
        return sum(r @ (J @ vdot[3 * i:3 * i + 3] + bias)
                   for i, (r, J, bias) in enumerate(arms or self._arms(q, v))) / 3.0

    def accelerations(self, x: np.ndarray, u, tau, f=(0.0, 0.0, 0.0), m=(0.0, 0.0, 0.0)):
        """(vdot, qwdd, plate acceleration) with a force f at the tool tip and a moment m (world).

        The wrist loads the plate with F = -Lambda a + f0 (coupling.plate_load) and the delta's
        plate acceleration is affine in the force on it, a = A + B F: so a = (1 + B Lambda)^-1 (A + B f0)."""
        q, qw, v, qwd = x[:9], x[9:12], x[12:21], x[21:24]
        f, m = np.asarray(f, float), np.asarray(m, float)
        tau_all = np.asarray(tau, float) + W.tip_jacobian(self.pw, qw).T @ f + W.joint_axes(qw).T @ m
        lam, f0 = W.plate_load(self.pw, qw, qwd, tau_all, external_force=f)

        arms = self._arms(q, v)  # the same at each of the five forces below

        def plate(force):
            vdot, _ = D.accelerations(DELTA, q, v, u, force, 20.0)
            return vdot, self._zdd(q, v, vdot, arms)

        a0 = plate(np.zeros(3))[1]
        B = np.column_stack([plate(e)[1] - a0 for e in np.eye(3)])
        a = np.linalg.solve(np.eye(3) + B @ lam, a0 + B @ f0)
        vdot, _ = plate(f0 - lam @ a)
        return vdot, W.accelerations(self.pw, qw, qwd, tau_all, base_accel=a), a

    def derivative(self, x, u, tau, f=(0.0, 0.0, 0.0), m=(0.0, 0.0, 0.0)) -> np.ndarray:
        vdot, qwdd, _ = self.accelerations(x, u, tau, f, m)
        return np.concatenate((x[12:21], x[21:24], vdot, qwdd))

    def tip(self, x) -> np.ndarray:
        return K.wrist_position(DELTA, x[:9]) + np.array(MOUNT) + W.tool_tip(self.pw, x[9:12])

    def start(self, tip, qw) -> np.ndarray:
        z = np.asarray(tip, float) - np.array(MOUNT) - W.tool_tip(self.pw, qw)
        return np.concatenate((K.inverse_kinematics(DELTA, z), qw, np.zeros(12)))


PLANT = Plant(W.WRIST)


def law_for(impedance, tilt=TILT, wrist=W.WRIST):
    return make_assembly_law(DELTA, wrist, MOUNT, hole_frame(tilt), impedance)


def measure(x):
    return tuple(x[0:9:3]), tuple(x[12:21:3]), tuple(x[9:12]), tuple(x[21:24])


def run(law, wrist, x, n, r, phi, f=(0.0, 0.0, 0.0), m=(0.0, 0.0, 0.0)):
    """n samples of the sampled loop from x with a constant tip force f and moment m (world) that
    an ideal sensor reports in the tool frame; returns the plant states after each sample."""
    settings = AssemblySettings(T, True, False)
    state = initial_state(tuple(PLANT.tip(x)))
    program = make_program((0.0, 0.0, -1.2), (0.0, 0.0))
    out = []
    for k in range(n):
        R = W.tool_rotation(x[9:12])
        ft = tuple(R.T @ np.asarray(f)) + tuple(R.T @ np.asarray(m))
        state = sample(law, wrist, settings, program, state, k * T, *measure(x), ft, r, (0.0,) * 3, (0.0,) * 3, phi,
                       (0.0,) * 3, (0.0,) * 3)
        x = solve_ivp(lambda t, s: PLANT.derivative(s, state.u, state.tau, f, m), (0.0, T), x, method="DOP853",
                      rtol=1e-10, atol=1e-12).y[:, -1]
        out.append(x)
    return np.array(out)


def errors(states, r, phi):
    """Tip error and orientation error (rotation vector of R R_ref^T), both in the nominal hole frame."""
    Rh = np.array(hole_frame(TILT)).reshape(3, 3)
    Rref = np.array(orientation_reference(phi, (0.0,) * 3, (0.0,) * 3, TOOL_DOWN)[0]).reshape(3, 3)
    e = np.array([Rh.T @ (PLANT.tip(x) - r) for x in states])
    er = np.array([Rh.T @ np.array(rotation_vector(tuple((W.tool_rotation(x[9:12]) @ Rref.T).ravel())))
                   for x in states])
    return e, er


def test_the_wrist_inverse_dynamics_is_the_numpy_wrist_read_backwards():
    wrist = W.WristParams(damping=0.02)
    w = wrist_constants(wrist)
    rng = np.random.default_rng(7)
    for _ in range(5):
        q, qd, qdd, a, m_ext, f = (rng.normal(size=3) * s for s in (1.0, 3.0, 20.0, 5.0, 0.5, 10.0))
        tau, force = inverse_dynamics(w, wrist_state(w, tuple(q), tuple(qd)), tuple(qd), tuple(qdd), tuple(a),
                                      tuple(m_ext), tuple(f))
        ref_tau = (W.mass_matrix(wrist, q) @ qdd + W.coriolis(wrist, q, qd) + W.gravity(wrist, q, a)
                   + wrist.damping * qd - W.joint_axes(q).T @ m_ext)
        ref_force = W.base_wrench(wrist, q, qd, qdd, a)[0] + f
        # same mechanics, other order of operations: rounding of terms of size ~10 N m / 10 N
        assert np.allclose(tau, ref_tau, rtol=0, atol=1e-12 * (1 + np.abs(ref_tau).max()))
        assert np.allclose(force, ref_force, rtol=0, atol=1e-12 * (1 + np.abs(ref_force).max()))


def test_orientation_references_are_consistent_with_their_rotation():
    # omega and alpha against central differences of R(t) = exp([phi(t)]) R0 (h = 1e-5: error ~h^2 |R'''| ~ 1e-9)
    rng = np.random.default_rng(3)
    p0, v, acc = rng.normal(size=3) * 0.8, rng.normal(size=3), rng.normal(size=3)
    phi = lambda t: tuple(p0 + v * t + 0.5 * acc * t * t)  # noqa: E731
    ref = lambda t: orientation_reference(phi(t), tuple(v + acc * t), tuple(acc), TOOL_DOWN)  # noqa: E731
    h = 1e-5
    Rd = (np.array(ref(h)[0]) - np.array(ref(-h)[0])).reshape(3, 3) / (2 * h)
    S = Rd @ np.array(ref(0.0)[0]).reshape(3, 3).T
    assert np.allclose([S[2, 1], S[0, 2], S[1, 0]], ref(0.0)[1], atol=1e-8)
    assert np.allclose((np.array(ref(h)[1]) - np.array(ref(-h)[1])) / (2 * h), ref(0.0)[2], atol=1e-8)
    # the logarithm inverts Rodrigues' formula below pi
    assert np.allclose(rotation_vector(rotation_from_vector(tuple(p0))), p0, atol=1e-14)


def _fmu_plant_accelerations(x, u, tau, f, m):
    """(vdot, qwdd, plate acceleration) from the DeltaWrist FMU's kernel (delta_wrist.dynamics)."""
    d = np.array(delta_wrist_dynamics.state_derivative(DELTA, wrist_constants(W.WRIST), WristMount(*MOUNT), list(x),
                                                       tuple(u), tuple(tau), tuple(f), tuple(m), 20.0))
    return d[12:21], d[21:24], PLANT._zdd(x[:9], x[12:21], d[12:21])


@pytest.mark.parametrize("plant", ["numpy", "fmu kernel"])
def test_the_law_gives_the_chosen_tip_and_tool_accelerations_exactly(plant):
    # One evaluation on a moving robot with a contact wrench that the sensor reports: the plant's
    # tip and tool accelerations under the law's torques are the impedance's, to rounding
    # (the model is exact; no integrator is involved), for this file's numpy plant and for the
    # DeltaWrist FMU's kernel. Near gimbal lock the wrist's damped inverse changes the angular
    # acceleration but the tip's stays exact.
    accelerations = PLANT.accelerations if plant == "numpy" else _fmu_plant_accelerations
    impedance = gains((4.0, 6.0, 8.0), (300.0, 500.0, 2000.0), (0.03, 0.02, 0.05), (3.0, 2.0, 5.0), zeta=0.7)
    law, w = law_for(impedance)
    Rh = np.array(hole_frame(TILT)).reshape(3, 3)
    rng = np.random.default_rng(11)
    for qw, damped in (((0.3, -0.2, 0.25), False), ((0.1, 1.45, -0.3), True)):
        x = PLANT.start((0.02, -0.01, -1.15), qw)
        jv = K.joint_rates(DELTA, x[:9], (0.05, -0.03, 0.02))
        x[12:21], x[21:24] = jv, (0.4, -0.3, 0.5)
        r, rd, rdd = (0.025, -0.012, -1.148), (0.01, 0.0, -0.02), (0.1, -0.2, 0.3)
        phi, phid, phidd = (0.05, -0.02, 0.3), (0.1, 0.2, -0.1), (1.0, -0.5, 0.2)
        f, m = rng.normal(size=3) * 5, rng.normal(size=3) * 0.2
        R = W.tool_rotation(qw)
        ft = tuple(R.T @ f) + tuple(R.T @ m)
        rot, omega_ref, alpha_ref = orientation_reference(phi, phid, phidd, TOOL_DOWN)
        out = evaluate(law, w, *measure(x), ft, r, rd, rdd, rot, omega_ref, alpha_ref, None)
        assert bool(out.status & STATUS_GIMBAL_DAMPED) == damped
        vdot, qwdd, a_plate = accelerations(x, out.u, out.tau, f, m)
        p = W.tool_tip(W.WRIST, qw)
        J = W.joint_axes(qw)
        omega = J @ x[21:24]
        h = 1e-6  # d/dt J_w along the motion, central difference: error ~h^2
        alpha = J @ qwdd + (W.joint_axes(qw + h * x[21:24]) - W.joint_axes(qw - h * x[21:24])) / (2 * h) @ x[21:24]
        tip_acc = a_plate + np.cross(alpha, p) + np.cross(omega, np.cross(omega, p))
        # the impedance's accelerations in the hole frame
        e = Rh.T @ (PLANT.tip(x) - r)
        ed = Rh.T @ (K.wrist_velocity(DELTA, x[:9], x[12:21]) + np.cross(omega, p) - rd)
        want = np.asarray(rdd) + Rh @ ((Rh.T @ f - np.array(impedance.damping) * ed - np.array(impedance.stiffness) * e)
                                       / np.array(impedance.mass))
        # the central difference of J_w above (rounding eps / h |qd| ~ 5e-11) dominates; the bounds
        # keep a factor of ~20 over what it leaves
        print(f"\n{plant} plant{', damped' if damped else ''}: tip acceleration {np.abs(tip_acc - want).max():.1e} m/s^2")
        assert np.allclose(tip_acc, want, rtol=0, atol=1e-10), (tip_acc, want)
        eR = Rh.T @ np.array(rotation_vector(tuple((R @ np.array(rot).reshape(3, 3).T).ravel())))
        wR = Rh.T @ (omega - np.array(omega_ref))
        want_alpha = np.asarray(alpha_ref) + Rh @ ((Rh.T @ m - np.array(impedance.rot_damping) * wR
                                                    - np.array(impedance.rot_stiffness) * eR)
                                                   / np.array(impedance.inertia))
        if not damped:
            print(f"{plant} plant: tool acceleration {np.abs(alpha - want_alpha).max():.1e} rad/s^2")
            assert np.allclose(alpha, want_alpha, rtol=0, atol=1e-9), (alpha, want_alpha)
        else:  # damped least squares: |qwdd| <= |b| / sigma0 for J_w qwdd = b, and not the exact inverse
            b = want_alpha - (alpha - J @ qwdd)
            assert np.linalg.norm(qwdd) <= np.linalg.norm(b) / 0.2 * (1 + 1e-12)
            assert not np.allclose(alpha, want_alpha, atol=1e-3)


WN = 10.0  # rad/s: the chosen natural frequency of the free-space test, critically damped


def test_free_space_errors_follow_the_chosen_second_order_dynamics():
    # A 5 mm step of the tip reference along the hole's x axis and a 0.05 rad step of the
    # orientation about the hole's y axis (a fixed axis: e_R'' = omega'): each error must be
    # e0 (1 + wn t) exp(-wn t), and every other axis must stay at 0. The 1 kHz zero-order hold
    # with the half-sample lead holds the torque's mean over a sample to second order: the
    # error's deviation from the continuous closed form is of order (wn T)^2 |e0| (1e-4 |e0|);
    # the bound allows that once. A law without the lead would miss it by ~wn T |e0| / 2.
    impedance = gains((5.0, 5.0, 5.0), (5.0 * WN ** 2,) * 3, (0.02,) * 3, (0.02 * WN ** 2,) * 3)
    law, w = law_for(impedance)
    Rh = np.array(hole_frame(TILT)).reshape(3, 3)
    x0 = PLANT.start((0.0, 0.0, -1.15), (0.0, 0.0, 0.0))
    # the references that put the robot 5 mm / 0.05 rad off, in the hole frame
    r = tuple(PLANT.tip(x0) + Rh @ np.array([0.005, 0.0, 0.0]))
    phi = tuple(Rh @ np.array([0.0, 0.05, 0.0]))  # R_ref = exp([phi]) R_down, and the tool starts down
    states = run(law, w, x0, 200, r, phi)
    e, er = errors(states, r, phi)
    t = np.arange(1, 201) * T
    closed = (1.0 + WN * t) * np.exp(-WN * t)
    bound = (WN * T) ** 2
    print(f"\nfree space: 5 mm step {np.abs(e[:, 0] - (-0.005) * closed).max():.1e} m, 0.05 rad tilt "
          f"{np.abs(er[:, 1] - (-0.05) * closed).max():.1e} rad off the closed form (bounds {bound * 0.005:.0e}, "
          f"{bound * 0.05:.0e})")
    assert np.abs(e[:, 0] - (-0.005) * closed).max() <= bound * 0.005
    assert np.abs(er[:, 1] - (-0.05) * closed).max() <= bound * 0.05
    assert np.abs(e[:, 1:]).max() <= bound * 0.005 and np.abs(er[:, [0, 2]]).max() <= bound * 0.05


def test_a_constant_tip_force_and_moment_deflect_by_f_over_k():
    # Constant contact wrench at the tip, measured by an ideal sensor: the robot settles where
    # K e = F and K_r e_R = M, axis by axis in the hole frame (wn = 30 rad/s on every axis;
    # after 0.4 s the transient (1 + wn t) exp(-wn t) is 8.0e-5 of the deflection, the bound 2e-4).
    wn = 30.0
    stiffness, rot_stiffness = np.array([400.0, 800.0, 2000.0]), np.array([2.0, 4.0, 8.0])
    impedance = gains(stiffness / wn ** 2, stiffness, rot_stiffness / wn ** 2, rot_stiffness)
    law, w = law_for(impedance)
    Rh = np.array(hole_frame(TILT)).reshape(3, 3)
    x0 = PLANT.start((0.01, 0.0, -1.15), (0.0, 0.0, 0.0))
    r = tuple(PLANT.tip(x0))
    phi = (0.0, 0.0, 0.0)
    F_h, M_h = np.array([2.0, -3.0, 8.0]), np.array([0.04, -0.03, 0.02])
    states = run(law, w, x0, 400, r, phi, f=Rh @ F_h, m=Rh @ M_h)
    e, er = errors(states, r, phi)
    print(f"\nconstant wrench: deflection {np.abs(e[-1] * stiffness / F_h - 1).max():.1e}, rotation "
          f"{np.abs(er[-1] * rot_stiffness / M_h - 1).max():.1e} relative")
    assert np.allclose(e[-1], F_h / stiffness, rtol=2e-4, atol=0)
    assert np.allclose(er[-1], M_h / rot_stiffness, rtol=2e-4, atol=1e-9)


def test_the_insertion_program_approaches_descends_and_bounds_the_push():
    prog = make_program((0.01, -0.02, -1.2), (0.02, -0.01), approach_height=0.02, approach_time=0.5,
                        insertion_speed=0.02, final_depth=0.03, push_force=15.0, axial_stiffness=1500.0)
    start, start_rot = (0.0, 0.0, -1.1), matmul(rotation_from_vector((0.1, -0.05, 0.2)), TOOL_DOWN)
    axis = np.array(prog.hole).reshape(3, 3)[:, 2]
    top = np.array(prog.hole_top)
    far = tuple(top - 1.0 * axis)  # a tip far down the hole: the push bound never acts
    a = reference(prog, 0.0, far, start, start_rot)
    assert a.phase == PHASE_APPROACH and np.allclose(a.r, start) and np.allclose(a.rotation, start_rot)
    b = reference(prog, 0.5, far, start, start_rot)
    assert b.phase == PHASE_DESCENT and np.allclose(b.r, top + 0.02 * axis, atol=1e-15)
    assert np.allclose(b.rotation, prog.goal_rotation, atol=1e-15) and np.allclose(b.rd, -0.02 * axis)
    # the goal rotation turns the tool's axis (tool z, pointing down) against the hole axis
    assert np.allclose(np.array(prog.goal_rotation).reshape(3, 3)[:, 2], -axis, atol=1e-15)
    # quintic approach: speed and acceleration vanish at both ends, and the midpoint is half way
    mid = reference(prog, 0.25, far, start, start_rot)
    assert np.allclose(mid.r, 0.5 * (np.array(start) + top + 0.02 * axis), atol=1e-15)
    assert np.allclose(reference(prog, 0.5 - 1e-9, far, start, start_rot).rd, 0.0, atol=1e-6)
    c = reference(prog, 3.0, far, start, start_rot)
    assert c.phase == PHASE_HOLD and c.depth == pytest.approx(0.03) and np.allclose(c.rd, 0.0)
    # a tip stuck 5 mm deep: the reference leads it by push_force / K = 10 mm and stands still
    stuck = tuple(top - 0.005 * axis)
    d = reference(prog, 2.4, stuck, start, start_rot)  # the program alone is 18 mm deep by then
    assert d.depth == pytest.approx(0.005 + 15.0 / 1500.0) and np.allclose(d.rd, 0.0)


@pytest.mark.parametrize("call, message", [
    (lambda: gains((0.0, 1.0, 1.0), (1.0,) * 3, (1.0,) * 3, (1.0,) * 3), "mass (0.0, 1.0, 1.0) and inertia"),
    (lambda: gains((1.0,) * 3, (1.0, -2.0, 1.0), (1.0,) * 3, (1.0,) * 3), "stiffness must be three finite numbers"),
    (lambda: make_program((0.0, 0.0, -1.1), (0.0, 0.0), push_force=0.0), "push_force must be > 0"),
    (lambda: make_assembly_law(DELTA, W.WRIST, MOUNT, TOOL_DOWN, gains((1.0,) * 3, (1.0,) * 3, (1.0,) * 3, (1.0,) * 3),
                               sigma0=1.5), "sigma0 must be in (0, 1)"),
])
def test_bad_settings_are_one_clear_line(call, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        call()


def test_status_text_is_readable():
    from deltafmi.physics.assembly import describe_status
    assert describe_status(0) == "ok"
    assert describe_status(STATUS_GIMBAL_DAMPED) == "wrist near gimbal lock: damped inverse"
