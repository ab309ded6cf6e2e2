"""The compliant collision law: calibration against closed forms, and isolated two-body impacts
through the full framework (restitution, duration, momentum) for several masses, speeds, laws."""
from __future__ import annotations

import math

import numpy as np
import pytest

from deltafmi.physics.contact_problems.box_on_table import make_box_drop
from deltafmi.physics.contact.collision_law import CollisionLaw, calibrate, elastic_duration
from deltafmi.physics.contact.system import ContactSystem
from hybrid_sim import simulate
from deltafmi.physics.contact_problems.newtons_cradle import ChainModel


@pytest.mark.parametrize("p", [1.0, 1.5, 3.0])
def test_elastic_calibration_matches_closed_form(p):
    c = calibrate(1.0, p)
    assert c.chi == 0.0
    assert c.tau == pytest.approx(elastic_duration(p), rel=1e-9)
    assert c.s_max == pytest.approx(((p + 1) / 2) ** (1 / (p + 1)), rel=1e-9)
    if p == 1.0:  # harmonic oscillator: half a period of a unit frequency
        assert c.tau == pytest.approx(math.pi, rel=1e-10)


@pytest.mark.parametrize("e", [0.2, 0.5, 0.9])
def test_linear_law_restitution_closed_form(e):
    # p = 1: s'' + chi s' + s = 0 while s + chi s' > 0. With zeta = chi/2, w = sqrt(1 - zeta^2):
    # s = exp(-zeta t) sin(w t)/w, and the force vanishes where tan(w t) = -2 zeta w / (1 - 2 zeta^2).
    c = calibrate(e, 1.0)
    zeta = c.chi / 2
    w = math.sqrt(1 - zeta ** 2)
    t_end = (math.atan2(-2 * zeta * w, 1 - 2 * zeta ** 2) % math.pi) / w
    s_dot = math.exp(-zeta * t_end) * (math.cos(w * t_end) - zeta * math.sin(w * t_end) / w)
    assert -s_dot == pytest.approx(e, rel=1e-9)
    assert c.tau == pytest.approx(t_end, rel=1e-9)


def test_parameters_follow_from_material():
    law = CollisionLaw(restitution=0.6, duration=2e-4, reference_speed=1.5, exponent=1.5)
    c = law.calibration
    assert law.kappa == pytest.approx((c.tau / 2e-4) ** 2.5 * 1.5 ** -0.5, rel=1e-12)
    assert law.gamma == pytest.approx(c.chi * math.sqrt(law.kappa), rel=1e-12)
    # Hertz: duration ~ v^(-1/5)
    assert law.duration_at(1.5 * 32) == pytest.approx(2e-4 / 2, rel=1e-12)


def _two_body_impact(m2, v0, e, p):
    law = CollisionLaw(restitution=e, duration=2e-4, reference_speed=1.0, exponent=p)
    system = ContactSystem(ChainModel([1.0, m2], [0.01, 0.01]), law, capture_speed=0.0)
    x0 = np.array([0.0, 0.02 + 1e-3, v0, 0.0])
    result = simulate(system, (0.0, 1e-3 / v0 + 5 * law.duration_at(v0)), x0, rtol=1e-10, atol=1e-13)
    switches = [ev.t for ev in result.events if ev.modes_before != ev.modes_after]
    return law, result.x[-1][2:], switches


@pytest.mark.parametrize("p", [1.0, 1.5, 3.0])
@pytest.mark.parametrize("e", [0.3, 1.0])
@pytest.mark.parametrize("m2, v0", [(3.0, 2.5), (0.2, 0.3)])
def test_isolated_impact_reproduces_restitution_and_duration(p, e, m2, v0):
    law, v, switches = _two_body_impact(m2, v0, e, p)
    assert len(switches) == 2  # FREE -> COLLISION -> FREE
    # restitution of the relative normal velocity, whatever the masses and the speed
    assert (v[1] - v[0]) / v0 == pytest.approx(e, abs=1e-8)
    assert (v[0] + m2 * v[1]) == pytest.approx(v0, rel=1e-12)
    assert switches[1] - switches[0] == pytest.approx(law.duration_at(v0), rel=1e-8)


def test_rotating_body_corner_impact_restitution():
    # a tilted box hits with one corner: m_eff = 1/(1/m + r_x^2/I) frozen at impact. Rotation
    # and gravity during the contact bias the rebound by O(duration); 1e-5 s keeps it < 1e-4.
    system, x0 = make_box_drop(law=CollisionLaw(restitution=0.5, duration=1e-5), capture_speed=0.0)
    result = simulate(system, (0.0, 0.16), x0, rtol=1e-10, atol=1e-13)
    t_in, t_out = [ev.t for ev in result.events if ev.modes_before != ev.modes_after][:2]
    H = system.model.gap_jacobian

    def corner_speed(t):
        x = result.at(t)
        return float(H(x[:3])[0] @ x[3:])

    v_in, v_out = corner_speed(t_in), corner_speed(t_out)
    assert v_in == pytest.approx(-math.sqrt(2 * 9.81 * 0.1), rel=1e-6)
    assert -v_out / v_in == pytest.approx(0.5, rel=1e-4)
    assert t_out - t_in == pytest.approx(system.laws[0].duration_at(-v_in), rel=1e-4)
