"""A small study for the tests that need a real sweep: the Oscillator at three stiffnesses (its
position at 0.75 s and at the end), and its check against the closed form. Its input F is left
unconnected (at 0), so that a sweep has a scenario warning to show."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from oscillator_analytic import P, solution

SCENARIO = """\
experiment: {stop: 1.5, step: 1.0e-2}
components:
  osc: {source: deltafmi.models:Oscillator, interface: ME, solver: {rtol: 1.0e-10, atol: 1.0e-12}}
outputs: [osc.x]
"""
STUDY = """\
scenario: osc.yaml
vary:
  grid:
    osc.k: [20.0, 40.0, 60.0]
metrics:
  x_final: {signal: osc.x, statistic: final}
  x_at: {signal: osc.x, statistic: at, time: 0.75}
"""


def write_study(folder: Path) -> Path:
    """The scenario and the study in ``folder``; returns the study's path."""
    (folder / "osc.yaml").write_text(SCENARIO)
    (folder / "osc_study.yaml").write_text(STUDY)
    return folder / "osc_study.yaml"


def check_closed_form(table: Path) -> None:
    """Every case of the study's result ``table`` ran and equals the closed form to 1e-7 m."""
    rows = pq.read_table(table).to_pylist()
    assert [row["osc.k"] for row in rows] == [20.0, 40.0, 60.0]
    for row in rows:
        assert row["status"] == "ok", row["error"]
        x, _, impacts = solution(np.array([0.75, 1.5]), p={**P, "k": row["osc.k"]})
        assert impacts  # every case bounces on the wall
        assert row["x_at"] == pytest.approx(x[0], abs=1e-7)
        assert row["x_final"] == pytest.approx(x[1], abs=1e-7)
