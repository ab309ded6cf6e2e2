"""A box dropped at an angle bounces, rocks and rests on two corners with statically right forces."""
from __future__ import annotations

import numpy as np
import pytest

from deltafmi.physics.contact_problems.box_on_table import make_box_drop
from deltafmi.physics.contact.system import Mode
from hybrid_sim import simulate


@pytest.mark.parametrize("offset", [0.0, 0.04])
def test_box_comes_to_rest_on_two_corners(offset):
    system, x0 = make_box_drop(com_offset=(offset, 0.0), angle=0.3, drop_height=0.1)
    r = simulate(system, (0.0, 3.0), x0, rtol=1e-8, atol=1e-10)
    model = system.model
    switches = [ev for ev in r.events if ev.modes_before != ev.modes_after]
    # it bounced (collisions ended in FREE) and rocked (both bottom corners collided) first
    assert sum(ev.modes_before[0] == Mode.COLLISION and ev.modes_after[0] == Mode.FREE for ev in switches) >= 2
    assert sum(ev.modes_before[1] == Mode.COLLISION and ev.modes_after[1] == Mode.FREE for ev in switches) >= 2
    assert list(r.modes[-1]) == [Mode.CONTACT, Mode.CONTACT, Mode.FREE, Mode.FREE]
    lam = r.forces[-1]
    weight = model.mass * model.g
    assert lam.sum() == pytest.approx(weight, rel=1e-6)
    np.testing.assert_allclose(lam[:2], model.resting_forces(), rtol=1e-6)
    if offset:
        assert lam[1] > lam[0]                 # the heavier side carries more
    x, y, theta = r.x[-1][:3]
    assert abs(theta) < 1e-6 and y == pytest.approx(model.height / 2, abs=1e-6)
    assert abs(x - x0[0]) < 1e-9               # frictionless: no horizontal force at all
    assert r.energy[-1] == pytest.approx(weight * y, rel=1e-9)
    assert r.energy[-1] < r.energy[0]


def test_resting_forces_by_moment_balance():
    system, _ = make_box_drop(width=0.4, com_offset=(0.04, 0.0))
    left, right = system.model.resting_forces()
    # corners at -0.24 and +0.16 from the centre of mass
    assert left == pytest.approx(9.81 * 0.16 / 0.4) and right == pytest.approx(9.81 * 0.24 / 0.4)
