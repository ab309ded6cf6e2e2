"""The joystick experiment (scenarios/joystick_tracking.yaml) from its recorded session:
paced, re-recorded, replayed; the wrist follows the follower's limited reference.

The live run plays the shipped session at four times real time and records the events it took
(``record:``); that recording, played again unpaced, and ``--replay`` of the live run's results
must both give the live run's numbers bit for bit.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import deltafmi
from deltafmi.shipped import SCENARIOS_DIR

STOP = 3.0
SESSION = SCENARIOS_DIR / "joystick_session.jsonl"


def _copy(tmp_path: Path, session: Path, record: Path | None) -> Path:
    text = (SCENARIOS_DIR / "joystick_tracking.yaml").read_text()
    joystick = f"joystick: {{session: '{session}'" + (f", record: '{record}'" if record else "") + "}"
    text = text.replace("joystick:\n      session: joystick_session.jsonl", joystick)
    text = text.replace("  - {plot:", "  # - {plot:")
    path = tmp_path / f"joy_{len(list(tmp_path.glob('joy_*.yaml')))}.yaml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    folder = tmp_path_factory.mktemp("joystick")
    recorded = folder / "recorded.jsonl"
    scenario = _copy(folder, SESSION, recorded)
    out = folder / "live.parquet"
    result = deltafmi.simulate(scenario, stop=STOP, speed=4.0, output=out)
    return folder, scenario, out, recorded, result


def _events(path: Path, until: float) -> list:
    lines = path.read_text().splitlines()
    return [json.loads(line) for line in lines[1:] if json.loads(line)["t"] <= until]


def test_the_recording_holds_the_events_the_run_took(live):
    """Every event of the session up to the last point, with its stamp, and the session's header
    axes (what a device would have written)."""
    _, _, _, recorded, result = live
    assert result.summary.live.realtime.speed == 4.0
    assert _events(recorded, STOP) == _events(SESSION, STOP)
    header, original = (json.loads(p.read_text().splitlines()[0]) for p in (recorded, SESSION))
    assert header["axes"].keys() == original["axes"].keys()


def test_the_recording_and_the_results_replay_the_live_run_bit_for_bit(live, tmp_path):
    folder, _, out, recorded, result = live
    again = deltafmi.simulate(_copy(tmp_path, recorded, None), stop=STOP, realtime=False)
    replayed = deltafmi.simulate(_copy(tmp_path, SESSION, None), stop=STOP, replay=out)
    kept = [n for n in result.names if not n.startswith("realtime.")]
    assert len(kept) == len(result.names) - 3 and "stick.x" in kept
    for run in (again, replayed):
        assert [n for n in run.names] == kept
        for name in kept:
            assert np.array_equal(run[name], result[name]), name
    assert "replayed" in str(replayed.summary)


def test_the_wrist_follows_the_limited_reference(live):
    """The follower keeps its limits (0.25 m/s, 2 m/s2 on the sampled reference) and the stick
    moves it; the robot tracks it at the talk's low gains with feed-forward to millimetres."""
    _, _, _, _, result = live
    r, rd = result["follower.r"], result["follower.rd"]
    assert np.linalg.norm(rd, axis=1).max() <= 0.25 * (1 + 1e-12)
    acceleration = np.diff(rd, axis=0) / 1e-3
    assert np.linalg.norm(acceleration, axis=1).max() <= 2.0 * (1 + 1e-6)
    assert np.ptp(r, axis=0).max() > 0.02  # the stick moved the reference
    stick = np.column_stack([result[f"stick.{a}"] for a in "xyz"])
    assert np.ptp(stick, axis=0).max() > 0.02
    error = np.abs(result["plant.z"] - r).max()
    assert error < 0.01, error
