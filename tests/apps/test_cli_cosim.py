"""``deltafmi run``, ``validate``, ``plot`` and ``build`` through click's CliRunner: help texts, exit
codes, one-line reasons, result files; Ctrl-C and SIGTERM sent to a real ``deltafmi run``."""
from __future__ import annotations

import io
import re
import signal
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns
from deltafmi.master.results.progress import Progress
from deltafmi.files import USER_FILE_MODE
from signal_runs import DELTAFMI, interrupt_when, rows_in


@pytest.fixture(scope="module")
def scenario(build_fmu_from_src, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("cli")
    path = folder / "osc.yaml"
    path.write_text(f"experiment: {{stop: 1.0, step: 0.01}}\n"
                    f"components:\n  osc: {{fmu: {build_fmu_from_src('oscillator.py')}, interface: ME}}\n"
                    "outputs: [osc.x, osc.v, osc.energy]\nresult: {file: out/osc.csv}\n")
    return path


@pytest.mark.parametrize("command, example", [
    ("run", "deltafmi run delta_tracking -o tracking.csv --stop 2"),
    ("validate", "deltafmi validate delta_tracking"),
    ("plot", "deltafmi plot tracking.csv 'plant.z[*]' 'trajectory.r[1:3]' -o tracking.png"),
    ("export-ssp", "deltafmi export-ssp bouncing_ball -o bouncing_ball.ssp"),
])
def test_help_shows_an_example(command, example):
    result = CliRunner().invoke(main, [command, "--help"])
    assert result.exit_code == 0
    assert ("Example:" in result.output or "Examples:" in result.output) and example in result.output


def test_run_writes_result_and_summary(scenario):
    result = CliRunner().invoke(main, ["run", str(scenario)])
    assert result.exit_code == 0, result.output
    assert "\r" not in result.output  # no progress bar: stdout is not a terminal
    summary = result.stdout.strip().splitlines()[-1]
    assert summary.startswith("100 steps (0 rejected), 2 events, 1 s simulated in ")  # 2 wall impacts
    assert "real-time factor" in summary
    written = scenario.parent / "out" / "osc.csv"  # result.file is relative to the scenario
    assert columns(written)["time"][-1] == 1.0


def test_run_output_and_stop_options(scenario, tmp_path):
    out = tmp_path / "short.csv"
    result = CliRunner().invoke(main, ["run", str(scenario), "-o", str(out), "--stop", "0.5", "--quiet"])
    assert result.exit_code == 0, result.output
    assert result.output == "" or result.output.startswith(f"{scenario}:")  # only warnings
    assert columns(out)["time"][-1] == 0.5


def test_run_with_bad_scenario_exits_2(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("experiment: {stop: 1.0, step: 0.1}\ncomponents:\n  a: {fmu: missing.fmu}\n")
    result = CliRunner().invoke(main, ["run", str(bad)])
    assert result.exit_code == 2
    assert result.output.strip().splitlines()[-1] == \
        f"{bad}:3: error: component 'a': FMU 'missing.fmu' not found"


def test_run_failure_exits_1_with_one_line_reason(scenario, tmp_path):
    failing = tmp_path / "fail.yaml"
    failing.write_text(scenario.read_text().replace(
        "interface: ME}", "interface: ME, parameters: {F_step: 1.0e+308, t_step: 0.5}}"))
    result = CliRunner().invoke(main, ["run", str(failing), "-o", str(tmp_path / "f.csv")])
    assert result.exit_code == 1
    last = result.output.strip().splitlines()[-1]
    assert last.startswith("Error: simulation failed at t = 0.5 s: osc: CVODE failed")
    assert last.endswith(f"(results up to the failure in {tmp_path / 'f.failed.csv'})")
    assert columns(tmp_path / "f.failed.csv")["time"][-1] == pytest.approx(0.5)
    assert not (tmp_path / "f.csv").exists()


def test_validate_prints_summary(scenario):
    result = CliRunner().invoke(main, ["validate", str(scenario)])
    assert result.exit_code == 0, result.output
    assert "1 components, 0 scalar connections, 3 recorded variables" in result.output
    assert result.output.strip().endswith(f"{scenario}: OK")


def test_plot_writes_png(scenario, tmp_path):
    CliRunner().invoke(main, ["run", str(scenario), "-o", str(tmp_path / "r.csv"), "-q"])
    figure = tmp_path / "fig.png"
    result = CliRunner().invoke(main, ["plot", str(tmp_path / "r.csv"), "osc.x", "osc.*", "-o", str(figure),
                                       "--separate"])
    assert result.exit_code == 0, result.output
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and figure.stat().st_size > 10000


def test_plot_unknown_signal_exits_2_with_suggestion(scenario, tmp_path):
    CliRunner().invoke(main, ["run", str(scenario), "-o", str(tmp_path / "r.csv"), "-q"])
    result = CliRunner().invoke(main, ["plot", str(tmp_path / "r.csv"), "osc.enrgy", "-o", str(tmp_path / "f.png")])
    assert result.exit_code == 2
    assert result.output.strip() == "Error: no column 'osc.enrgy' in the result (did you mean 'osc.energy'?)"


def test_plot_rejects_a_file_that_is_no_result(tmp_path):
    junk = tmp_path / "junk.csv"
    junk.write_text("time,a\n0.0,zero\n")
    result = CliRunner().invoke(main, ["plot", str(junk), "a", "-o", str(tmp_path / "f.png")])
    assert result.exit_code == 2
    assert result.output.startswith(f"Error: cannot read '{junk}' as a result file")


def test_plot_leaves_out_string_columns(tmp_path):
    result = tmp_path / "r.csv"
    result.write_text('time,a.label,a.x\n0.0,"hello",1.0\n0.1,"world",2.0\n')
    png = tmp_path / "r.png"
    outcome = CliRunner().invoke(main, ["plot", str(result), "a.label", "-o", str(png)])
    assert outcome.exit_code == 2
    assert outcome.output == "Error: 'a.label' is a String column: a plot draws numbers\n"
    outcome = CliRunner().invoke(main, ["plot", str(result), "a.*", "-o", str(png)])
    assert outcome.exit_code == 0 and png.stat().st_size > 0


def test_progress_bar_draws_on_a_terminal():
    stream = io.StringIO()
    bar = Progress(0.0, 2.0, enabled=True, stream=stream)
    bar.update(0.5)
    bar.close(2.0)
    text = stream.getvalue()
    assert text.startswith("\r[") and " 25.0% t = 0.5 s" in text and text.endswith("100.0% t = 2 s\n")


@pytest.mark.parametrize("target", ["existing", "slash/"])
def test_build_into_a_directory_names_the_fmu_after_its_model(tmp_path, target):
    folder = tmp_path / target
    if target == "existing":
        folder.mkdir()
    source = Path(__file__).parents[2] / "fmu_src" / "oscillator.py"
    result = CliRunner().invoke(main, ["build", str(source), "-o", f"{tmp_path}/{target}", "--no-validate"])
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() == f"built {folder / 'Oscillator.fmu'}"
    made = f"made the folder {folder} (it did not exist)"
    assert result.stderr.strip() == ("" if target == "existing" else made)
    assert [p.name for p in folder.iterdir()] == ["Oscillator.fmu"]
    # written through a private temporary file, the FMU still gets the user's usual permissions
    assert (folder / "Oscillator.fmu").stat().st_mode & 0o777 == USER_FILE_MODE


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_interrupted_run_keeps_its_rows_and_says_where(build_fmu_from_src, tmp_path, signum, code):
    """A real ``deltafmi run`` of a long Co-Simulation (the FMU's CVODE runs Python code in this
    process, where the signal lands): stopped once rows are on disk, it ends between two
    steps, says when, and leaves every row up to there in the file."""
    path = tmp_path / "long.yaml"
    path.write_text(f"experiment: {{stop: 1.0e+6, step: 1.0e-3}}\n"
                    f"components:\n  osc: {{fmu: {build_fmu_from_src('oscillator.py')}, interface: CS}}\n"
                    "outputs: [osc.x, osc.v]\n")
    out = tmp_path / "long.csv"
    returncode, stdout, stderr = interrupt_when(
        [*DELTAFMI, "run", str(path), "-o", str(out)],
        lambda: rows_in(out) > 2, signum)  # header and two rows
    assert returncode == code, stderr
    assert "Traceback" not in stderr and stdout == ""
    last = stderr.strip().splitlines()[-1]
    match = re.fullmatch(r"interrupted at t = (\S+) s \(results up to (\S+) in (.+)\)", last)
    assert match, last
    assert match[3] == str(out)
    c = columns(out)
    assert float(match[1]) == float(match[2]) == pytest.approx(c["time"][-1], rel=1e-9)  # printed %.9g
    assert c["time"][-1] > 0
    assert np.array_equal(c["time"], np.arange(len(c["time"])) * 1e-3)  # every step up to there
