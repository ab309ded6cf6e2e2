"""deltafmi plot: units on the axes (from .parquet/.mat results and Result objects), one axis per
unit, differences of two signals and of two result files, names that contain '-'."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.results.plot import UnknownSignal
from deltafmi.master.results.result import result_figure
from deltafmi.master.results.result import read_result
from deltafmi.master.results.result import Result

T = np.linspace(0.0, 1.0, 101)


def tracking() -> Result:
    """Positions in m, a reference 3 um off, torques in N.m: a tracking run in miniature."""
    columns = {"time": T}
    units = {"time": "s"}
    for i in (1, 2, 3):
        columns[f"plant.z[{i}]"] = np.sin(T + i)
        columns[f"trajectory.r[{i}]"] = np.sin(T + i) - 3e-6 * i * T
        columns[f"controller.u[{i}]"] = 40.0 * np.cos(T * i)
        units.update({f"plant.z[{i}]": "m", f"trajectory.r[{i}]": "m", f"controller.u[{i}]": "N.m"})
    return Result(columns, units)


def lines(ax):
    return {line.get_label(): line.get_ydata() for line in ax.get_lines()}


def test_one_axis_per_unit_and_the_error_in_um():
    fig = result_figure(tracking(), ["plant.z", "trajectory.r[*]", "controller.u", "plant.z - trajectory.r"])
    axes = fig.axes
    assert [ax.get_ylabel() for ax in axes] == ["plant.z, trajectory.r [m]", "controller.u [N.m]",
                                              "plant.z - trajectory.r [um]"]
    assert axes[-1].get_xlabel() == "time [s]"
    assert sorted(lines(axes[0])) == sorted([f"plant.z[{i}]" for i in (1, 2, 3)] +
                                             [f"trajectory.r[{i}]" for i in (1, 2, 3)])
    errors = lines(axes[2])
    for i in (1, 2, 3):  # z - r = 3 i t um, drawn in um
        assert errors[f"plant.z[{i}] - trajectory.r[{i}]"] == pytest.approx(3.0 * i * T, abs=1e-9)


def test_one_curve_names_its_axis_with_the_unit():
    fig = result_figure(tracking(), ["controller.u[2]", "plant.z[1] - trajectory.r[1]"])
    assert [ax.get_ylabel() for ax in fig.axes] == ["controller.u[2] [N.m]", "plant.z[1] - trajectory.r[1] [um]"]


def test_separate_gives_each_curve_its_axis():
    fig = result_figure(tracking(), ["plant.z[1:2]"], separate=True)
    assert [ax.get_ylabel() for ax in fig.axes] == ["plant.z[1] [m]", "plant.z[2] [m]"]


@pytest.mark.parametrize("signal, message", [
    ("plant.z - controller.u", "'plant.z[1] - controller.u[1]': plant.z[1] is in m, controller.u[1] in N.m"),
    ("plant.z - trajectory.r[1]", "'plant.z - trajectory.r[1]': 3 signal(s) minus 1"),
    ("plant.z - trajectory.rr", "no column 'trajectory.rr' in the result (did you mean"),
])
def test_differences_that_do_not_fit(signal, message):
    with pytest.raises(UnknownSignal) as raised:
        result_figure(tracking(), [signal])
    assert message in str(raised.value)


def test_cli_plots_a_parquet_result_with_units_and_a_csv_without(tmp_path):
    result = tracking()
    result.save(tmp_path / "r.parquet")
    result.save(tmp_path / "r.csv")
    # a CSV keeps its units beside it (r.csv.units.json): its plot has them as the Parquet's has
    from_csv = result_figure(tmp_path / "r.csv", ["plant.z[1]", "plant.z - trajectory.r"])
    assert [ax.get_ylabel() for ax in from_csv.axes] == ["plant.z[1] [m]", "plant.z - trajectory.r [um]"]
    (tmp_path / "r.csv.units.json").unlink()  # a CSV from elsewhere: no units
    for name in ("r.parquet", "r.csv"):
        outcome = CliRunner().invoke(main, ["plot", str(tmp_path / name), "plant.z[1]", "plant.z - trajectory.r",
                                            "-o", str(tmp_path / f"{name}.png")])
        assert outcome.exit_code == 0, outcome.output
        assert (tmp_path / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
    with_units = result_figure(tmp_path / "r.parquet", ["plant.z[1]", "plant.z - trajectory.r"])
    assert [ax.get_ylabel() for ax in with_units.axes] == ["plant.z[1] [m]", "plant.z - trajectory.r [um]"]
    # a CSV without units: no brackets, a power of ten instead of a prefix (the difference on its
    # own axis still)
    without = result_figure(tmp_path / "r.csv", ["plant.z[1]", "plant.z - trajectory.r"])
    assert [ax.get_ylabel() for ax in without.axes] == ["plant.z[1]", "plant.z - trajectory.r (×1e-6)"]
    assert lines(without.axes[1])["plant.z[3] - trajectory.r[3]"] == pytest.approx(9.0 * T, abs=1e-9)


def test_a_name_with_a_minus_is_a_name(tmp_path):
    (tmp_path / "r.csv").write_text("time,a.x-y,a.z\n0.0,1.0,0.5\n1.0,2.0,0.25\n")
    fig = result_figure(tmp_path / "r.csv", ["a.x-y", "a.x-y - a.z"])
    assert [ax.get_ylabel() for ax in fig.axes] == ["a.x-y", "a.x-y - a.z"]
    assert list(lines(fig.axes[1])["a.x-y - a.z"]) == [0.5, 1.75]


def test_compare_two_result_files_on_the_first_ones_times(tmp_path):
    base = tracking()
    base.save(tmp_path / "a.parquet")
    t = np.linspace(0.0, 1.0, 11)  # coarser: interpolated onto a's times
    other = Result({"time": t, "plant.z[1]": np.sin(t + 1) + 2e-3 * t, "plant.z[2]": np.sin(t + 2)},
                   {"time": "s", "plant.z[1]": "m", "plant.z[2]": "m"})
    other.save(tmp_path / "b.parquet")
    fig = result_figure(tmp_path / "a.parquet", ["plant.z[1:2]"], compare=tmp_path / "b.parquet")
    (ax,) = fig.axes
    assert ax.get_ylabel() == "plant.z difference [mm]"
    drawn = lines(ax)
    expected = np.sin(T + 1) - np.interp(T, t, np.sin(t + 1) + 2e-3 * t)
    assert drawn["plant.z[1] (a.parquet - b.parquet)"] == pytest.approx(1e3 * expected, abs=1e-12)
    outcome = CliRunner().invoke(main, ["plot", str(tmp_path / "a.parquet"), "plant.z[3]", "--compare",
                                        str(tmp_path / "b.parquet"), "-o", str(tmp_path / "c.png")])
    assert outcome.exit_code == 2
    assert outcome.output.startswith("Error: b.parquet: no column 'plant.z[3]' in the result")


def test_axes_without_units_have_no_offset_beside_them(tmp_path):
    """The default CSV has no units: positions near -1 m that move by 1e-5 and an error of a few
    1e-6 read as plain numbers, the power of ten in the label, nothing beside the axis."""
    t = np.linspace(0.0, 1.0, 101)
    Result({"time": t, "plant.z[3]": -1.0 - 1e-5 * t, "trajectory.r[3]": -1.0 - 1e-5 * t + 4e-6 * t}).save(
        tmp_path / "r.csv")
    fig = result_figure(tmp_path / "r.csv", ["plant.z[3]", "trajectory.r[3]", "plant.z[3] - trajectory.r[3]"])
    fig.savefig(tmp_path / "r.png")  # draws: the tick labels and their offset text are set
    assert [ax.get_ylabel() for ax in fig.axes] == ["plant.z, trajectory.r", "plant.z[3] - trajectory.r[3] (×1e-6)"]
    assert [ax.yaxis.get_offset_text().get_text() for ax in fig.axes] == ["", ""]
    assert lines(fig.axes[1])["plant.z[3] - trajectory.r[3]"] == pytest.approx(-4.0 * t, abs=1e-6)
    ticks = [float(label.get_text().replace("\u2212", "-")) for label in fig.axes[0].get_yticklabels()]
    assert all(-1.00002 < tick < -0.99998 for tick in ticks)


@pytest.mark.parametrize("unit, values, label, factor", [
    ("deg", 3e-4, "a.x [deg] (×1e-3)", 1e3),    # no SI prefix for degrees: a power of ten
    ("m", 3e-4, "a.x [mm]", 1e3),
    ("", 3e-8, "a.x (×1e-9)", 1e9),
    ("", 40.0, "a.x", 1.0),
])
def test_an_axis_scale_without_a_prefix_is_a_power_of_ten(unit, values, label, factor):
    result = Result({"time": T, "a.x": values * T}, {"a.x": unit})
    (ax,) = result_figure(result, ["a.x"]).axes
    assert ax.get_ylabel() == label
    assert lines(ax)["a.x"] == pytest.approx(factor * values * T, rel=1e-12)


def test_a_result_without_rows_is_an_error_not_an_empty_figure(tmp_path):
    """A run that ended before its first row leaves a header: reading it is an empty result
    without numpy's 'input contained no data' warning; plotting it is exit 2."""
    path = tmp_path / "empty.csv"
    path.write_text("time,plant.z[1],plant.z[2]\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        empty = read_result(path)
    assert len(empty) == 0 and empty.names == ["plant.z[1]", "plant.z[2]"] and empty["plant.z"].shape == (0, 2)
    outcome = CliRunner().invoke(main, ["plot", str(path), "plant.z[1]", "-o", str(tmp_path / "f.png")])
    assert outcome.exit_code == 2 and outcome.output == f"Error: {path} has no rows\n"
    assert not (tmp_path / "f.png").exists()
    tracking().save(tmp_path / "full.csv")
    outcome = CliRunner().invoke(main, ["plot", str(tmp_path / "full.csv"), "plant.z[1]", "--compare", str(path),
                                        "-o", str(tmp_path / "f.png")])
    assert outcome.exit_code == 2 and outcome.output == f"Error: {path} has no rows\n"


def test_an_unknown_figure_format_blames_the_figure_file(tmp_path):
    tracking().save(tmp_path / "r.csv")
    for name, what in (("a.jpg2", "unknown format '.jpg2'"), ("a", "no extension")):
        outcome = CliRunner().invoke(main, ["plot", str(tmp_path / "r.csv"), "plant.z[1]", "-o", str(tmp_path / name)])
        assert outcome.exit_code == 2
        assert outcome.output.startswith(f"Error: figure file '{tmp_path / name}': {what}; use ")
        assert ".png" in outcome.output and ".pdf" in outcome.output and ".svg" in outcome.output
        assert not (tmp_path / name).exists()


def test_a_difference_without_spaces_gets_a_hint():
    with pytest.raises(UnknownSignal) as raised:
        result_figure(tracking(), ["plant.z-trajectory.r"])
    assert str(raised.value) == ("no column 'plant.z-trajectory.r' in the result; a difference is written "
                                 "with spaces: 'plant.z - trajectory.r'")
    with pytest.raises(UnknownSignal) as raised:  # only where both halves are there
        result_figure(tracking(), ["plant.z-trajectory.q"])
    assert "a difference is written" not in str(raised.value)
