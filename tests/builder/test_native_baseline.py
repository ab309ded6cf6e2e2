"""Issue 26's baseline, benchmarks/native/flagship.c (a C transcription of the flagship's kernels),
computes what the flagship computes, so that benchmarks/native.py measures deltafmi against the same
computation and the baseline cannot drift from the model unnoticed.

The tolerance is zero: the transcription performs the same IEEE-754 double operations in the same
order as the Python kernels, with the same math library (the process's libm), so every value is
identical. Nothing looser would do: the closed loop amplifies one differing last bit to about
1e-12 relative in the torques within a second (a compiler folding the path's pow(x, 2.0) into
x * x did exactly that, from 2.233 s on), so a tolerance would hide changes to the model as well.
The whole flagship (3.5 s) runs: that divergence appeared only after 2.2 s.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import deltafmi
from deltafmi.toolchain import NoCompilerError
from deltafmi.physics import delta

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def native():
    spec = importlib.util.spec_from_file_location("deltafmi_benchmark_native", ROOT / "benchmarks" / "native.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def baseline(native, tmp_path_factory):
    try:
        library = native.compile_baseline(tmp_path_factory.mktemp("native"))
    except NoCompilerError as exc:
        pytest.skip(f"no C compiler to build the C transcription: {exc}")
    return native.Baseline(library)


@pytest.fixture(scope="module")
def flagship(native):
    return native.load_flagship()


@pytest.fixture(scope="module")
def spec(native, flagship):
    return native.flagship_spec(flagship)


def test_closed_loop_reproduces_the_flagship_bit_for_bit(native, baseline, spec):
    result = deltafmi.simulate("delta_tracking")
    steps = len(result.time) - 1
    rows, _, _ = baseline.run(spec, steps)
    assert steps == 3500
    np.testing.assert_array_equal(rows[:, 0], result.time)
    for j, name in enumerate(native.COLUMNS[1:], start=1):
        if name.startswith(("plant.z[", "controller.u[")):
            np.testing.assert_array_equal(rows[:, j], result[name], err_msg=f"{name}: the C transcription differs")
    # the run moves: the wrist leaves home and comes back, the torques vary
    z = rows[:, 1:4]
    assert np.ptp(z[:, 0]) > 0.4 and np.ptp(z[:, 2]) > 0.09
    assert np.ptp(rows[:, 10]) > 10.0


def test_plant_derivative_matches_the_model_bit_for_bit(native, baseline, spec, flagship):
    """Away from the flagship's path too: random states near the closed loops, random torques."""
    models = native.flagship_models(flagship)
    rng = np.random.default_rng(26)
    for _ in range(50):
        z0 = [rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-1.15, -0.8)]
        q = delta.inverse_kinematics(models.plant, z0) + rng.normal(0.0, 1e-3, 9)
        x = np.concatenate([q, rng.normal(0.0, 2.0, 9)])
        u = rng.normal(0.0, 50.0, 3)
        expected = delta.state_derivative(models.plant, x, u, models.f, models.pole)
        np.testing.assert_array_equal(baseline.state_derivative(spec, x, u), expected)


def test_replayed_controller_matches_the_model_bit_for_bit(native, baseline, spec, flagship):
    """The controller alone, on the flagship's first second of samples, as the benchmark times it."""
    rows, states, _ = baseline.run(spec, 1000)
    inputs = native.controller_inputs(baseline, spec, rows, states)
    u_c, _ = baseline.replay_controller(spec, inputs)
    u_py, _ = native.python_controller(native.flagship_models(flagship).controller, inputs)
    np.testing.assert_array_equal(u_c, u_py)
    np.testing.assert_array_equal(u_c[1:], rows[2:, 10:13])
