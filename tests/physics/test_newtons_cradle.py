"""Newton's cradle on the contact framework: momentum, energy, the velocity hand-over, and an
independent plain-ODE integration of the same per-contact laws."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from deltafmi.physics.contact.collision_law import CollisionLaw
from deltafmi.physics.contact.system import Mode
from hybrid_sim import simulate
from deltafmi.physics.contact_problems.newtons_cradle import make_cradle, momentum


def run(n, t_end=0.01, **kw):
    system, x0 = make_cradle(n, **kw)
    result = simulate(system, (0.0, t_end), x0, rtol=1e-10, atol=1e-13)
    return system, result


def collision_window(result):
    """First sample index where a contact collides, last index where one still does."""
    colliding = np.any(result.modes == Mode.COLLISION, axis=1) & np.any(np.abs(result.forces) > 0, axis=1)
    idx = np.flatnonzero(colliding)
    return max(idx[0] - 1, 0), idx[-1] + 1


@pytest.mark.parametrize("n", [2, 3, 5, 7])
def test_touching_free_chain_hands_over_the_velocity(n):
    system, r = run(n)
    v = system.model.ball_velocities(r.x[-1])
    p0, p1 = momentum(system.model, r.x[0]), momentum(system.model, r.x[-1])
    assert abs(p1 - p0) / abs(p0) < 1e-6
    assert abs(r.energy[-1] - r.energy[0]) / r.energy[0] < 1e-3
    assert v[-1] >= 0.97                       # striker speed is 1 m/s
    assert np.all(np.abs(v[:-1]) < 0.08)
    assert np.all(np.diff(v) > 0)              # every contact has opened
    assert all(m == Mode.FREE for m in r.modes[-1])


def _plain_chain(n, law, m=1.0):
    """The same contacts written directly: m x_i'' = forces of m_eff * a(delta) from each side."""
    m_eff = m / 2

    def rhs(_t, y):
        x, v = y[:n], y[n:]
        delta = np.maximum(x[:-1] - x[1:] + 2 * 0.02, 0.0)
        f = m_eff * law.kappa * delta ** law.exponent
        a = np.zeros(n)
        a[:-1] -= f / m
        a[1:] += f / m
        return np.r_[v, a]

    y0 = np.r_[0.04 * np.arange(n), 1.0, np.zeros(n - 1)]
    with np.errstate(over="ignore", invalid="ignore"):  # rejected trial steps may overflow
        sol = solve_ivp(rhs, (0, 0.01), y0, method="DOP853", rtol=1e-11, atol=1e-14)
    return sol.y[n:, -1]


@pytest.mark.parametrize("p, lead", [(1.5, [-0.071, 0.076, 0.9945]), (3.0, [-0.0104, 0.0105, 0.9999])])
def test_touching_chain_matches_independent_integration(p, lead):
    law = CollisionLaw(exponent=p)
    system, r = run(3, law=law)
    v = system.model.ball_velocities(r.x[-1])
    np.testing.assert_allclose(v, _plain_chain(3, law), atol=1e-6)
    np.testing.assert_allclose(v, lead, atol=6e-4)   # the lead's Hertz figures, rounded


@pytest.mark.parametrize("n", [3, 5])
def test_chain_with_gaps_is_ideal(n):
    system, r = run(n, gap=1e-3)
    v = system.model.ball_velocities(r.x[-1])
    np.testing.assert_allclose(v, np.r_[np.zeros(n - 1), 1.0], atol=1e-3)
    assert abs(r.energy[-1] - r.energy[0]) / r.energy[0] < 1e-3


def test_inelastic_chain_conserves_momentum_and_loses_energy():
    system, r = run(3, law=CollisionLaw(restitution=0.8))
    p0, p1 = momentum(system.model, r.x[0]), momentum(system.model, r.x[-1])
    assert abs(p1 - p0) < 1e-9
    assert r.energy[-1] < 0.99 * r.energy[0]


@pytest.mark.parametrize("n", [3, 5])
def test_touching_pendulums(n):
    # steel-like 20 us collisions: gravity's impulse over the window, ~ g (v T_w / L) T_w, is ~1e-8
    system, r = run(n, pendulum=True, striker_speed=1.0, t_end=0.002,
                    law=CollisionLaw(duration=2e-5))
    i0, i1 = collision_window(r)
    p0, p1 = momentum(system.model, r.x[i0]), momentum(system.model, r.x[i1])
    assert r.t[i1] - r.t[i0] < 1e-4            # the wave passes in a few collision durations
    assert abs(p1 - p0) / abs(p0) < 1e-6
    assert abs(r.energy[-1] - r.energy[0]) / r.energy[0] < 1e-3
    v = system.model.ball_velocities(r.x[i1])
    assert v[-1] >= 0.97 and np.all(np.abs(v[:-1]) < 0.08)


def test_pendulums_with_gaps_are_ideal():
    system, r = run(3, pendulum=True, gap=1e-3, t_end=0.004)
    v = system.model.ball_velocities(r.x[-1])
    np.testing.assert_allclose(v, [0.0, 0.0, 1.0], atol=1e-3)


def test_released_pendulum_swings_back_and_forth_conserving_energy():
    # released from 0.3 rad: the last ball swings out and comes back to strike again
    system, r = run(3, pendulum=True, striker_angle=0.3, t_end=1.2)
    events = [ev for ev in r.events if ev.indicator >= 0]   # not the initial mode assignment
    strikes = [ev.t for ev in events if ev.modes_before[0] == Mode.FREE and ev.modes_after[0] == Mode.COLLISION]
    returns = [ev.t for ev in events if ev.modes_before[1] == Mode.FREE and ev.modes_after[1] == Mode.COLLISION]
    quarter = np.pi / 2 * np.sqrt(0.3 / 9.81)
    assert strikes[0] == pytest.approx(quarter, rel=0.02)   # finite amplitude lengthens the period
    assert returns and returns[0] == pytest.approx(strikes[0] + 2 * quarter, rel=0.02)
    assert abs(r.energy[-1] - r.energy[0]) / r.energy[0] < 1e-3


def test_frozen_balls_do_not_change_the_answer():
    small, r_small = run(3)
    big, r_big = run(3, n_max=7)
    np.testing.assert_allclose(big.model.ball_velocities(r_big.x[-1])[:3],
                               small.model.ball_velocities(r_small.x[-1]), atol=1e-9)
    x_end = r_big.x[-1]
    np.testing.assert_array_equal(x_end[3:7], r_big.x[0][3:7])   # unused balls never move
    z = big.event_indicators(r_big.t[-1], x_end)
    assert np.all(z[[2, 3, 4, 5, 8, 9, 10, 11]] == 1.0)           # unused contacts: constant +1
