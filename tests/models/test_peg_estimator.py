"""The PegEstimator FMU: validation, and peg_estimation.yaml (the peg-in-hole insertion with a hole
1.8 mm off and 1 degree tilted from the nominal one) run by the master: the estimated contact
wrench against the plant's true contact_force/contact_moment in free space, at the impact on the
chamfer and in steady contact in the bore, and the hole's estimated x, y and tilt against the
plant's hole_position/hole_tilt, without and with seeded encoder noise. Figures measured when
this was written are quoted next to each bound."""
from __future__ import annotations

from pathlib import Path

import fmpy
import numpy as np
import pytest
import yaml
from fmpy.validation import validate_fmu

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "peg_estimation.yaml"
STOP = 2.2  # s: free approach, impact on the chamfer at ~1.015 s, sliding in the bore from ~1.3 s


@pytest.fixture(scope="module")
def estimator(build_fmu_from_src) -> Path:
    return build_fmu_from_src("peg_estimator.py")


def test_estimator_fmu_validates(estimator):
    assert validate_fmu(str(estimator)) == []
    md = fmpy.read_model_description(str(estimator))
    assert md.modelExchange and md.coSimulation


def run(folder: Path, **estimator: object) -> dict:
    """peg_estimation.yaml up to STOP with ``estimator`` merged into the estimator's parameters."""
    spec = yaml.safe_load(SCENARIO.read_text())
    spec["components"]["estimator"]["parameters"].update(estimator)
    spec["experiment"]["stop"] = STOP
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    out = path.with_suffix(".csv")
    Master(resolve_system(load_scenario(path)), result=out).run()
    return columns(out)


def errors(c: dict) -> dict:
    """The estimates' errors against the plant's truth, per phase (N, N m, m, rad)."""
    t = c["time"]
    on_grid = np.abs(t / 1e-3 - np.round(t / 1e-3)) < 1e-6  # the sample instants (not event rows)
    c = {k: v[on_grid] for k, v in c.items()}
    t = c["time"]
    F = np.array([c[f"plant.contact_force[{i}]"] for i in (1, 2, 3)]).T
    M = np.array([c[f"plant.contact_moment[{i}]"] for i in (1, 2, 3)]).T
    eF = np.array([c[f"estimator.force[{i}]"] for i in (1, 2, 3)]).T - F
    eM = np.array([c[f"estimator.moment[{i}]"] for i in (1, 2, 3)]).T - M
    touch = int(np.argmax(c["plant.active_contacts"] > 0))
    free, impact, steady = slice(100, touch), slice(touch, touch + 300), t > STOP - 0.5

    def rms(e):
        return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))

    std = np.array([c[f"estimator.force_std[{i}]"] for i in (1, 2, 3)]).T
    impulse = np.trapezoid(F[impact], t[impact], axis=0)
    hole = np.array([c["estimator.hole[1]"][-1], c["estimator.hole[2]"][-1]])
    true_hole = np.array([c["plant.hole_position[1]"][-1], c["plant.hole_position[2]"][-1]])
    tilt = np.array([c["estimator.tilt[1]"][-1], c["estimator.tilt[2]"][-1]])
    true_tilt = np.array([c["plant.hole_tilt[1]"][-1], c["plant.hole_tilt[2]"][-1]])
    return dict(
        touch=float(t[touch]), false_contact=bool(np.any(c["estimator.in_contact"][:touch] > 0)),
        free_force=rms(eF[free]), free_moment=rms(eM[free]),
        impact_peak=float(np.linalg.norm(F[impact], axis=1).max()),
        impact_error=float(np.linalg.norm(eF[impact], axis=1).max()),
        impulse=float(np.linalg.norm(impulse)),
        impulse_error=float(np.linalg.norm(np.trapezoid(eF[impact], t[impact], axis=0))),
        steady_force=rms(eF[steady]), steady_moment=rms(eM[steady]),
        steady_level=float(np.linalg.norm(F[steady], axis=1).mean()),
        within_3_std=float(np.mean(np.abs(eF[steady]) < 3.0 * std[steady])),
        hole=float(np.linalg.norm(hole - true_hole)), hole_std=float(c["estimator.hole_std[1]"][-1]),
        tilt=float(np.abs(tilt - true_tilt).max()), offset=float(np.linalg.norm(true_hole)))


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    return errors(run(tmp_path_factory.mktemp("clean")))


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    return errors(run(tmp_path_factory.mktemp("noisy"), sensor_noise=2e-7, seed=7))


def test_without_noise_the_estimates_match_the_plant(clean):
    """The estimator's model is the plant's. Free space: force error 0.026 N rms (measured; the
    plant's BDF at rtol 1e-6 against the filter's RK4), moment 5e-12 N m, no false contact. The
    impact on the chamfer is a train of ~5 ms bounces up to 10.3 N (the controller's force
    feedback no longer takes the half-sample lead): the force's walk smooths them, but the
    momentum they exchange, the impulse over 0.3 s (0.458 N s), is right to 4.3 % (measured;
    between detected manoeuvres the wrench walks at its steady levels, set for the bore, and lags
    the bounces until the joint angles' innovations flag them; bound 5 %). Sliding in the bore
    (0.57 N of wall and friction forces, the last 0.5 s): force error 0.015 N rms, moment 6.2e-4 N m
    (measured: the integrated walk, 0.7 N/s^2/sqrt(Hz) on the force's rate as the plant's bore
    force varies, lags the axial force where its ramp turns, at ~1.87 s; 0.0045 N and 1.8e-4 N m
    with the previous walk, 1 N/s/sqrt(Hz), 24 times the bore's rate and its NEES 0.5); the
    bounds are 2 to 2.5 times these."""
    print(f"free force error {clean['free_force']:.4f} N rms, impulse error "
          f"{100 * clean['impulse_error'] / clean['impulse']:.2f} % of {clean['impulse']:.3f} N s, bore force error "
          f"{clean['steady_force']:.4f} N rms, moment {clean['steady_moment']:.2e} N m")
    assert clean["touch"] == pytest.approx(1.012, abs=0.01)  # the scenario as measured
    assert not clean["false_contact"] and clean["free_force"] < 0.06 and clean["free_moment"] < 1e-6
    assert clean["impulse_error"] < 0.05 * clean["impulse"]
    assert clean["steady_force"] < 0.03 and clean["steady_moment"] < 1.5e-3


def test_without_noise_the_hole_and_the_impact_are_found(clean):
    """The hole, 1.8 mm off the nominal, to within 5 um and its 1-degree tilt to 1 mrad (measured:
    1.8 um and 0.06 mrad: the law's updates on exact data, the hole's slow random walk
    letting the estimate leave where the first chamfer bounces put it); the worst force error
    during the bounces below their peak, the estimate never overshooting past the truth by more
    than the truth's own size (measured 0.89 of the peak: a 5 ms bounce is over before the walk,
    at its steady level until the detector flags the bounce, follows it; 0.70 with the previous
    steady level, 100 times the bore's)."""
    print(f"hole error {clean['hole'] * 1e6:.2f} um (std {clean['hole_std'] * 1e6:.2f} um), tilt error "
          f"{clean['tilt'] * 1e3:.3f} mrad, worst impact error {clean['impact_error'] / clean['impact_peak']:.3f} "
          f"of the peak")
    assert clean["hole"] < 5e-6 and clean["tilt"] < 1e-3
    assert clean["impact_error"] < clean["impact_peak"]


def test_with_encoder_noise_the_errors_stay_within_the_filter_noise(noisy):
    """Encoder noise 2e-7 rad on y and qw (seeded; a 23-bit encoder's quantisation step is
    7.5e-7 rad, std 2e-7), the filter assuming 1e-6: no false contact; force error 0.029 N rms in
    free space and 0.015 N in the bore, moment 6.2e-4 N m (measured: about the noise-free run's; the
    wrench's steady walks, set for the bore, pass little of the noise), the force errors within 3
    of the filter's standard deviations at more than 99 % of the bore's samples (measured 100 %).
    The hole to 1.8 um and its tilt to 0.09 mrad (measured). With the previous steady walk (100
    times the bore's force rate) the noise came through: 0.14 N, 0.011 N m, the hole to 0.14 mm and
    its tilt to 7.5 mrad. The bounds are 2 to 5 times the figures measured now."""
    print(f"free force error {noisy['free_force']:.4f} N rms, bore {noisy['steady_force']:.4f} N rms, moment "
          f"{noisy['steady_moment']:.2e} N m, within 3 std {100 * noisy['within_3_std']:.1f} %, hole error "
          f"{noisy['hole'] * 1e6:.1f} um, tilt {noisy['tilt'] * 1e3:.2f} mrad")
    assert not noisy["false_contact"]
    assert noisy["free_force"] < 0.06 and noisy["steady_force"] < 0.03 and noisy["steady_moment"] < 1.5e-3
    assert noisy["within_3_std"] > 0.99
    assert noisy["hole"] < 1e-5 and noisy["tilt"] < 5e-4


@pytest.fixture(scope="module")
def compiled_functions():
    """The PegEstimator's functions compiled (C generated from peg_kernels' Python), as its FMU
    calls them; the class goes back to Python afterwards."""
    from deltafmi.builder.codegen import use_compiled_functions
    from deltafmi.models.peg_estimator import PegEstimator
    from deltafmi.runtime.native_functions import register_library

    assert use_compiled_functions(PegEstimator)
    try:
        functions = PegEstimator().native_functions
    finally:
        register_library(PegEstimator, None)
    assert functions.compiled and not PegEstimator().native_functions.compiled
    return functions


def _scene():
    """The wrist of tests/physics/test_peg_estimation.py and the peg upright 0.31 mm below the top
    plane of a hole 1.8 mm off along +x: one rim point on the chamfer (active contact)."""
    from deltafmi.physics import delta_wrist as dw
    from deltafmi.physics.peg import Hole, Peg, PegContact
    from deltafmi.physics.wrist.kernels import tip_position, wrist_constants

    w = wrist_constants(dw.wrist_params((3e-4, 2e-4, 1e-4), dw.peg_tool(0.25, 0.1, 0.01, 0.13), 9.81, 0.0))
    z = np.array([0.0, 0.0, -1.2 - 0.00031]) - np.array(tip_position(w, (0.0, 0.0, 0.0))) - np.array([0.0, 0.0, -0.05])
    s = np.concatenate([z, [0.01, -0.02, 0.0], [0.002, -0.001, -0.003, 0.05, -0.02, 0.1]])
    return w, dw.MOUNT, Hole(x=0.0018, y=0.0, z=-1.2), Peg(), PegContact(), s


def test_compiled_functions_give_the_python_functions_bits(compiled_functions):
    """Each function at points that reach every branch: the prediction with all 18 Jacobian columns,
    with columns in turn across the wrap (16, 17, 0) and 3 Runge-Kutta substeps; the contact
    law's linearisation at an active chamfer contact, full and hole-only; the locator finding the
    hole behind it, and finding none for an axial force; the servo angles' kinematics. The C keeps Python's operations and their
    order (-ffp-contract=off): the same bits."""
    from deltafmi.physics.delta.params import RL5
    from deltafmi.physics.estimation.peg_ekf import PYTHON_FUNCTIONS

    w, m, hole, peg, law, s = _scene()
    u, tau, W = [12.0, -3.0, 5.0], [0.01, -0.02, 0.005], [1.0, -0.5, 2.0, 0.002, -0.001, 0.0005]
    calls = [("prediction", (RL5, w, m, list(s), u, tau, W, 5.0, 1e-3, 1, 0, 18)),
             ("prediction", (RL5, w, m, list(s), u, tau, W, 5.0, 1e-3, 3, 16, 3)),
             ("contact_linearization", (hole, peg, law, w, m, list(s), [0.0018, 0.0, 0.0, 0.0], False)),
             ("contact_linearization", (hole, peg, law, w, m, list(s), [0.00179, 1e-5, 0.001, 0.0], True))]
    felt = compiled_functions.contact_linearization(hole, peg, law, w, m, list(s), [0.0018, 0.0, 0.0, 0.0], True)[:6]
    assert felt[0] > 0.1  # the chamfer pushes the peg towards +x
    weights = [0.05] * 3 + [0.005] * 3
    calls += [("hole_search", (hole, peg, law, w, m, list(s), [0.0, 0.0, 0.0, 0.0], list(felt), weights)),
              ("hole_search", (hole, peg, law, w, m, list(s), [0.0] * 4, [0.0, 0.0, 5.0, 0.0, 0.0, 0.0], weights)),
              ("servo_kinematics", (RL5, list(s[:3])))]
    results = []
    for name, args in calls:
        fast, python = getattr(compiled_functions, name)(*args), getattr(PYTHON_FUNCTIONS, name)(*args)
        np.testing.assert_array_equal(fast, python, err_msg=name)
        results.append(python)
    evaluated = [set(np.flatnonzero(np.any(r[12:].reshape(18, 6) != 0.0, axis=1))) for r in results[:2]]
    assert evaluated == [set(range(18)), {16, 17, 0}]
    hole_only = np.any(results[3][6:102].reshape(16, 6) != 0.0, axis=1)
    assert results[2][-1] >= 1.0 and not hole_only[:12].any() and hole_only[12:].all()
    assert results[4][0] == 1.0 and results[5][0] == 0.0  # a hole found, and none


def test_the_filter_compiled_estimates_what_it_estimates_in_python(compiled_functions):
    """PegEKF with the compiled functions and with the Python ones through 40 samples of the scene
    above (the robot held at rest, the chamfer's wrench as the filter's start, the hole's prior
    10 um off: it predicts, updates with the angles and applies the iterated contact law):
    estimates and covariances to 1e-12 relative (measured: the same bits)."""
    from deltafmi.physics import delta_wrist as dw
    from deltafmi.physics.delta.params import RL5
    from deltafmi.physics.estimation.wrist_process import full_state
    from deltafmi.physics.estimation.peg_ekf import PYTHON_FUNCTIONS, PegEKF, PegEKFSettings
    from deltafmi.physics.estimation.peg_contact import contact_wrench

    w, m, hole, peg, law, s = _scene()
    s[6:] = 0.0
    c = contact_wrench(hole, peg, law, w, m, s, [hole.x, hole.y, 0.0, 0.0])
    felt = np.array(c.force + c.moment)
    x = full_state(RL5, s)[0]
    y = x[[0, 3, 6]]
    u, tau = (list(v) for v in dw.holding_torques(RL5, w, x))
    filters = []
    for functions in (compiled_functions, PYTHON_FUNCTIONS):
        ekf = PegEKF(RL5, w, m, replace_hole(hole, 0.00179), peg, law, PegEKFSettings(contact_samples=1), y, s[3:6],
                     functions=functions)
        ekf.x[12:18] = felt
        ekf.P[18:20, 18:20] = np.diag([2e-5 ** 2] * 2)
        filters.append(ekf)
    contact = []
    for _ in range(40):
        fast, python = (np.hstack([np.ravel(v) for v in ekf.step(y, s[3:6], u, tau)])
                        for ekf in filters)
        np.testing.assert_allclose(fast, python, rtol=1e-12, atol=0.0)
        contact.append(filters[0].in_contact)
    np.testing.assert_allclose(filters[0].P, filters[1].P, rtol=1e-12, atol=0.0)
    assert sum(contact) >= 10


def replace_hole(hole, x: float):
    from dataclasses import replace

    return replace(hole, x=x)
