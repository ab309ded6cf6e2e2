"""The 6-DOF plant's mechanics (deltafmi.physics.delta_wrist, wrist.kernels) against independent references.

- The wrist's float kernels against the numpy wrist (same formulas, other order of operations:
  rounding of a few eps per term over at most ~30 terms, asserted to 1e-13 of each quantity's scale).
- The plant's accelerations against a DENSE 12-coordinate KKT solve assembled here from the numpy
  delta (mass matrix, Coriolis, gravity, constraint Jacobian and bias) and the numpy wrist, with
  the coupling written as the full mass matrix [[M_d + m Jv^T Jv, Jv^T J_s], [J_s^T Jv, M_w]].
  Both solve the same equations on the closed loops (the states here are on them to rounding);
  the KKT matrix's 2-norm condition number is asserted below 1e4 (measured 2.4e3), so rounding
  leaves < eps * 1e4 = 2.2e-12 of the accelerations' and multipliers' scale: asserted to 5e-12.
- Energy without damping or inputs over 2 s of free swinging (DOP853, rtol 1e-11).
- The generated C gives the kernels' Python bits.
"""
from __future__ import annotations

import dataclasses
import struct

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from deltafmi.builder.codegen import Entry
from deltafmi.builder.codegen.build import compile_unit
from deltafmi.builder.codegen.kernel_types import D, Obj, Vec
from deltafmi.toolchain import NoCompilerError
from deltafmi.physics import delta as d
from deltafmi.physics import delta_wrist as dw
from deltafmi.physics import wrist as w
from deltafmi.physics.delta_wrist import dynamics as dyn
from deltafmi.physics.delta_wrist.params import WristMount
from deltafmi.physics.wrist import kernels as k
from deltafmi.physics.wrist.params import Body, Tool, WristParams

P = d.DeltaParams(payload=0.5, damping=0.0)
#: a wrist with every inertia field in use (products of inertia, off-axis centres of mass)
SKEWED = WristParams(
    links=(Body(0.8, (0.01, -0.005, 0.02), (1.6e-3, 1.2e-3, 1.4e-3, 1e-4, -2e-4, 5e-5)),
           Body(0.5, (-0.004, 0.003, -0.01), (6e-4, 8e-4, 5e-4, -5e-5, 3e-5, 1e-4)),
           Body(0.2, (0.002, 0.001, -0.02), (1.5e-4, 1.5e-4, 1e-4, 2e-5, -1e-5, 3e-5))),
    tool=Tool(0.3, 0.07, 0.12, (2e-4, 2.3e-4, 1.5e-5, 1e-5, 2e-6, -3e-6)), damping=0.02)
WRISTS = {"default": w.WRIST, "skewed": SKEWED}
MOUNT = dw.MOUNT
ZERO = (0.0, 0.0, 0.0)


def _sym(m) -> np.ndarray:
    return np.array([[m[0], m[1], m[2]], [m[1], m[3], m[4]], [m[2], m[4], m[5]]])


def _close(actual, expected, rtol: float, what: str) -> None:
    expected = np.asarray(expected, dtype=float)
    scale = max(np.max(np.abs(expected)), 1e-300)
    np.testing.assert_allclose(np.asarray(actual, dtype=float).reshape(expected.shape), expected, rtol=0.0,
                               atol=rtol * scale, err_msg=what)


@pytest.mark.parametrize("name", sorted(WRISTS))
def test_wrist_kernels_are_the_numpy_wrist(name):
    wp = WRISTS[name]
    c = k.wrist_constants(wp)
    rng = np.random.default_rng(7)
    for _ in range(20):
        q, qd, tau, accel = rng.uniform(-3, 3, 3), rng.normal(0, 4, 3), rng.normal(0, 2, 3), rng.normal(0, 5, 3)
        ql, qdl = tuple(q), tuple(qd)
        g_eff = (-accel[0], -accel[1], -wp.g - accel[2])
        force, _ = w.base_wrench(dataclasses.replace(wp, g=0.0), q, qd, np.zeros(3))  # -b_s at qdd = 0, g = 0
        rows = {
            "R_tool": (k.tool_rotation(ql), w.tool_rotation(q)),
            "tip": (k.tip_position(c, ql), w.tool_tip(wp, q)),
            "J_p": (k.tip_jacobian(c, ql), w.tip_jacobian(wp, q)),
            "J_w": (np.column_stack(k.joint_axes(ql)), w.joint_axes(q)),
            "M": (_sym(k.mass_matrix(c, ql)), w.mass_matrix(wp, q)),
            "h": (k.bias_torques(c, ql, qdl), w.coriolis(wp, q, qd)),
            "g": (k.gravity_torques(c, ql, g_eff), w.gravity(wp, q, accel)),
            "J_s": (k.first_moment_jacobian(c, ql), w.first_moment_jacobian(wp, q)),
            "b_s": (k.first_moment_bias(c, ql, qdl), -force),
            "T": (k.kinetic_energy(c, ql, qdl), w.kinetic_energy(wp, q, qd)),
            "E": (k.energy(c, ql, qdl), w.energy(wp, q, qd)),
            "qdd": (k.accelerations(c, ql, qdl, tuple(tau), tuple(accel)), w.accelerations(wp, q, qd, tau, accel)),
        }
        for what, (kernel, reference) in rows.items():
            _close(kernel, reference, 1e-13, what)


def _random_state(rng, c, spread: float = 1.0) -> np.ndarray:
    """A state on the closed loops, the plate and the wrist moving."""
    tip = rng.uniform([-0.25, -0.25, -1.35], [0.25, 0.25, -1.0])
    qw = rng.uniform(-0.8, 0.8, 3)
    return dw.start_state(P, c, MOUNT, tip, qw, zd=rng.normal(0, 0.5 * spread, 3), qwd=rng.normal(0, 3 * spread, 3))


def dense_kkt(p: d.DeltaParams, wp: WristParams, x, u, tau, f, moment, pole):
    """(xdot, lam) from the 12-coordinate Lagrange equations with the six loop closures, one dense solve."""
    q, qw, v, vw = x[:9], x[9:12], x[12:21], x[21:24]
    Jv = d.virtual_jacobian(p, q)
    jvd_v = sum(r @ d.arm_bias(p, q[3 * i:3 * i + 3], v[3 * i:3 * i + 3])
                for i, r in enumerate(d.ARM_ROTATIONS)) / 3.0
    H = d.constraint_jacobian(p, q)
    m = float(w.link_inertias(wp)[0].sum())
    g_vec = np.array([0.0, 0.0, -wp.g])
    Js = w.first_moment_jacobian(wp, qw)
    b_s = -w.base_wrench(dataclasses.replace(wp, g=0.0), qw, vw, np.zeros(3))[0]
    tau_w = tau + w.tip_jacobian(wp, qw).T @ f + w.joint_axes(qw).T @ moment
    M = np.block([[d.mass_matrix(p, q) + m * Jv.T @ Jv, Jv.T @ Js], [Js.T @ Jv, w.mass_matrix(wp, qw)]])
    Bu = np.zeros(9)
    Bu[[0, 3, 6]] = u
    rhs_d = (Bu - d.coriolis(p, q, v) - p.damping * v - d.gravity(p, q)
             + Jv.T @ (m * g_vec - m * jvd_v - b_s + f))
    rhs_w = tau_w - w.coriolis(wp, qw, vw) - wp.damping * vw + Js.T @ (g_vec - jvd_v)
    H12 = np.hstack([H, np.zeros((6, 3))])
    kkt = np.block([[M, -H12.T], [H12, np.zeros((6, 6))]])
    rhs = np.concatenate([rhs_d, rhs_w, -d.constraint_bias(p, q, v) - 2 * pole * H @ v
                          - pole ** 2 * d.constraint(p, q)])
    sol = np.linalg.solve(kkt, rhs)
    return np.concatenate([v, vw, sol[:12]]), sol[12:], np.linalg.cond(kkt)


@pytest.mark.parametrize("name", sorted(WRISTS))
def test_accelerations_are_the_dense_kkt_solve(name):
    wp = WRISTS[name]
    c = k.wrist_constants(wp)
    rng = np.random.default_rng(11)
    worst = 0.0
    for _ in range(10):
        x = _random_state(rng, c)
        u, tau = rng.normal(0, 30, 3), rng.normal(0, 1, 3)
        f, moment = rng.normal(0, 20, 3), rng.normal(0, 2, 3)
        xdot = dw.state_derivative(P, c, MOUNT, x.tolist(), tuple(u), tuple(tau), tuple(f), tuple(moment), 5.0)
        out = dw.plant_outputs(P, c, MOUNT, x.tolist(), tuple(u), tuple(tau), tuple(f), tuple(moment), 5.0)
        ref, lam, cond = dense_kkt(P, wp, x, u, tau, f, moment, 5.0)
        assert cond < 1e4
        _close(xdot[12:], ref[12:], 5e-12, "accelerations")
        _close(out[11], lam, 5e-12, "lambda")
        worst = max(worst, np.abs(np.asarray(xdot[12:]) - ref[12:]).max() / np.abs(ref[12:]).max(),
                    np.abs(np.asarray(out[11]) - lam).max() / np.abs(lam).max())
    print(f"\n{name}: dense KKT, worst relative error {worst:.1e}")


def test_wrist_load_is_the_coupling_modules():
    """Lambda and f0 against wrist.coupling.plate_load (numpy), a tip force and moment included."""
    c = k.wrist_constants(SKEWED)
    rng = np.random.default_rng(5)
    for _ in range(10):
        qw, vw, tau = rng.uniform(-1, 1, 3), rng.normal(0, 3, 3), rng.normal(0, 1, 3)
        f, moment = rng.normal(0, 10, 3), rng.normal(0, 1, 3)
        load = dw.wrist_load(c, tuple(qw), tuple(vw), tuple(tau), tuple(f), tuple(moment))
        tau_w = tau + w.tip_jacobian(SKEWED, qw).T @ f + w.joint_axes(qw).T @ moment
        ref = w.plate_load(SKEWED, qw, vw, tau_w, external_force=f)
        _close(_sym(load.apparent_mass), ref.apparent_mass, 1e-13, "Lambda")
        _close(load.force, ref.force, 1e-12, "f0")


def test_holding_torques_hold_the_pose_still():
    c = k.wrist_constants(SKEWED)
    x = dw.start_state(P, c, MOUNT, [0.15, -0.1, -1.25], [0.4, -0.3, 0.2])
    u, tau = dw.holding_torques(P, c, x)
    xdot = dw.state_derivative(P, c, MOUNT, x.tolist(), tuple(u), tuple(tau), ZERO, ZERO, 5.0)
    # gravity-scale accelerations are ~10 (delta) to ~1e3 (wrist rotors) rad/s^2: zero to rounding
    assert np.max(np.abs(xdot)) < 1e-10
    ref, _, _ = dense_kkt(P, SKEWED, x, u, tau, np.zeros(3), np.zeros(3), 5.0)
    assert np.max(np.abs(ref)) < 1e-9


def test_start_state_places_the_tip_and_orientation():
    c = k.wrist_constants(w.WRIST)
    R = w.tool_rotation([0.3, -0.4, 0.5])
    x = dw.start_state(P, c, MOUNT, [0.1, 0.2, -1.1], R, qwd=[1.0, 0.0, 0.0])
    out = dw.plant_outputs(P, c, MOUNT, x.tolist(), ZERO, ZERO, ZERO, ZERO, 5.0)
    np.testing.assert_allclose(out[6], [0.1, 0.2, -1.1], atol=1e-12)
    np.testing.assert_allclose(np.reshape(out[8], (3, 3)), R, atol=1e-14)
    np.testing.assert_allclose(out[10], np.add(out[4], [0.0, 0.0, -0.05]), atol=1e-15)  # O = z + mount
    assert out[12] < 1e-13  # loops closed
    # the tip moves with the spin about a_1 = e_z only: omega x p
    np.testing.assert_allclose(out[7], np.cross([0.0, 0.0, 1.0], np.subtract(out[6], out[10])), atol=1e-12)
    with pytest.raises(ValueError, match=r"tool tip \(0\.0000, 0\.0000, -1\.7000\) m is out of reach.*"
                                         r"plate centre.*workspace"):
        dw.start_state(P, c, MOUNT, [0.0, 0.0, -1.7], ZERO)
    with pytest.raises(ValueError, match="tool orientation"):
        dw.start_state(P, c, MOUNT, [0.0, 0.0, -1.1], [0.0, 0.0])


def test_projection_closes_the_loops_and_keeps_the_wrist_momenta():
    c = k.wrist_constants(SKEWED)
    rng = np.random.default_rng(2)
    x = _random_state(rng, c)
    x[:9] += rng.normal(0, 1e-5, 9)
    x[12:21] += rng.normal(0, 1e-4, 9)
    y = dw.project_to_constraints(P, c, x)
    assert dw.loop_residual(P, y) < 1e-13
    assert np.max(np.abs(d.constraint_jacobian(P, y[:9]) @ y[12:21])) < 1e-12
    np.testing.assert_array_equal(y[9:12], x[9:12])

    def momenta(s):  # dT/dvw = M vw + J_s^T zd
        qw = s[9:12]
        return (w.mass_matrix(SKEWED, qw) @ s[21:24]
                + w.first_moment_jacobian(SKEWED, qw).T @ d.wrist_velocity(P, s[:9], s[12:21]))
    _close(momenta(y), momenta(x), 1e-12, "wrist momenta")
    assert np.max(np.abs(y - x)) < 1e-3  # a correction, not another state


def test_energy_is_conserved_in_free_motion():
    """No damping, no inputs: the delta falls and the wrist swings for 2 s (the plate down to
    within 1 mm of the all-stretched height, the wrist within 3 degrees of gimbal lock).
    DOP853 at rtol 1e-11 keeps each step's local error below 1e-11 of the state; summed without
    cancellation over the n accepted steps the energy error is at most n * 1e-11 of the energy's
    scale (the peak kinetic energy plus the potential's range): asserted, and <= 1e-7."""
    c = k.wrist_constants(w.WRIST)
    x0 = dw.start_state(P, c, MOUNT, [0.1, -0.05, -1.2], [0.2, 0.9, -0.3], zd=[0.3, -0.2, 0.1], qwd=[2.0, -3.0, 4.0])
    zero = (0.0, 0.0, 0.0)

    def rhs(t, x):
        return dw.state_derivative(P, c, MOUNT, x.tolist(), zero, zero, zero, zero, 5.0)
    sol = solve_ivp(rhs, (0.0, 2.0), x0, method="DOP853", rtol=1e-11, atol=1e-12, dense_output=True)
    assert sol.success
    outs = [dw.plant_outputs(P, c, MOUNT, x.tolist(), zero, zero, zero, zero, 5.0) for x in sol.y.T]
    energy = np.array([o[13] for o in outs])
    kinetic = [energy[i] - _potential(c, sol.y[:, i]) for i in range(len(energy))]
    scale = max(kinetic) + np.ptp([_potential(c, x) for x in sol.y.T])
    drift = np.max(np.abs(energy - energy[0])) / scale
    steps = len(sol.t) - 1
    print(f"\nfree motion: energy drift {np.max(np.abs(energy - energy[0])):.1e} J of a {scale:.0f} J scale")
    assert drift < min(steps * 1e-11, 1e-7), (drift, steps)
    assert min(o[14] for o in outs) < 0.05  # |cos q2| < 0.05: within 3 degrees of gimbal lock
    assert max(o[12] for o in outs) < 1e-9  # loops stay closed (Baumgarte, from closed)


def _potential(c, x) -> float:
    """The plant's potential energy: its energy at rest in the same pose."""
    rest = np.array(x, dtype=float)
    rest[12:] = 0.0
    return dw.energy(P, c, MOUNT, rest)


def bits(value) -> list:
    """Every number of a (nested) result as its IEEE-754 bits."""
    if isinstance(value, (tuple, list, np.ndarray)):
        return [b for v in value for b in bits(v)]
    return [struct.unpack("<q", struct.pack("<d", value))[0]]


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    args = [Obj(d.DeltaParams), Obj(k.WristConstants), Obj(WristMount), Vec(24), Vec(3), Vec(3), Vec(3), Vec(3), D]
    entries = [Entry("derivatives", dyn.state_derivative, args), Entry("outputs", dyn.plant_outputs, args)]
    try:
        return compile_unit(entries, tmp_path_factory.mktemp("delta_wrist"), identities=("_as_list",))
    except NoCompilerError as exc:
        pytest.skip(f"no C compiler: {exc}")


def test_generated_c_gives_the_python_bits(compiled):
    c = k.wrist_constants(SKEWED)
    mount = WristMount(0.01, -0.02, -0.06)
    rng = np.random.default_rng(4)
    for _ in range(5):
        x = _random_state(rng, c)
        x[:9] += rng.normal(0, 1e-6, 9)  # off the loops too
        inputs = [tuple(rng.normal(0, s, 3)) for s in (30.0, 1.0, 20.0, 2.0)]
        for role, func in (("derivatives", dyn.state_derivative), ("outputs", dyn.plant_outputs)):
            python = func(P, c, mount, x.tolist(), *inputs, 5.0)
            assert bits(compiled.call(role, P, c, mount, x.tolist(), *inputs, 5.0)) == bits(python), role


def test_peg_tool_is_a_solid_cylinder():
    tool = dw.peg_tool(0.25, 0.1, 0.01, 0.13)
    assert tool.com == pytest.approx(0.08) and tool.tip == 0.13
    assert tool.inertia[0] == pytest.approx(0.25 * (3e-4 + 1e-2) / 12) and tool.inertia[2] == pytest.approx(1.25e-5)
    with pytest.raises(ValueError, match="tool tip distance"):
        dw.peg_tool(0.25, 0.1, 0.01, 0.05)
    with pytest.raises(ValueError, match="rotor inertia 2"):
        dw.wrist_params((1e-4, 0.0, 1e-4), tool, 9.81, 0.0)
    assert dataclasses.replace(dw.wrist_params((1e-4,) * 3, tool, 9.81, 0.1), damping=0.0).tool == tool
