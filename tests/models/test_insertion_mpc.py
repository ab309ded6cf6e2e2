"""The InsertionMpc FMU planning an AssemblyController's reference for the peg-in-hole, beside the
impedance controller's own program (peg_in_hole_mpc.yaml): model by ``deltafmi linearize`` of the
scenario's loop, OSQP, real FMUs through the master."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from deltafmi.physics.control import LinearMPC, zoh
from deltafmi.physics.control.insertion import BALANCING_SCALE, InsertionMpc, InsertionTask, polynomial_shaping
from deltafmi.physics.control.model_file import LinearModelFile
from deltafmi.physics.control.reduction import balanced_truncation, lift, output_coordinates
from deltafmi.apps.insertion_mpc_model import keep_components, write_model
from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "peg_in_hole_mpc.yaml"
F_MAX = 15.0                      # N, the scenario's force_limit
K_AX, M_AX = 1500.0, 10.0         # the impedance along the hole (N/m, kg)
K_LAT, M_LAT = 300.0, 5.0         # sideways


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    """The scenario's loop (controller + plant) linearized by the CLI, as the scenario's comment says."""
    return write_model(SCENARIO, tmp_path_factory.mktemp("insertion") / "peg_in_hole_mpc_model")


def run(folder: Path, model: Path, impedance: bool = True, stop: float = 3.0, start: tuple = (),
        outputs: tuple = (), **mpc: object) -> dict:
    spec = yaml.safe_load(SCENARIO.read_text())
    spec["experiment"]["stop"] = stop
    spec["outputs"] += list(outputs)
    if start:  # the tip, the controller's reference and the MPC's, somewhere else
        spec["components"]["plant"]["parameters"]["tip0"] = list(start)
        spec["components"]["controller"]["parameters"]["r"] = list(start)
        mpc["start"] = list(start)
    spec["components"]["mpc"]["parameters"].update(linear_model=str(model), **mpc)
    del spec["components"]["mpc"]["resources"]
    if not impedance:
        spec = keep_components(spec, ("mpc", "controller", "plant"))
    path = folder / "peg_in_hole_mpc.yaml"
    path.write_text(yaml.safe_dump(spec))
    out = path.with_suffix(".csv")
    Master(resolve_system(load_scenario(path)), result=out).run()
    return columns(out)


def figures(c: dict, plant: str) -> dict:
    """Insertion time (success latched), peak axial and total contact force, success."""
    t = c["time"]
    F = np.column_stack([c[f"{plant}.contact_force[{k}]"] for k in (1, 2, 3)])
    success = c[f"{plant}.success"]
    return {"time": float(t[np.argmax(success > 0)]) if success.max() > 0 else math.inf,
            "axial": float(np.abs(F[:, 2]).max()), "total": float(np.linalg.norm(F, axis=1).max()),
            "success": int(success[-1])}


def test_lift_is_the_one_step_map_stepped_with_the_reference_polynomial():
    """lift(Phi, Gamma, n, T) against n steps of x+ = Phi x + Gamma T(j) v: the same products in
    another order, so equal to round-off (1e-12 of the entries)."""
    rng = np.random.default_rng(1)
    Phi, Gamma = 0.3 * rng.normal(size=(5, 5)), rng.normal(size=(5, 9))
    shaping = polynomial_shaping(1e-3, 1)
    A, B = lift(Phi, Gamma, 10, shaping)
    x0, v = rng.normal(size=5), rng.normal(size=9)
    x = x0.copy()
    for j in range(10):
        x = Phi @ x + Gamma @ shaping(j) @ v
    np.testing.assert_allclose(A @ x0 + B @ v, x, rtol=0.0, atol=1e-12 * np.abs(x).max())


def test_balanced_truncation_keeps_the_glover_bound_and_drops_unreachable_modes():
    """A random stable system beside modes no input reaches: truncated to the reachable order it
    is exact (the dropped Hankel singular values are round-off, the frequency responses agree to
    1e-9); truncated further, the frequency response's error stays below 2 sum of the dropped
    values (Enns, Glover), checked on 400 frequencies; in output coordinates, C = 1."""
    rng = np.random.default_rng(2)
    A1 = rng.normal(size=(6, 6))
    A1 *= 0.9 / np.max(np.abs(np.linalg.eigvals(A1)))
    A = np.block([[A1, np.zeros((6, 3))], [np.zeros((3, 6)), 0.5 * np.eye(3)]])
    B = np.vstack([rng.normal(size=(6, 2)), np.zeros((3, 2))])
    C = rng.normal(size=(3, 9))
    w = np.linspace(0.0, np.pi, 400)

    def response(A, B, C):
        return np.array([C @ np.linalg.solve(np.exp(1j * wk) * np.eye(len(A)) - A, B) for wk in w])
    full = response(A, B, C)
    Ar, Br, Cr, hsv = balanced_truncation(A, B, C, 6)
    assert hsv[6:].max() < 1e-10 * hsv[0]
    assert np.abs(response(Ar, Br, Cr) - full).max() < 1e-9 * np.abs(full).max()
    Ar, Br, Cr, hsv = balanced_truncation(A, B, C, 3)
    error = np.array([np.linalg.norm(e, 2) for e in response(Ar, Br, Cr) - full])
    assert error.max() <= 2.0 * hsv[3:].sum()
    Az, Bz = output_coordinates(Ar, Br, Cr)
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(Az)), np.sort_complex(np.linalg.eigvals(Ar)),
                               rtol=1e-10)


def test_per_stage_limits_are_the_constructors_when_equal_and_bind_where_lowered():
    """A double integrator pushed towards 1 m with x' <= 0.5 m/s: per-stage limits equal to the
    constructor's give the same plan (to OSQP's 1e-8); lowering the limit at stages 5..N to
    0.1 m/s makes the plan keep it there (soft, exact penalty: to the tolerance)."""
    stage = zoh(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), 0.1)
    kw = dict(C=np.eye(2), D=np.zeros((2, 1)), g=np.zeros(2), Q=np.diag([10.0, 0.0]), R=np.eye(1) * 1e-2, N=10,
              u_min=[-2.0], u_max=[2.0], H=np.array([[0.0, 1.0]]), hi=[0.5], rho_l=100.0, eps=1e-9, polish=False)
    a, b = LinearMPC(stage, **kw), LinearMPC(stage, **kw)
    x0, ref = np.zeros(2), np.array([1.0, 0.0])
    np.testing.assert_allclose(a.solve(x0, ref).u, b.solve(x0, ref, hi=np.full((10, 1), 0.5)).u, atol=1e-8)
    hi = np.full((10, 1), 0.5)
    hi[4:] = 0.1
    plan = LinearMPC(stage, **kw).solve(x0, ref, hi=hi)
    assert plan.x[1:, 1].max() <= 0.5 + 1e-6 and plan.x[5:, 1].max() <= 0.1 + 1e-6
    assert plan.x[1:5, 1].max() > 0.2  # faster before, where the bound is 0.5


def test_the_linearized_loop_has_the_designed_impedance_poles(model):
    """Feedback linearization makes each hole axis M e'' + D e' + K e = 0 with D = 2 sqrt(K M): a
    double pole at -sqrt(K/M). The linearization's slowest controllable poles are those (axial
    sqrt(150), lateral sqrt(60) rad/s); the 1 ms sampling splits a double root z0 by
    ~sqrt(|perturbation|), so the pair's modulus is compared, to 1e-3 (measured 1e-4). The
    MPC's reduced model (10 ms samples, six states) keeps six Hankel singular values two orders
    above the rest (the sampling's one-step states) and ten orders above the Baumgarte modes, and
    its frequency response stays within Glover's bound of the whole loop's."""
    m = LinearModelFile.read(str(model))
    s = np.log(np.linalg.eigvals(m.A).astype(complex)) / m.sample_time
    moduli = np.abs(s[np.isfinite(s)])
    for k, mass in ((K_AX, M_AX), (K_LAT, M_LAT)):
        assert np.min(np.abs(moduli - math.sqrt(k / mass))) < 1e-3 * math.sqrt(k / mass)
    mpc = InsertionMpc(m, task())
    assert mpc.hankel[6] < 0.03 * mpc.hankel[5]
    assert mpc.hankel[12] < 1e-5 * mpc.hankel[5]
    # the six-state stage against the whole loop lifted to 10 ms (inputs scaled as balanced):
    # frequency-response error within Glover's bound 2 sum of the dropped Hankel values
    scale = np.repeat(BALANCING_SCALE, 3)
    Al, Bl = lift(m.A, m.B, 10, polynomial_shaping(m.sample_time, 1))
    Az, Bz = mpc.stage.A[:6, :6], np.hstack([mpc.stage.A[:6, 6:], mpc.stage.B[:6]])
    worst = 0.0
    for w in np.linspace(0.0, np.pi, 200):
        z = np.exp(1j * w)
        full = m.C @ np.linalg.solve(z * np.eye(len(Al)) - Al, Bl * scale)
        reduced = np.linalg.solve(z * np.eye(6) - Az, Bz * scale)
        worst = max(worst, np.linalg.norm(full - reduced, 2))
    print(f"\nreduced loop: Hankel values {mpc.hankel[:7].round(5)}, response error {worst:.2e} <= "
          f"{2 * mpc.hankel[6:].sum():.2e}")
    assert worst <= 2.0 * mpc.hankel[6:].sum()


def test_the_shipped_model_is_what_the_tool_makes_now(model):
    """The shipped peg_in_hole_mpc_model.npz against a fresh linearization: compared through the
    MPC's stage model, which the input-output map fixes whatever basis the controller's
    realization took (the output coordinates are unique). A changed robot or impedance moves it by
    its own relative change (1e-3 and more); round-off and the realization's differences stay
    near 1e-9 of the largest entry: asserted to 1e-6."""
    fresh = InsertionMpc(LinearModelFile.read(str(model)), task()).stage
    shipped = InsertionMpc(LinearModelFile.read(str(SCENARIO.with_name("peg_in_hole_mpc_model.npz"))), task()).stage
    for a, b in ((fresh.A, shipped.A), (fresh.B, shipped.B)):
        np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-6 * np.abs(b).max())


@pytest.mark.parametrize("change, message", [
    ({"contact_speed": 0.0}, r"^contact_speed must be a finite number > 0, got 0.0$"),
    ({"horizon": 0}, r"^horizon must be >= 1 sample, got 0$"),
    ({"sample_period": 0.0105}, r"^sample_period 0.0105 s must be a multiple of the linearization's step 0.001 s$"),
    ({"solver": "qpoases"}, r"^solver must be 'daqp' or 'osqp', got 'qpoases'$"),
])
def test_bad_settings_are_one_line_naming_the_setting(model, change, message):
    with pytest.raises(ValueError, match=message):
        InsertionMpc(LinearModelFile.read(str(model)), task(**change))


def test_a_missing_linear_model_is_named_with_the_command_that_makes_it(tmp_path, monkeypatch):
    from deltafmi.models.insertion_mpc import InsertionMpc as Component
    monkeypatch.chdir(tmp_path)
    controller = Component()
    controller.linear_model = "missing.npz"
    with pytest.raises(ValueError, match=r"linear_model 'missing.npz' not found .*insertion_mpc_model SCENARIO"):
        controller.initialize(0.0)


def test_the_mpc_fmu_carries_no_co_simulation_code():
    """InsertionMpc reads its model with numpy: its FMU carries none of deltafmi.master (fmpy's)."""
    from deltafmi.builder.packager import runtime_modules
    carried = runtime_modules(Path(__file__).resolve().parents[2] / "fmu_src" / "insertion_mpc.py")
    assert "deltafmi.physics.control.insertion" in carried
    assert not [name for name in carried if name.startswith("deltafmi.master")]


def task(**changes) -> InsertionTask:
    values = dict(hole_top=[0.0, 0.0, -1.2], hole_axis=[0.0, 0.0, 1.0], goal_depth=0.035, axial_stiffness=K_AX,
                  axial_damping=2.0 * math.sqrt(K_AX * M_AX), force_limit=F_MAX, speed_limit=0.1,
                  contact_speed=0.01, bore_speed=0.03, contact_zone=(0.002, 0.003), acceleration_limit=2.0,
                  sample_period=0.01, horizon=30)
    values.update(changes)
    return InsertionTask(**values)


def test_mpc_and_impedance_alone_both_insert_side_by_side(tmp_path, model):
    """Nominal case (hole 1.8 mm off, 1 degree tilt): both succeed. The MPC arrives at the chamfer
    at its 10 mm/s contact speed (the program at 20 mm/s) and its planned push never passes
    force_limit; the contact forces it meets stay under it too. Its planned axial push is a
    plan of the soft limit, which OSQP meets to its tolerance (1e-5 relative): asserted to 1e-3 N."""
    c = run(tmp_path, model)
    mpc, imp = figures(c, "plant"), figures(c, "impedance_plant")
    print(f"\n{'':22}{'MPC + impedance':>18}{'impedance alone':>18}")
    for key, label in (("time", "insertion time (s)"), ("axial", "peak axial force (N)"),
                       ("total", "peak total force (N)"), ("success", "success")):
        print(f"{label:22}{mpc[key]:18.3f}{imp[key]:18.3f}")
    solve = c["mpc.solve_time"][::10]
    print(f"QP solve median {np.median(solve) * 1e3:.2f} ms, p99 {np.percentile(solve, 99) * 1e3:.2f} ms")
    assert mpc["success"] == 1 and imp["success"] == 1
    assert c["mpc.planned_force"].max() <= F_MAX + 1e-3
    assert mpc["axial"] <= F_MAX
    assert mpc["time"] < imp["time"]



def test_the_approach_moves_sideways_and_the_reference_leaves_the_centring_to_the_chamfer(tmp_path, model):
    """From 36 mm beside the nominal axis the MPC brings the tip over the nominal hole before the
    contact zone, within the chamfer's capture that the hole's true offset leaves (chamfer 2 mm +
    clearance 0.1 mm - offset 1.8 mm = 0.3 mm), and inserts. In the bore its reference stays on
    the NOMINAL axis while the tip sits on the true one (1.8 mm off): the tip's lateral position
    has no cost, so the reference does not push it back against the bore (the impedance's
    300 N/m does that alone)."""
    c = run(tmp_path, model, impedance=False, start=(0.03, -0.02, -1.17))
    depth = c["plant.depth"]
    lateral = np.hypot(c["plant.tip[1]"], c["plant.tip[2]"])
    reference = np.hypot(c["mpc.r[1]"], c["mpc.r[2]"])
    arrive = np.argmax(depth > -0.002)
    inside = depth > 0.005
    print(f"\nsideways: tip {lateral[arrive] * 1e3:.3f} mm from the nominal axis entering the zone, reference "
          f"{reference[inside].max() * 1e6:.1f} um from it in the bore, success {c['plant.success'][-1]:.0f} at "
          f"{figures(c, 'plant')['time']:.3f} s")
    assert lateral[arrive] < 3e-4
    assert reference[inside].max() < 1e-4
    assert c["plant.success"][-1] == 1


def test_mpc_pushing_on_the_bottom_holds_the_force_limit(tmp_path, model):
    """Goal 20 mm below the 40 mm bore's bottom: the tip meets the bottom (at bottom_speed), the
    sensor's push-back blocks the prediction, and the MPC's lead grows (at contact_speed) until the
    planned push K_ax lead + D_ax lead rate reaches force_limit, then stays.

    What the controller states: its plan's push (every stage 1..N) <= force_limit. The plan is
    polished (the active set's exact solution), so that holds to round-off, not to where OSQP's
    iterations stopped; asserted to 1e-3 N (the unpolished samples meet the row to OSQP's
    1e-5 + 1e-5 |row|). The push at the sample instants (the measured state's F_ax) is the plan's
    first stage plus what the blocked model leaves out, the tip's axial motion: K_ax times its
    displacement over a sample and D_ax times its velocity, bounded by the largest of both over
    the hold measured in the same run (the contact's compliance and its ripple under the 1 kHz
    sampled force feedback; machine-dependent, and not the MPC's). At rest the impedance's static
    force is K_ax lead exactly (feedback linearization on the sensed force); under F_max the tip
    sinks by at most F_max / k (k = 2e5 N/m, one penalty point; more points are stiffer), a lead
    error of K_ax F_max / k = 0.1125 N: the mean contact force over the last 0.2 s is within that
    of F_max."""
    c = run(tmp_path, model, impedance=False, stop=4.4, goal_depth=0.06, outputs=["plant.tip_velocity[3]"])
    compliance = K_AX * F_MAX / 2e5
    t = c["time"]
    Fz = np.abs(c["plant.contact_force[3]"])
    late = Fz[t > t[-1] - 0.2]
    hold = t >= t[np.argmax(c["mpc.planned_force"] >= F_MAX - 0.01)]
    speed = np.abs(c["plant.tip_velocity[3]"][hold]).max()
    shift = np.ptp(c["plant.tip[3]"][hold])  # the tip's axial travel over the hold (>= over one sample)
    ripple = K_AX * shift + 2.0 * math.sqrt(K_AX * M_AX) * speed
    print(f"\nbottom: contact force over the last 0.2 s {late.mean():.4f} N (from {late.min():.3f} to "
          f"{late.max():.3f}), planned push max {c['mpc.planned_force'].max():.6f} N, measured push max "
          f"{c['mpc.axial_force'].max():.4f} N (bound {F_MAX + ripple:.4f} N: tip travel {shift * 1e6:.2f} um, "
          f"speed {speed * 1e3:.3f} mm/s over the hold), peak at the first touch {Fz.max():.2f} N")
    assert c["mpc.planned_force"].max() <= F_MAX + 1e-3
    assert c["mpc.axial_force"][hold].max() <= F_MAX + ripple + 1e-3
    assert late.mean() == pytest.approx(F_MAX, abs=compliance)
    assert c["plant.success"][-1] == 1
