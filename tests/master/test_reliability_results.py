"""Results are never lost: a run writes a temporary file beside its result file and moves it into
place when it ends; a failed run keeps its rows under a name that says so and leaves an earlier
result as it was; SIGINT, SIGTERM and SIGHUP leave a readable file; a killed run leaves the
earlier file intact."""
from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import scipy.io
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns
from deltafmi.master.results.safe_file import failed_name
from signal_runs import DELTAFMI, bytes_in, growing, interrupt_when

SUFFIXES = ["csv", "parquet", "mat"]


@pytest.fixture(scope="module")
def oscillator(build_fmu_from_src) -> Path:
    return build_fmu_from_src("oscillator.py")


@pytest.fixture(scope="module")
def scenarios(oscillator, tmp_path_factory) -> dict:
    """A good run to t = 1 s, and the same run made to fail at t = 0.5 s (CVODE, a force of 1e308)."""
    folder = tmp_path_factory.mktemp("runs")
    good = folder / "osc.yaml"
    good.write_text(f"experiment: {{stop: 1.0, step: 0.01}}\n"
                    f"components:\n  osc: {{fmu: {oscillator}, interface: ME}}\n"
                    "outputs: [osc.x, osc.v]\n")
    bad = folder / "fail.yaml"
    bad.write_text(good.read_text().replace("interface: ME}",
                                            "interface: ME, parameters: {F_step: 1.0e+308, t_step: 0.5}}"))
    long = folder / "long.yaml"
    long.write_text(f"experiment: {{stop: 1.0e+6, step: 1.0e-3}}\n"
                    f"components:\n  osc: {{fmu: {oscillator}, interface: CS}}\n"
                    "outputs: [osc.x, osc.v]\n")
    return {"good": good, "bad": bad, "long": long}


def _times(path: Path) -> np.ndarray:
    if path.suffix == ".csv":
        return columns(path)["time"]
    if path.suffix == ".parquet":
        return pq.read_table(path).column("time").to_numpy()
    return scipy.io.loadmat(path)["time"].ravel()


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_a_failed_run_leaves_the_earlier_result_and_keeps_its_rows_beside_it(scenarios, tmp_path, suffix):
    out = tmp_path / f"r.{suffix}"
    done = CliRunner().invoke(main, ["run", str(scenarios["good"]), "-o", str(out), "-q"])
    assert done.exit_code == 0, done.output
    before = out.read_bytes()
    failed = CliRunner().invoke(main, ["run", str(scenarios["bad"]), "-o", str(out)])
    assert failed.exit_code == 1
    kept = tmp_path / f"r.failed.{suffix}"
    assert failed_name(out) == kept
    last = failed.output.strip().splitlines()[-1]
    assert last.endswith(f"(results up to the failure in {kept}; {out} left as it was)"), last
    assert out.read_bytes() == before  # the complete result, byte for byte
    assert _times(out)[-1] == pytest.approx(1.0)
    t = _times(kept)
    assert t[0] == 0.0 and 0.49 <= t[-1] <= 0.5
    left = sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".units.json"))
    assert left == sorted([out.name, kept.name])  # no temporary left


def test_a_completed_run_replaces_the_earlier_result_and_a_later_failure_replaces_the_failed_one(scenarios,
                                                                                                  tmp_path):
    out = tmp_path / "r.csv"
    for _ in range(2):
        assert CliRunner().invoke(main, ["run", str(scenarios["bad"]), "-o", str(out)]).exit_code == 1
    assert not out.exists() and (tmp_path / "r.failed.csv").is_file()
    assert CliRunner().invoke(main, ["run", str(scenarios["good"]), "-o", str(out), "-q"]).exit_code == 0
    assert _times(out)[-1] == pytest.approx(1.0)


def test_a_nan_names_the_failed_file_and_leaves_the_earlier_result(tmp_path):
    from test_troubleshooting_docs import NAN_SOURCE  # a component whose output becomes NaN after 0.05 s
    (tmp_path / "nanny.py").write_text(NAN_SOURCE)
    scenario = tmp_path / "nan.yaml"
    scenario.write_text("experiment: {stop: 0.1, step: 1.0e-3}\ncomponents:\n  n: {source: nanny.py}\n")
    (tmp_path / "r.csv").write_text("time,n.y\n0,1\n")
    done = CliRunner().invoke(main, ["run", str(scenario), "-o", str(tmp_path / "r.csv")])
    assert done.exit_code == 1, done.output
    assert done.output.strip().splitlines()[-1] == (
        f"Error: n.y is NaN at t = 0.051 s; the rows up to there are in {tmp_path / 'r.failed.csv'}; "
        f"{tmp_path / 'r.csv'} left as it was (to record it and go on: --allow-nan, or allow_nan: true under "
        "master:)")
    assert (tmp_path / "r.csv").read_text() == "time,n.y\n0,1\n"
    kept = columns(tmp_path / "r.failed.csv")
    assert kept["time"][-1] == pytest.approx(0.051) and np.isnan(kept["n.y"][-1])


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_every_catchable_signal_leaves_a_readable_parquet_in_place(scenarios, tmp_path, signum):
    out = tmp_path / "r.parquet"
    out.write_bytes(b"an earlier result")
    code, stdout, stderr = interrupt_when([*DELTAFMI, "run", str(scenarios["long"]), "-o", str(out)],
                                          lambda: bytes_in(out) > 4, signum)
    assert code == 128 + signum, stderr
    assert "Traceback" not in stderr
    assert stderr.strip().splitlines()[-1].startswith("interrupted at t = ")
    t = pq.read_table(out).column("time").to_numpy()
    assert t[-1] > 0 and np.array_equal(t, np.arange(len(t)) * 1e-3)
    assert [p.name for p in tmp_path.iterdir()] == ["r.parquet"]


def test_sighup_is_left_alone_under_nohup(scenarios, tmp_path):
    """``nohup deltafmi run ...``: a closed terminal must not stop it (SIGHUP ignored stays ignored)."""
    out = tmp_path / "r.csv"
    process = subprocess.Popen(["nohup", *DELTAFMI, "run", str(scenarios["long"]), "-o", str(out)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 600
        while bytes_in(out) < 100:
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        process.send_signal(signal.SIGHUP)
        time.sleep(1.0)
        assert process.poll() is None  # still running
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=600)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 143, stderr
    assert columns(out)["time"][-1] > 0


def test_a_killed_run_leaves_the_earlier_result_intact(scenarios, tmp_path):
    out = tmp_path / "r.csv"
    out.write_text("time,osc.x\n0,1\n")
    code, _, _ = interrupt_when([*DELTAFMI, "run", str(scenarios["long"]), "-o", str(out)],
                                lambda: bytes_in(out) > 1000, signal.SIGKILL)
    assert code == -signal.SIGKILL
    assert out.read_text() == "time,osc.x\n0,1\n"
    left = growing(out)  # the killed run's rows, hidden beside it
    assert left is not None and left.name.startswith(".r.csv.")
    text = left.read_text()
    whole = text[:text.rfind("\n") + 1].splitlines()  # a kill may cut the last write short
    assert whole[0] == "time,osc.x,osc.v" and len(whole) > 2
    times = [float(line.split(",")[0]) for line in whole[1:]]
    assert times == [pytest.approx(k * 1e-3, abs=1e-12) for k in range(len(times))]


@pytest.mark.parametrize("output, expected", [
    ("afile/r.csv", "result file '{tmp}/afile/r.csv': {tmp}/afile is a file, not a folder"),
    ("afile/deeper/r.csv", "result file '{tmp}/afile/deeper/r.csv': {tmp}/afile is a file, not a folder"),
    ("folder.csv", "Invalid value for '-o' / '--output': File '{tmp}/folder.csv' is a directory."),
    ("/sys/r.csv", "result file '/sys/r.csv': cannot write in /sys: Permission denied"),
])
def test_an_output_that_cannot_be_written_is_refused_before_the_run(scenarios, tmp_path, output, expected):
    (tmp_path / "afile").write_text("")
    (tmp_path / "folder.csv").mkdir()
    target = output if output.startswith("/") else str(tmp_path / output)
    done = CliRunner().invoke(main, ["run", str(scenarios["good"]), "-o", target])
    assert done.exit_code == 2, done.output
    assert done.output.strip().splitlines()[-1] == "Error: " + expected.format(tmp=tmp_path)
