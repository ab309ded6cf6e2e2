"""The process model's plain-float kernels (deltafmi.physics.estimation.delta_process_kernels)
against the numpy formulation they stand for (deltafmi.physics.estimation.delta_process and the
robot's kinematics): the prediction to the bit (the same operations in the same order), the
kinematics to rounding (the same quantities computed another way: by hand for the rotations,
by the adjugate for the inverses where numpy uses LAPACK)."""
from __future__ import annotations

import numpy as np
import pytest

from deltafmi.physics import delta as d
from deltafmi.physics.delta.jacobian import jacobian_values
from deltafmi.physics.estimation import delta_process as dp
from deltafmi.physics.estimation.delta_process_kernels import (N_KINEMATICS, N_PREDICTION, PYTHON_KERNELS,
                                                               prediction_values, wrist_kinematics)

P = d.RL5


def _state(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = d.inverse_kinematics(P, [rng.uniform(-0.15, 0.15), rng.uniform(-0.15, 0.15), rng.uniform(-1.1, -0.85)])
    return q, dp.tangent_basis(P, q) @ rng.normal(scale=0.3, size=3)


@pytest.mark.parametrize("substeps", [1, 3])
@pytest.mark.parametrize("seed", range(5))
def test_the_prediction_is_the_numpy_runge_kutta_and_jacobian_to_the_bit(seed, substeps):
    q, v = _state(seed)
    u, f = [0.5, -1.0, 2.0], [3.0, -2.0, 15.0]
    out = prediction_values(P, q, v, u, f, 1e-3, 5.0, substeps)
    assert len(out) == N_PREDICTION
    _, rate = dp.process_linearization(P, q, v, u, f, 5.0)
    qn, vn = dp.propagate(P, q, v, u, f, 1e-3, 5.0, substeps, rate)
    assert np.array_equal(out[:9], qn) and np.array_equal(out[9:18], vn)
    assert out[18:] == jacobian_values(P, q, v, u, f, 5.0)


@pytest.mark.parametrize("seed", range(5))
def test_the_kinematics_are_the_numpy_ones_to_rounding(seed):
    q, v = _state(seed)
    out = np.array(wrist_kinematics(P, q, v))
    assert out.shape == (N_KINEMATICS,)
    arms = dp.arm_jacobians(P, q)
    Jv, D = dp.wrist_jacobians(P, q, v, arms)
    np.testing.assert_allclose(out[:3], d.wrist_position(P, q), rtol=0, atol=1e-15)
    np.testing.assert_allclose(out[3:30], arms.reshape(-1), rtol=0, atol=1e-15 * np.abs(arms).max())
    np.testing.assert_allclose(out[30:57], D.reshape(-1), rtol=0, atol=1e-15 * np.abs(D).max())
    basis = dp.tangent_basis(P, q)
    np.testing.assert_allclose(out[57:], basis.reshape(-1), rtol=0, atol=1e-12 * np.abs(basis).max())
    # and the basis is what it says: each arm's rows invert its Jacobian
    for i in range(3):
        np.testing.assert_allclose(out[57 + 9 * i:66 + 9 * i].reshape(3, 3) @ arms[i], np.eye(3), atol=1e-12)


def test_the_python_kernels_return_arrays_of_the_functions_floats():
    q, v = _state(7)
    assert np.array_equal(PYTHON_KERNELS.kinematics(P, q, v), wrist_kinematics(P, q, v))
    qp, vp = d.project_to_constraints(P, q + 1e-6, v)
    assert np.array_equal(PYTHON_KERNELS.project(P, q + 1e-6, v), np.r_[qp, vp])
