"""The talk's Modelica bouncing ball as written, and the restitution variant on the framework."""
from __future__ import annotations

import math

import numpy as np
import pytest

from deltafmi.physics.contact_problems.bouncing_ball import make_bouncing_ball
from bouncing_ball_figures import bounce_figures, energy_gain_per_bounce, free_flight_apexes
from deltafmi.physics.contact.system import Mode
from hybrid_sim import simulate

G = 9.81


@pytest.fixture(scope="module")
def damped():
    return bounce_figures(a1=20.0, t_end=3.0)


@pytest.fixture(scope="module")
def undamped():
    return bounce_figures(a1=0.0, t_end=4.0)


def test_first_impact_at_free_fall_time(damped):
    assert damped.impact_times[0] == pytest.approx(math.sqrt(2 / G), abs=1e-9)


def test_state_machine_with_damping_runs_0_1_2_0(damped):
    # released (1 -> 2) when lambda turns negative below the floor, free (2 -> 0) when h > 0
    order = [(a, b) for _, a, b in damped.transitions]
    assert order[:6] == [(0, 1), (1, 2), (2, 0)] * 2
    assert order[-1] == (0, 1)                 # the last impact never releases: at rest in state 1
    q, v = damped.result.x[-1]
    assert abs(q) < 1e-6 and abs(v) < 1e-5
    assert damped.result.forces[-1][0] == pytest.approx(G, rel=1e-5)


def test_state_machine_without_damping_skips_state_0(undamped):
    # with a1 = 0, lambda pushes on above the floor: b3 = h > 0 rises while contact == 1, so
    # edge(b3) is gone when the ball is released, state 0 never returns and b4 re-arms state 1
    order = [(a, b) for _, a, b in undamped.transitions]
    assert order[0] == (0, 1)
    assert order[1:] == [(1, 2), (2, 1)] * ((len(order) - 1) // 2) + [(1, 2)] * ((len(order) - 1) % 2)


def test_free_flight_follows_the_parabola(damped):
    r = damped.result
    flying = r.modes[:, 0] != 1
    starts = np.flatnonzero(flying & ~np.r_[False, flying[:-1]])
    worst = 0.0
    for s in starts:
        e = s
        while e + 1 < len(r.t) and flying[e + 1]:
            e += 1
        t0, (q0, v0) = r.t[s], r.x[s]
        dt = r.t[s:e + 1] - t0
        worst = max(worst, np.max(np.abs(r.x[s:e + 1, 0] - (q0 + v0 * dt - 0.5 * G * dt ** 2))))
    assert len(starts) >= 3 and worst < 1e-8


def test_energy_created_per_bounce_without_damping(undamped):
    q_star, gain = energy_gain_per_bounce()
    assert 100 * q_star + 1e6 * q_star ** 3 == pytest.approx(G, rel=1e-12)
    assert len(undamped.energy_per_bounce) >= 3
    np.testing.assert_allclose(undamped.energy_per_bounce, gain, rtol=1e-6)
    assert gain == pytest.approx(0.13621, abs=1e-5)


def test_damped_bounces_lose_energy(damped):
    assert damped.apex_heights[0] < 0.5 and np.all(np.array(damped.energy_per_bounce) < 0)


@pytest.mark.parametrize("e", [0.8, 0.5])
def test_restitution_variant_apex_heights_scale_by_e_squared(e):
    system, x0 = make_bouncing_ball(e=e, duration=1e-4)
    r = simulate(system, (0.0, 3.0), x0)
    heights = np.array([1.0] + [h for _, h in free_flight_apexes(r, G, lambda m: m == Mode.FREE)])
    ratios = heights[1:4] / heights[:3]
    # gravity acts during each impact (duration T(v)): the apex ratio is biased low by about
    # 4 (1 - e) g T(v) / v, zero for e = 1; allow 5 (1 - e) g T(v) / v per bounce (<= 2e-3 here)
    speeds = np.sqrt(2 * G * heights[:3])
    bias = 5 * (1 - e) * G * np.array([system.laws[0].duration_at(v) for v in speeds]) / speeds
    assert np.all(np.abs(ratios / e ** 2 - 1) < bias)
    assert np.all(ratios < e ** 2)
    if e == 0.5:  # the bounces end: captured into CONTACT, resting on lambda = m g
        assert r.modes[-1][0] == Mode.CONTACT
        assert r.forces[-1][0] == pytest.approx(G, rel=1e-6)
