"""The peg robustness study's figures (docs/assembly.md, section 8; README): from a results table of
``deltafmi sweep peg_robustness``, success, peak force and insertion time within the chamfer
(offset d <= 2 mm) and per offset, and how many cases oscillated from sample to sample.

Oscillating: the study's ``oscillation`` metric (the contact force's ``alternation`` over the last
0.5 s) above 0.5 N. A table without that column (an older study) is given its value from the time
series kept next to it (``--timeseries``), computed by the same statistic.

Usage: python benchmarks/peg_study_summary.py peg_robustness.parquet [more.parquet ...]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from deltafmi.apps.studies.metrics import alternation
from deltafmi.apps.studies.spec import Window

OSCILLATING = 0.5   # N
FORCE = [f"plant.contact_force[{i}]" for i in (1, 2, 3)]


def _oscillation(table: Path, cases: pd.Index) -> pd.Series:
    series = table.with_suffix(".timeseries")
    values = {}
    for case in cases:
        run = pd.read_parquet(series / f"case={case}" / "part-0.parquet")
        values[case] = alternation(run["time"].to_numpy(), run[FORCE].to_numpy(), None, Window(3.0, None))
    return pd.Series(values)


def summary(path: Path) -> None:
    r = pd.read_parquet(path).set_index("case")
    if "oscillation" not in r:
        r["oscillation"] = _oscillation(path, r.index)
    d = r["plant.hole_position[1]"]
    inside = r[d <= 0.002 + 1e-9]
    print(f"{path}: {len(r)} cases, {(r.status != 'ok').sum()} failed")
    print(f"  within the chamfer (d <= 2 mm, {len(inside)} cases): success {inside.success.mean() * 100:.1f} %, "
          f"peak |F| median {inside.peak_force.median():.1f} N, 95th percentile {inside.peak_force.quantile(0.95):.1f} N, "
          f"max {inside.peak_force.max():.1f} N; insertion time median {inside.insertion_time.median():.2f} s, "
          f"max {inside.insertion_time.max():.2f} s")
    for offset in sorted(d.unique()):
        s = r[np.isclose(d, offset)]
        print(f"  d {offset * 1e3:4.2f} mm: success {s.success.mean() * 100:5.1f} %, peak |F| median "
              f"{s.peak_force.median():5.1f} N, max {s.peak_force.max():6.1f} N, oscillation max {s.oscillation.max():.3f} N")
    print(f"  oscillating (oscillation > {OSCILLATING} N): {(r.oscillation > OSCILLATING).sum()} of {len(r)}; "
          f"largest {r.oscillation.max():.3f} N; peak |F| over 40 N: {(r.peak_force > 40.0).sum()}, "
          f"largest {r.peak_force.max():.1f} N")


if __name__ == "__main__":
    for name in sys.argv[1:]:
        summary(Path(name))
