"""The ContactEstimator FMU: validation, and contact_estimation.yaml (the robot pressing on a table
in impedance mode) run by the master, the estimates against the plant's true normal force fn and
surface height, without and with seeded servo noise. Figures measured when this was written are
quoted next to each bound."""
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
SCENARIO = ROOT / "scenarios" / "contact_estimation.yaml"
G = 9.81


@pytest.fixture(scope="module")
def estimator(build_fmu_from_src) -> Path:
    return build_fmu_from_src("contact_estimator.py")


def test_estimator_fmu_validates(estimator):
    assert validate_fmu(str(estimator)) == []
    md = fmpy.read_model_description(str(estimator))
    assert md.modelExchange and md.coSimulation


@pytest.mark.parametrize("fmi_type", ["ModelExchange", "CoSimulation"])
def test_torques_holding_more_than_the_robot_mean_a_push(estimator, fmi_type):
    """The FMU alone in fmpy, inputs held: servo angles of the wrist at rest at (0.1, 0, -1) m and
    the torques that hold it with a 0.5 kg payload the estimator's model lacks. Nothing moves, so
    an external force must take the extra support: f = (0, 0, -m g) (closed form), reached to
    1e-3 N within 0.5 s (measured 5e-13 N in both interfaces)."""
    from dataclasses import replace

    from deltafmi.physics import delta as d

    q = d.inverse_kinematics(d.RL5, [0.1, 0.0, -1.0])
    u = d.holding_torque(replace(d.RL5, payload=0.5), q)[0]
    start = {f"y[{i + 1}]": q[3 * i] for i in range(3)} | {f"u[{i + 1}]": u[i] for i in range(3)}
    r = fmpy.simulate_fmu(str(estimator), fmi_type=fmi_type, start_values=start, stop_time=0.5,
                          output_interval=1e-3, output=["force[1]", "force[2]", "force[3]", "z[1]", "z[3]"])
    np.testing.assert_allclose([r["force[1]"][-1], r["force[2]"][-1], r["force[3]"][-1]], [0.0, 0.0, -0.5 * G],
                               atol=1e-3)
    np.testing.assert_allclose([r["z[1]"][-1], r["z[3]"][-1]], [0.1, -1.0], atol=1e-9)


def run(folder: Path, stop: float | None = None, **changes: dict) -> dict:
    """contact_estimation.yaml with ``changes[component]`` merged into that component's parameters
    (the components keep their order: the master's Gauss-Seidel order breaks ties by it, and the
    estimator must step after the plant and the controller to see y and u of the same instant)."""
    spec = yaml.safe_load(SCENARIO.read_text())
    for component, parameters in changes.items():
        spec["components"][component]["parameters"].update(parameters)
    if stop is not None:
        spec["experiment"]["stop"] = stop
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    out = path.with_suffix(".csv")
    Master(resolve_system(load_scenario(path)), result=out).run()
    return columns(out)


def errors(c: dict) -> dict:
    """Normal-force and surface-height errors of a run against the plant's truth (N, m)."""
    t, fn, est = c["time"], c["plant.fn"], c["estimator.fn"]
    touch = int(np.argmax(c["plant.mode"] > 0))
    e = est - fn
    steady = slice(len(t) - 1000, None)  # the last second: the press at rest
    return dict(touch=touch, free_rms=float(np.sqrt(np.mean(e[100:touch] ** 2))),
                impact=float(np.abs(e[touch:touch + 100]).max()), impact_peak=float(fn[touch:touch + 100].max()),
                settled=float(np.abs(e[touch + 300:]).max()),
                steady_mean=float(e[steady].mean()), steady_rms=float(np.sqrt(np.mean(e[steady] ** 2))),
                surface=float(c["estimator.surface_height"][-1] - c["plant.surface_height"][-1]),
                surface_std=float(c["estimator.surface_std"][-1]),
                false_contact=bool(np.any(c["estimator.in_contact"][:touch] > 0)),
                within_3_std=float(np.mean(np.abs(e[steady]) < 3.0 * c["estimator.fn_std"][steady])),
                final=float(fn[-1]))


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    return errors(run(tmp_path_factory.mktemp("clean")))


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    return errors(run(tmp_path_factory.mktemp("noisy"), estimator={"sensor_noise": 1e-5, "seed": 7}))


def test_without_noise_the_estimates_match_the_plant(clean):
    """The estimator's model is the plant's (same DAE, same payload): free-space force error at
    round-off (measured 2.4e-10 N), the pressing force of 24.8 N to 0.05 N over the last second, the
    press settling and then at rest (measured mean 8.2e-6 N, rms 5.3e-5 N: the force's rate follows
    the ramp and its end, and at rest the torques' balance holds it), the table's height to 1 um from a 5 cm prior (measured 2.4e-10 m). The
    impact (true peak 15.6 N) is missed until the manoeuvre detector fires a few ms after the touch
    (measured worst error 15.2 N, the force itself); from 0.3 s after touching on, the error stays
    under 1 N (measured 1.4e-4 N)."""
    assert clean["final"] == pytest.approx(20.0 + 0.5 * G, rel=0.01)
    assert clean["free_rms"] < 1e-3 and not clean["false_contact"]
    assert abs(clean["steady_mean"]) < 0.05 and clean["steady_rms"] < 0.05
    assert abs(clean["surface"]) < 1e-6 and clean["surface_std"] < 1e-5
    assert clean["impact"] < clean["impact_peak"] and clean["settled"] < 1.0


def test_with_servo_noise_the_errors_stay_within_the_filter_noise(noisy):
    """Servo noise 1e-5 rad (seeded, as the filter assumes): no false contact before touching; the
    force error is filter noise, measured 0.0027 N rms in free space and 5.2e-5 N rms over the last
    second in contact (where the contact law also informs it), with a mean over it of 3.6e-6 N
    (bounds 0.5 N, 0.1 N, 0.05 N: room for a false manoeuvre detection, which lets the force walk
    at force_rate_std for 0.1 s); the table's height to 8.8e-8 m (the contact law averages
    thousands of samples, std 5.3e-8 m)."""
    assert not noisy["false_contact"]
    assert noisy["free_rms"] < 0.5 and noisy["steady_rms"] < 0.1
    assert abs(noisy["steady_mean"]) < 0.05
    assert abs(noisy["surface"]) < 3.0 * noisy["surface_std"] and abs(noisy["surface"]) < 1e-5
    assert noisy["within_3_std"] > 0.99


def test_an_unknown_payload_is_an_external_force(tmp_path):
    """The estimator's model without the plant's 0.5 kg payload, the robot at rest (reference held
    at its start): the payload's weight is an external force on the wrist, f = (0, 0, -m g)
    (closed form; joint angles and torques cannot tell a payload from a push)."""
    c = run(tmp_path, stop=0.5, estimator={"payload": 0.0}, trajectory={"n_waypoints": 1})
    force = np.array([c[f"estimator.force[{i}]"][-100:] for i in (1, 2, 3)])
    np.testing.assert_allclose(force.mean(axis=1), [0.0, 0.0, -0.5 * G], atol=0.01)


def test_the_compiled_process_kernels_give_the_python_estimates():
    """The component's compiled functions (C generated from the process model's kernels) against
    the same kernels as Python, through the filter: the robot held at rest at (0.1, 0, -1) m by the
    torques of the robot without payload, the estimator modelling a 2 kg payload (so that it sees
    an upward push of 2 g = 19.6 N, above its contact threshold: the contact-law update runs too),
    seeded servo noise. Every estimate equal to 1e-12 relative (they are the same bits), and the
    push found (closed form): the mean normal force over the last 0.4 s within three standard
    errors of 2 g (the filter's reported deviation ~4.2 N over about 0.4 s x 40 Hz of bandwidth
    independent samples: 1.05 N each; measured 19.48 N, the samples' scatter 1.3 N)."""
    from dataclasses import replace

    from deltafmi.builder.codegen import use_compiled_functions
    from deltafmi.models.contact_estimator import ContactEstimator
    from deltafmi.physics import delta as d
    from deltafmi.physics.estimation.contact_ekf import ContactEKF, ContactEKFSettings
    from deltafmi.physics.estimation.delta_process_kernels import PYTHON_KERNELS
    from deltafmi.runtime.native_functions import register_library

    assert use_compiled_functions(ContactEstimator)
    try:
        compiled = ContactEstimator().native_functions
    finally:
        register_library(ContactEstimator, None)
    assert compiled.compiled and not ContactEstimator().native_functions.compiled
    model, settings = replace(d.RL5, payload=2.0), ContactEKFSettings()
    q = d.inverse_kinematics(replace(d.RL5, payload=0.0), [0.1, 0.0, -1.0])
    u = d.holding_torque(replace(d.RL5, payload=0.0), q)[0]
    rng = np.random.default_rng(5)
    ys = q[[0, 3, 6]] + settings.y_std * rng.standard_normal((600, 3))
    filters = [ContactEKF(model, settings, ys[0], kernels=kernels) for kernels in (compiled, PYTHON_KERNELS)]
    contact, fn = [], []
    for y in ys:
        fast, python = (np.hstack([np.ravel(value) for value in ekf.step(y, u)] + [ekf.gap()]) for ekf in filters)
        np.testing.assert_allclose(fast, python, rtol=1e-12, atol=0.0)
        contact.append(filters[0].in_contact)
        fn.append(filters[0].estimate().fn)
    np.testing.assert_allclose(filters[0].P, filters[1].P, rtol=1e-12, atol=0.0)
    assert any(contact) and contact[-1]
    assert np.mean(fn[200:]) == pytest.approx(2.0 * G, abs=3 * 1.05)
