"""deltafmi plot: units on the axes (from .parquet/.mat results and Result objects), one axis per
unit, differences of two signals and of two result files, names that contain '-'."""
from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from deltafmi.cli import main
from deltafmi.cosim.results.plot import UnknownSignal, result_figure
from deltafmi.cosim.results.result import Result

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
    assert [ax.get_ylabel() for ax in axes] == ["[m]", "[N.m]", "difference [um]"]
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
    for name in ("r.parquet", "r.csv"):
        outcome = CliRunner().invoke(main, ["plot", str(tmp_path / name), "plant.z[1]", "plant.z - trajectory.r",
                                            "-o", str(tmp_path / f"{name}.png")])
        assert outcome.exit_code == 0, outcome.output
        assert (tmp_path / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
    with_units = result_figure(tmp_path / "r.parquet", ["plant.z[1]", "plant.z - trajectory.r"])
    assert [ax.get_ylabel() for ax in with_units.axes] == ["plant.z[1] [m]", "difference [um]"]
    # a CSV carries no units: no brackets, values as they are (the difference on its own axis still)
    without = result_figure(tmp_path / "r.csv", ["plant.z[1]", "plant.z - trajectory.r"])
    assert [ax.get_ylabel() for ax in without.axes] == ["plant.z[1]", "difference"]
    assert lines(without.axes[1])["plant.z[3] - trajectory.r[3]"] == pytest.approx(9e-6 * T, abs=1e-15)


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
    assert ax.get_ylabel() == "difference [mm]"
    drawn = lines(ax)
    expected = np.sin(T + 1) - np.interp(T, t, np.sin(t + 1) + 2e-3 * t)
    assert drawn["plant.z[1] (a.parquet - b.parquet)"] == pytest.approx(1e3 * expected, abs=1e-12)
    outcome = CliRunner().invoke(main, ["plot", str(tmp_path / "a.parquet"), "plant.z[3]", "--compare",
                                        str(tmp_path / "b.parquet"), "-o", str(tmp_path / "c.png")])
    assert outcome.exit_code == 2
    assert outcome.output.startswith("Error: b.parquet: no column 'plant.z[3]' in the result")
