"""deltafmi plot-study on results tables: a line per parameter, a heat map for two, a histogram for
Monte Carlo; failed cases are gaps; wrong names are errors with suggestions (exit code 2)."""
from __future__ import annotations

import math

import matplotlib.image
import numpy as np
import pyarrow.parquet as pq
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.apps.studies.store import ResultStore, read_results, study_metadata


def results(tmp_path, monte_carlo: bool = False):
    """A results table as deltafmi sweep writes it: y = a * b (a x b grid) or samples of a."""
    targets = [{"name": "ctl.a", "kind": "monte_carlo" if monte_carlo else "grid", "unit": "1/s"}]
    if not monte_carlo:
        targets.append({"name": "plant.b", "kind": "grid", "unit": "kg"})
    metadata = {"study": "s.yaml", "targets": targets, "metrics": [{"name": "y", "unit": "m"}]}
    store = ResultStore(tmp_path / "r.parquet", "f", [t["name"] for t in targets], ["y"], metadata)
    rng = np.random.default_rng(1)
    rows = []
    grid = [(a, b) for a in (1.0, 2.0, 3.0) for b in (0.0, 1.0, 2.0, 4.0)]
    points = [(a, None) for a in rng.normal(1.0, 0.1, 300)] if monte_carlo else grid
    for i, (a, b) in enumerate(points):
        failed = not monte_carlo and (a, b) == (3.0, 4.0)
        values = {"ctl.a": a} if b is None else {"ctl.a": a, "plant.b": b}
        rows.append({"case": i, "values": values, "metrics": {"y": math.nan if failed else a * (b or 1.0)},
                     "status": "failed" if failed else "ok", "error": "boom" if failed else "",
                     "wall_time": 0.1, "setup_time": 0.01, "sim_time": 0.08, "worker": "w"})
    pq.write_table(store.build_table(rows), store.table)
    return store.table


def plot(*arguments):
    return CliRunner().invoke(main, ["plot-study", *map(str, arguments)])


def test_tables_keep_their_study_description(tmp_path):
    table = read_results(results(tmp_path))
    assert study_metadata(table)["targets"][1]["name"] == "plant.b"
    assert table.column_names == ["case", "ctl.a", "plant.b", "y", "status", "error", "wall_time", "setup_time",
                                  "sim_time", "worker"]


def test_heat_map_line_and_histogram(tmp_path):
    table = results(tmp_path)
    for extra, name in (([], "heat.png"), (["--x", "plant.b"], "lines.png"), (["--kind", "line", "--log"], "log.png")):
        result = plot(table, "-o", tmp_path / name, *extra)
        assert result.exit_code == 0, result.output
        assert matplotlib.image.imread(tmp_path / name).shape[0] > 200
    (tmp_path / "mc").mkdir()
    mc = results(tmp_path / "mc", monte_carlo=True)
    result = plot(mc, "-o", tmp_path / "hist.png")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "hist.png").stat().st_size > 10000


def test_wrong_names_are_reported_with_suggestions(tmp_path):
    table = results(tmp_path)
    result = plot(table, "-o", tmp_path / "x.png", "-m", "yy")
    assert result.exit_code == 2 and "no metric 'yy'" in result.output and "did you mean 'y'" in result.output
    result = plot(table, "-o", tmp_path / "x.png", "--x", "plant.bb")
    assert result.exit_code == 2 and "did you mean 'plant.b'" in result.output
    (tmp_path / "junk.parquet").write_text("not parquet")
    result = plot(tmp_path / "junk.parquet", "-o", tmp_path / "x.png")
    assert result.exit_code == 2 and "cannot read" in result.output and "Traceback" not in result.output


def test_heat_map_cells_show_the_median_or_the_mean_of_their_cases():
    """Two samples per grid point: the median and mean of (1, 0) and (1, 1); a failed (NaN) case
    is left out of its cell; --cell mean of a 0/1 metric is the success rate."""
    from deltafmi.apps.studies.plot import heatmap_cells

    xs, ys = [0.0, 0.0, 1.0, 1.0, 0.0, 0.0], ["a", "a", "a", "a", "b", "b"]
    values = np.array([1.0, 0.0, 1.0, 1.0, 0.0, math.nan])
    x_values, y_values, grid, several = heatmap_cells(xs, ys, values, "mean")
    assert x_values == [0.0, 1.0] and y_values == ["a", "b"] and several
    assert grid[0].tolist() == [0.5, 1.0] and grid[1, 0] == 0.0 and math.isnan(grid[1, 1])
    assert heatmap_cells(xs, ys, values)[2][0].tolist() == [0.5, 1.0]  # median of two is their mean too
    assert heatmap_cells(xs, ys, np.array([1.0, 0.0, 0.0, 0.0, 1.0, 1.0]), "median")[2][0, 1] == 0.0


def test_success_map_from_the_command_line(tmp_path):
    result = plot(results(tmp_path), "-o", tmp_path / "rate.png", "--cell", "mean", "-m", "y")
    assert result.exit_code == 0, result.output
    assert plot(results(tmp_path), "-o", tmp_path / "x.png", "--cell", "mode").exit_code == 2
