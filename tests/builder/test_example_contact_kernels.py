"""The contact examples' plain-float kernels (compiled into their FMUs) against the numpy
ContactSystem they replace in the FMUs: the same gaps, Jacobians, forces, accelerations, indicators
and energies in every mode (FREE, COLLISION, CONTACT), to round-off, for the restitution ball,
the box on the table and Newton's cradle (pendulums and free chain, frozen balls included)."""
from __future__ import annotations

import numpy as np
import pytest

from deltafmi.physics.contact.collision_law import CollisionLaw
from deltafmi.physics.contact.system import COLLISION, CONTACT, FREE, ContactSystem
from deltafmi.physics.contact_problems.restitution_kernels import RestitutionBall, ball_evaluate
from deltafmi.physics.contact_problems.bouncing_ball import BallModel
from deltafmi.physics.contact_problems.box_kernels import BoxModes, BoxParams, box_evaluate, box_outputs
from deltafmi.physics.contact_problems.box_on_table import BoxModel
from deltafmi.physics.contact.law_kernels import law_constants
from deltafmi.physics.contact_problems.contact_kernels import KernelContactSystem, _solve_masked
from deltafmi.physics.contact_problems.cradle_kernels import CradleModes, cradle_outputs
from deltafmi.physics.contact_problems.newtons_cradle import make_cradle

LAW = CollisionLaw(restitution=0.7, duration=1e-3, reference_speed=1.0, exponent=3.0)
FIELDS = ("h", "hdot", "H", "lam", "vdot")


def _ball():
    params = RestitutionBall(1.3, 9.81, law_constants(LAW), 100.0, 20.0)
    numpy_system = ContactSystem(BallModel(1.3, 9.81), LAW, capture_speed=0.05)
    kernel_system = KernelContactSystem(BallModel(1.3, 9.81), LAW, ball_evaluate, params, capture_speed=0.05)
    for system in (numpy_system, kernel_system):
        system.model.force = 0.4
    kernel_system.inputs = (0.4,)
    return numpy_system, kernel_system


def _box():
    model = BoxModel(1.0, 0.4, 0.2, None, (0.04, 0.01), 9.81)
    params = BoxParams(model.mass, model.inertia, model.g, tuple(tuple(c) for c in model.corners.tolist()),
                       law_constants(LAW), 100.0, 20.0)
    numpy_system = ContactSystem(BoxModel(1.0, 0.4, 0.2, None, (0.04, 0.01), 9.81), LAW)
    kernel_system = KernelContactSystem(model, LAW, box_evaluate, params)
    for system in (numpy_system, kernel_system):
        system.model.force = np.array([0.3, -0.2, 0.05])
    kernel_system.inputs = ([0.3, -0.2], 0.05)
    return numpy_system, kernel_system


def _cradle(pendulum: bool):
    options = dict(pendulum=pendulum, law=LAW, n_max=7, striker_speed=0.7, mass=0.1, radius=0.0125)
    return make_cradle(5, **options)[0], make_cradle(5, kernels=True, **options)[0]


def _state(rng, system, scale_q: float, scale_v: float, x0: np.ndarray) -> np.ndarray:
    n = system.model.n_q
    active = np.r_[system.active_dofs, system.active_dofs].astype(float)
    return x0 + active * np.r_[scale_q * rng.standard_normal(n), scale_v * rng.standard_normal(n)]


def _compare(numpy_system, kernel_system, x, modes, m_eff):
    for system in (numpy_system, kernel_system):
        system.modes[:] = modes
        system.m_eff[:] = m_eff
        system._cache_key = None
    expected, got = numpy_system._solve(0.0, x, numpy_system.modes), kernel_system._solve(0.0, x, kernel_system.modes)
    # the two solves of the CONTACT multipliers differ by round-off times the condition of their matrix
    K = np.flatnonzero(np.asarray(modes) == CONTACT)
    M = numpy_system.model.mass_matrix(x[:numpy_system.model.n_q])
    cond = np.linalg.cond(expected.H[K] @ np.linalg.solve(M, expected.H[K].T)) if len(K) else 1.0
    for name in FIELDS:
        a, b = getattr(expected, name), getattr(got, name)
        scale = max(float(np.max(np.abs(a))), 1.0)  # SI: metres, m/s, N, m/s2 of order 1
        np.testing.assert_allclose(b, a, rtol=0, atol=(1e-11 + 1e-13 * cond) * scale, err_msg=name)
    np.testing.assert_allclose(kernel_system.event_indicators(0.0, x), numpy_system.event_indicators(0.0, x),
                               rtol=1e-9, atol=1e-12)
    return expected


CASES = {
    "ball": (_ball, np.array([-1e-4, -0.5]), 1e-4, 0.5),
    "box": (_box, np.array([0.01, 0.11 - 1e-4, 0.0, 0.1, -0.3, 0.4]), 1e-4, 0.3),  # bottom corners in the table
    "pendulums": (lambda: _cradle(True), None, 1e-3, 0.5),
    "chain": (lambda: _cradle(False), None, 1e-4, 0.5),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_kernel_evaluation_is_contact_systems_in_every_mode(case):
    make, x0, scale_q, scale_v = CASES[case]
    numpy_system, kernel_system = make()
    n_c = numpy_system.model.n_c
    if x0 is None:  # the cradle: balls in their row, compressed a little
        x0 = np.r_[np.zeros(7), np.zeros(7)] if numpy_system.model.__class__.__name__ == "PendulumModel" else \
            np.r_[0.025 * np.arange(7), np.zeros(7)]
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(40):
        x = _state(rng, numpy_system, scale_q, scale_v, x0)
        modes = rng.choice([FREE, COLLISION, CONTACT], n_c)
        if case == "box":  # the bottom corners rest on the table, the top ones cannot join them
            modes[2:][modes[2:] == CONTACT] = COLLISION
        if case in ("pendulums", "chain"):
            modes[np.flatnonzero(modes == CONTACT)[1:]] = COLLISION
        seen.update(modes.tolist())
        ev = _compare(numpy_system, kernel_system, x, modes, rng.uniform(0.05, 2.0, n_c))
        assert np.all(ev.lam[modes == FREE] == 0.0)
    assert seen == {FREE, COLLISION, CONTACT}


def test_box_resting_on_two_corners_carries_its_weight_by_moment_balance():
    numpy_system, kernel_system = _box()
    numpy_system.model.force = np.zeros(3)
    kernel_system.inputs = ([0.0, 0.0], 0.0)
    model = kernel_system.model
    x = np.array([0.0, 0.1 + 0.01, 0.0, 0.0, 0.0, 0.0])   # lying flat, centre of mass 0.01 above the centre
    ev = _compare(numpy_system, kernel_system, x, [CONTACT, CONTACT, FREE, FREE], np.ones(4))
    np.testing.assert_allclose(ev.lam[:2], model.resting_forces(), rtol=1e-12)
    np.testing.assert_allclose(ev.vdot, 0.0, atol=1e-12)


def test_outputs_energy_is_contact_systems_energy():
    for numpy_system, kernel_system, outputs, modes_type, n in (
            (*_box(), box_outputs, BoxModes, 4), (*_cradle(True), cradle_outputs, CradleModes, 6)):
        rng = np.random.default_rng(3)
        for _ in range(10):
            x = np.r_[numpy_system.model.n_q * [0.0], numpy_system.model.n_q * [0.0]]
            x = _state(rng, numpy_system, 1e-3, 0.4, x + (np.r_[0, 0.1, 0, 0, 0, 0] if n == 4 else 0.0))
            modes = rng.choice([FREE, COLLISION], n)
            m_eff = rng.uniform(0.05, 2.0, n)
            numpy_system.modes[:] = modes
            numpy_system.m_eff[:] = m_eff
            args = (kernel_system.params, modes_type(tuple(modes.tolist()), tuple(m_eff.tolist())), x.tolist(),
                    *kernel_system.inputs)
            energy = outputs(*args)[-1 if n == 4 else -2]
            assert energy == pytest.approx(numpy_system.energy(x), rel=1e-12)


def test_masked_solve_is_the_submatrix_solve_and_refuses_redundant_contacts():
    rng = np.random.default_rng(5)
    B = rng.standard_normal((4, 4))
    A = B @ B.T + 0.1 * np.eye(4)
    b = rng.standard_normal(4)
    keep = [True, False, True, True]
    K = [0, 2, 3]
    x = _solve_masked(A.tolist(), b.tolist(), keep)
    np.testing.assert_allclose(np.array(x)[K], np.linalg.solve(A[np.ix_(K, K)], b[K]), rtol=1e-12)
    assert x[1] == 0.0
    H = np.array([[0.0, 1.0, 0.2], [0.0, 1.0, -0.2], [0.0, 1.0, 0.1]])     # three box corners: rank 2
    with pytest.raises(ValueError, match="redundant"):
        _solve_masked((H @ H.T).tolist(), [1.0, 1.0, 1.0], [True, True, True])
