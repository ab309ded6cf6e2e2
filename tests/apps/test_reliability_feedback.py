"""Feedback: a CSV result keeps its units (beside it) and its plots show them; a warning repeated
hundreds of times shows a few times and then as a count; the summary's real-time factor is the
stepping's, the figure the README quotes, with the whole run's beside it."""
from __future__ import annotations

import json
import re

import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.apps.console import RepeatedWarnings
from deltafmi.master.results.csv_file import units_file
from deltafmi.master.results.result import result_figure
from deltafmi.master.results.progress import Summary
from deltafmi.master.results.result import read_result


def test_a_csv_result_carries_its_units_and_its_plot_shows_them(tmp_path):
    out = tmp_path / "r.csv"
    done = CliRunner().invoke(main, ["run", "delta_tracking", "--stop", "0.05", "-q", "-o", str(out)])
    assert done.exit_code == 0, done.output
    units = json.loads(units_file(out).read_text())
    assert units["time"] == "s" and units["plant.z[3]"] == "m" and units["controller.u[1]"] == "N.m"
    assert read_result(out).unit("plant.z") == "m"
    figure = result_figure(out, ["plant.z[3]", "controller.u[1]"])
    assert [ax.get_ylabel() for ax in figure.axes] == ["plant.z[3] [m]", "controller.u[1] [N.m]"]
    assert figure.axes[-1].get_xlabel() == "time [s]"
    # a failed run's rows keep theirs beside their own name
    assert units_file(tmp_path / "r.failed.csv").name == "r.failed.csv.units.json"


def test_repeated_warnings_show_a_few_times_then_as_a_count(capsys):
    warn = RepeatedWarnings(keep=3)
    for k in range(258):
        warn(f"fell behind real time at t = {k * 0.078:.6g} s: released {100 + k} us late")
    warn("something else at t = 1 s")
    warn.close()
    lines = capsys.readouterr().err.splitlines()
    assert lines[:3] == ["warning: fell behind real time at t = 0 s: released 100 us late",
                         "warning: fell behind real time at t = 0.078 s: released 101 us late",
                         "warning: fell behind real time at t = 0.156 s: released 102 us late"]
    assert lines[3] == "warning: more warnings like this one are counted, not shown"
    assert lines[4] == "warning: something else at t = 1 s"
    assert lines[5] == ("warning: 255 more warnings like 'fell behind real time at t = 0 s: released 100 us late' "
                        "not shown (258 in all)")
    assert len(lines) == 6


def test_warnings_that_differ_in_a_unit_of_time_are_one_kind(capsys):
    """The pacing says '10.1 ms late' or '9069.7 us late' as the lateness goes: one kind, counted
    once (a paced run on a loaded machine showed three kinds of it, three lines each)."""
    warn = RepeatedWarnings(keep=3)
    for k, late in enumerate(["10.1 ms", "9069.7 us", "15.6 ms", "5157.0 us", "1.2 s", "812 ns"]):
        warn(f"fell behind real time at t = {k * 0.01:.6g} s: released {late} late, more than a whole step "
             "(1000.0 us of wall time); going on")
    warn.close()
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 5 and lines[3] == "warning: more warnings like this one are counted, not shown"
    assert lines[4].startswith("warning: 3 more warnings like 'fell behind real time at t = 0 s: released 10.1 ms")


def test_the_real_time_factor_is_the_stepping_s_with_the_whole_run_s_beside_it():
    summary = Summary(steps=3500, rejected=0, events=0, wall_time=0.35, simulated=3.5, rows=3501,
                      result="r.csv", setup_time=0.32, close_time=0.014)
    text = str(summary)
    stepping = 3.5 / (0.35 - 0.32 - 0.014)
    assert summary.stepping_factor == pytest.approx(stepping) and summary.real_time_factor == pytest.approx(10.0)
    assert (f"3.5 s simulated in 0.350 s wall (real-time factor {stepping:.1f}x stepping, 10.0x with the 0.33 s "
            "of loading and writing)") in text


def test_a_run_s_summary_says_both_factors(tmp_path):
    done = CliRunner().invoke(main, ["run", "delta_tracking", "--stop", "0.2", "-o", str(tmp_path / "r.csv")])
    assert done.exit_code == 0, done.output
    match = re.search(r"\(real-time factor (\S+)x stepping, (\S+)x with the (\S+) s of loading and writing\)",
                      done.output)
    assert match, done.output
    assert float(match[1]) > float(match[2]) > 0  # the stepping alone is faster than the whole run


def test_a_run_without_a_terminal_prints_a_progress_line_at_a_modest_rate():
    import io
    import time

    from deltafmi.master.results import progress as module
    stream = io.StringIO()
    bar = module.Progress(0.0, 10.0, enabled=False, stream=stream, lines=True)
    bar.update(1.0)  # within LINE_EVERY of the start: nothing yet
    assert stream.getvalue() == ""
    bar._next_draw = time.monotonic() - 1  # the next line is due
    bar.update(4.2)
    bar.update(4.3)  # LINE_EVERY later at the earliest
    bar.close(10.0)
    assert stream.getvalue() == "progress:  42.0% t = 4.2 s\n" and module.LINE_EVERY >= 10


def test_a_small_real_time_factor_keeps_its_digits():
    summary = Summary(steps=10, rejected=0, events=0, wall_time=1.2, simulated=0.01, rows=11, result="r.csv",
                      setup_time=1.19, close_time=0.0)
    assert "0.0083x with the 1.19 s" in str(summary)  # not 0.0x
