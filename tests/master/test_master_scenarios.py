"""The scenarios shipped in scenarios/: each validates, and each runs to physically right answers
(checked against closed forms and conservation laws, not against earlier runs)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master

SCENARIOS = Path(__file__).parents[2] / "scenarios"


def system(name: str):
    return resolve_system(load_scenario(SCENARIOS / f"{name}.yaml"), check_fmus=True)


def run(name: str, tmp_path: Path, stop: float | None = None):
    summary = Master(system(name), result=tmp_path / f"{name}.csv", stop=stop).run()
    return summary, columns(tmp_path / f"{name}.csv")


@pytest.mark.parametrize("name", sorted(p.stem for p in SCENARIOS.glob("*.yaml")))
def test_shipped_scenario_validates(name):
    resolved = system(name)
    assert resolved.components and resolved.recorded


def tracking_error(c) -> np.ndarray:
    return np.sqrt(sum((c[f"plant.z[{i}]"] - c[f"trajectory.r[{i}]"]) ** 2 for i in (1, 2, 3)))


def test_delta_tracking_steady_state_error_below_one_micrometre(tmp_path):
    summary, c = run("delta_tracking", tmp_path)
    error, t = tracking_error(c), c["time"]
    assert t[-1] == 3.5 and summary.steps == 3500
    assert error[t >= 3.2].max() < 1e-6  # at rest after the last move
    assert error.max() < 50e-6  # while moving, with feedforward
    assert np.ptp(c["trajectory.r[1]"]) > 0.4  # it did move: 0.25 m to -0.20 m


def test_delta_without_feedforward_has_large_transient_error(tmp_path):
    _, c = run("delta_no_feedforward", tmp_path, stop=1.6)
    assert tracking_error(c).max() > 1e-3  # millimetres, against micrometres with feedforward


def test_delta_circle_tracks_within_micrometres(tmp_path):
    _, c = run("delta_circle", tmp_path, stop=2.5)
    t = c["time"]
    radius = np.hypot(c["plant.z[1]"], c["plant.z[2]"])
    assert np.all(np.abs(radius[t > 1.2] - 0.15) < 2e-6)  # on the circle, at full speed
    assert tracking_error(c).max() < 2e-6


def test_bouncing_balls(tmp_path):
    _, c = run("bouncing_ball", tmp_path, stop=1.6)
    t, q, v = c["time"], c["restitution.q"], c["restitution.v"]
    g, h0, e = 9.81, 1.0, 0.8
    first = np.argmax(v > 0)  # the first rebound
    assert t[first] == pytest.approx(math.sqrt(2 * h0 / g), abs=2e-3)
    assert v[first:first + 50].max() == pytest.approx(e * math.sqrt(2 * g * h0), rel=2e-3)
    apex = q[first:np.searchsorted(t, t[first] + 2 * e * math.sqrt(2 * h0 / g) * 0.9)].max()
    assert apex == pytest.approx(e ** 2 * h0, rel=2e-3)
    assert np.any(np.diff(t) == 0)  # state events recorded as repeated time stamps


def test_newtons_cradle_conserves_and_transfers(tmp_path):
    _, c = run("newtons_cradle", tmp_path, stop=0.4)
    energy, momentum = c["cradle.energy"], c["cradle.momentum"]
    assert np.max(np.abs(energy - energy[0])) < 1e-6 * energy[0]
    t = c["time"]
    moving = np.nonzero(np.abs(c["cradle.vx[5]"]) > 1e-3)[0]
    strike, settled = moving[0], np.searchsorted(t, t[moving[0]] + 0.02)  # the pulse has crossed
    swing = c["cradle.vx[1]"][:strike]
    before = swing[np.argmax(np.abs(swing))]  # the striker's speed at the bottom of its swing
    assert abs(before) > 0.4  # it swung down from 0.3 rad
    assert c["cradle.vx[5]"][settled] == pytest.approx(before, rel=0.03)
    assert max(abs(c[f"cradle.vx[{i}]"][settled]) for i in (1, 2, 3, 4)) < 0.03 * abs(before)
    # at the bottom of the swings (no horizontal pull of the strings) momentum went over whole
    last = np.argmax(np.abs(c["cradle.vx[5]"][:settled + 1]))
    assert momentum[last] == pytest.approx(momentum[np.argmax(np.abs(swing))], rel=1e-3)


def test_box_comes_to_rest_on_two_corners(tmp_path):
    _, c = run("box_on_table", tmp_path)
    forces = [c[f"box.lam[{i}]"][-1] for i in range(1, 5)]
    assert c["box.total_force"][-1] == pytest.approx(1.0 * 9.81, rel=1e-6)
    assert sorted(forces)[:2] == [0.0, 0.0] and min(sorted(forces)[2:]) > 1.0
    assert sorted(c[f"box.mode[{i}]"][-1] for i in range(1, 5)) == [0.0, 0.0, 2.0, 2.0]
