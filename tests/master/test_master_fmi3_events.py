"""Our own FMI 3.0 FMUs in Co-Simulation with the master's event mode: the talk's bouncing ball
built as FMI 3.0 declares ``hasEventMode``; the master instantiates it with ``eventModeUsed`` and
``earlyReturnAllowed``, handles each state event in Event Mode at the time the step returned at,
and records a row before and after it. The references are independent of that path: fmpy's
Model Exchange run of the FMI 2.0 build for the event times and the contact state around each
event, and the FMI 2.0 Co-Simulation scenario (events inside the FMU's steps) for the grid."""
from __future__ import annotations

from pathlib import Path

import fmpy
import numpy as np
import pytest

from deltafmi import resolve_system
from deltafmi.master.results.csv_file import columns
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master

STOP, H = 3.0, 0.01


def _run(tmp_path: Path, fmi_version: int) -> tuple:
    path = tmp_path / f"ball{fmi_version}.yaml"
    path.write_text(f"experiment: {{stop: {STOP}, step: {H}}}\n"
                    f"fmi_version: {fmi_version}\n"
                    "components:\n  ball: {source: 'deltafmi.models:BouncingBall', interface: CS}\n"
                    "outputs: ['ball.q', 'ball.v', 'ball.contact']\n")
    master = Master(resolve_system(load_scenario(path)), result=tmp_path / f"ball{fmi_version}.csv")
    summary = master.run()
    event_mode = [getattr(unit, "event_mode", False) for unit in master.units]
    return summary, columns(tmp_path / f"ball{fmi_version}.csv"), event_mode


@pytest.fixture(scope="module")
def me_events() -> np.ndarray:
    """fmpy's Model Exchange run of the FMI 2.0 BouncingBall (CVODE at rtol 1e-10 locating the
    roots of the event indicators): time, contact state before, contact state after each event."""
    from deltafmi.builder.packager import build_cached
    from conftest import FMU_SRC
    fmu = build_cached(FMU_SRC / "bouncing_ball.py", fmi_version=2)
    result = fmpy.simulate_fmu(str(fmu), fmi_type="ModelExchange", stop_time=STOP, output_interval=H,
                               relative_tolerance=1e-10, output=["q", "v", "contact"])
    t = result["time"]
    at = np.flatnonzero(np.diff(t) == 0)
    assert len(at) == 14
    return np.column_stack([t[at], result["contact"][at], result["contact"][at + 1]])


def test_the_fmi3_bouncing_ball_reports_its_impacts_to_the_master(tmp_path, me_events):
    """The FMI 3.0 build in event mode: 14 events, each recorded as two rows at its time, within
    1e-6 s of the Model Exchange event times, with the contact state before and after it that
    the Model Exchange run has. On the grid (the first row at each communication point) the
    values equal the FMI 2.0 build's, whose steps handle the same events inside: bit for bit, as
    the FMU restarts CVODE at the same events either way."""
    summary3, ours, event_mode3 = _run(tmp_path, 3)
    summary2, fmi2, event_mode2 = _run(tmp_path, 2)
    assert event_mode3 == [True] and event_mode2 == [False]
    assert summary3.events == 14 and summary2.events == 0
    t = ours["time"]
    before = np.flatnonzero(t[1:] == t[:-1])
    np.testing.assert_allclose(t[before], me_events[:, 0], rtol=0, atol=1e-6)
    np.testing.assert_array_equal(ours["ball.contact"][before], me_events[:, 1])
    np.testing.assert_array_equal(ours["ball.contact"][before + 1], me_events[:, 2])
    assert np.all(np.diff(fmi2["time"]) > 0)  # FMI 2.0: no event rows
    grid = np.searchsorted(t, fmi2["time"])  # the first row at each communication point
    np.testing.assert_array_equal(t[grid], fmi2["time"])
    assert len(t) == len(grid) + 2 * 14
    for name in ("ball.q", "ball.v", "ball.contact"):
        np.testing.assert_array_equal(ours[name][grid], fmi2[name])
