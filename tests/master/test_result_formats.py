"""``deltafmi run -o`` picks the result format by extension: .csv, .parquet (units in the field
metadata), .mat (MATLAB names plus the original names); other extensions are refused before
anything runs; a failed or interrupted run leaves a readable file with the rows so far."""
from __future__ import annotations

import os
import re
import signal
import threading
from pathlib import Path

import fmpy
import numpy as np
import pyarrow.parquet as pq
import pytest
import scipy.io
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns, read_units
from deltafmi.master.results.writers import matlab_names
from signal_runs import DELTAFMI, bytes_in, interrupt_when

OUTPUTS = ["osc.x", "osc.v", "osc.energy", "osc.F"]


@pytest.fixture(scope="module")
def oscillator(build_fmu_from_src) -> Path:
    return build_fmu_from_src("oscillator.py")


@pytest.fixture(scope="module")
def scenario(oscillator, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("formats") / "osc.yaml"
    path.write_text(f"experiment: {{stop: 1.0, step: 0.01}}\n"
                    f"components:\n  osc: {{fmu: {oscillator}, interface: ME}}\n"
                    f"outputs: [{', '.join(OUTPUTS)}]\n")
    return path


@pytest.fixture(scope="module")
def results(scenario, tmp_path_factory):
    """The same run written as .csv, .parquet and .mat."""
    folder = tmp_path_factory.mktemp("out")
    paths = {}
    for suffix in ("csv", "parquet", "mat"):
        paths[suffix] = folder / f"r.{suffix}"
        result = CliRunner().invoke(main, ["run", str(scenario), "-o", str(paths[suffix]), "-q"])
        assert result.exit_code == 0, result.output
    return paths


def _units_from_model_description(fmu: Path) -> dict:
    """Units read straight from the FMU's modelDescription.xml (declared type as fallback)."""
    description = fmpy.read_model_description(str(fmu))
    return {f"osc.{v.name}": v.unit or (v.declaredType.unit if v.declaredType is not None else "") or ""
            for v in description.modelVariables}


def test_three_formats_hold_the_same_numbers(results):
    csv = columns(results["csv"])
    table = pq.read_table(results["parquet"])
    mat = scipy.io.loadmat(results["mat"])
    assert table.column_names == ["time", *OUTPUTS] == list(csv)
    assert len(csv["time"]) > 100  # 100 steps and the event rows of the wall impacts
    variables = {str(n[0]): str(v[0]) for n, v in zip(mat["names"].ravel(), mat["variables"].ravel())}
    for name in ["time", *OUTPUTS]:
        expected = csv[name]
        assert np.array_equal(table.column(name).to_numpy(), expected), name
        mat_name = "time" if name == "time" else variables[name]
        assert mat[mat_name].shape == (len(expected), 1)
        assert np.array_equal(mat[mat_name].ravel(), expected), name


def test_parquet_units_are_the_model_descriptions(results, oscillator):
    units = _units_from_model_description(oscillator)
    assert units["osc.x"] == "m" and units["osc.energy"] == "J"  # the oscillator declares them
    schema = pq.read_schema(results["parquet"])
    assert schema.field("time").metadata == {b"unit": b"s"}
    for name in OUTPUTS:
        assert schema.field(name).metadata[b"unit"].decode() == units[name], name


def test_mat_maps_back_to_the_original_names(results, oscillator):
    mat = scipy.io.loadmat(results["mat"])
    names = [str(x[0]) for x in mat["names"].ravel()]
    variables = [str(x[0]) for x in mat["variables"].ravel()]
    units = [str(x[0]) if x.size else "" for x in mat["units"].ravel()]
    assert names == OUTPUTS
    assert variables == ["osc_x", "osc_v", "osc_energy", "osc_F"]
    expected = _units_from_model_description(oscillator)
    assert units == [expected[n] for n in OUTPUTS]
    for variable in variables:
        assert re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,62}", variable) and variable in mat


def test_matlab_names_are_valid_and_distinct():
    names = ["plant.z[3]", "plant.z_3", "der(plant.x)", "1st.value", "time", "a" * 80, "a" * 80 + "b"]
    mapped = matlab_names(names)
    assert mapped[:5] == ["plant_z_3", "plant_z_3_2", "der_plant_x", "x1st_value", "time_2"]
    assert len(set(mapped)) == len(mapped)
    assert all(re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,62}", m) for m in mapped)


def test_every_fmi_type_gets_its_column_type(tmp_path):
    """Rows with Real, Integer, Boolean, Enumeration and String values, through all three writers
    (String values with a quote and a comma), in row groups of 3: the same values read back."""
    from deltafmi.master.results.csv_file import CsvWriter
    from deltafmi.master.results.writers import MatWriter, ParquetWriter

    names = ["a.x", "a.n", "a.b", "a.e", "a.s"]
    kinds = ["Real", "Integer", "Boolean", "Enumeration", "String"]
    units = ["m", "", "", "", ""]
    writers = [CsvWriter(tmp_path / "t.csv", names, kinds=kinds),
               ParquetWriter(tmp_path / "t.parquet", names, kinds=kinds, units=units, chunk=3),
               MatWriter(tmp_path / "t.mat", names, kinds=kinds, units=units, chunk=3)]
    for i in range(7):
        row = np.array([0.1 * i, i - 3, i % 2, 2, f'v"{i},'], dtype=object)
        for writer in writers:
            writer.write(0.01 * i, row)
    for writer in writers:
        writer.close()
    assert [w.rows_written for w in writers] == [7, 7, 7]
    csv = columns(tmp_path / "t.csv")
    table = pq.read_table(tmp_path / "t.parquet").to_pydict()
    assert table["a.n"] == list(range(-3, 4)) and table["a.b"] == [i % 2 == 1 for i in range(7)]
    assert table["a.e"] == [2] * 7 and table["a.s"] == list(csv["a.s"]) == [f'v"{i},' for i in range(7)]
    assert table["time"] == list(csv["time"]) and table["a.x"] == list(csv["a.x"])
    mat = scipy.io.loadmat(tmp_path / "t.mat")
    for name, variable in zip(names[:4], ["a_x", "a_n", "a_b", "a_e"]):
        assert np.array_equal(mat[variable].ravel(), csv[name].astype(float)), name
    assert [str(x[0]) for x in mat["a_s"].ravel()] == list(csv["a.s"])


@pytest.mark.parametrize("suffix", [".txt", ".xlsx", ""])
def test_unknown_extension_is_refused_before_running(scenario, tmp_path, suffix):
    out = tmp_path / f"r{suffix}"
    result = CliRunner().invoke(main, ["run", str(scenario), "-o", str(out)])
    assert result.exit_code == 2
    assert "Traceback" not in result.output and isinstance(result.exception, SystemExit)
    last = result.output.strip().splitlines()[-1]
    shown = suffix or "(no extension)"
    assert last == f"Error: result file '{out}': unknown format '{shown}'; use .csv, .parquet, .mat"
    assert list(tmp_path.iterdir()) == []


def test_scenario_result_file_with_unknown_extension_is_refused(scenario, tmp_path):
    path = tmp_path / "osc.yaml"
    path.write_text(scenario.read_text() + "result: {file: out/r.txt}\n")
    result = CliRunner().invoke(main, ["run", str(path)])
    assert result.exit_code == 2
    assert result.output.strip().splitlines()[-1] == \
        f"Error: result file '{tmp_path / 'out' / 'r.txt'}': unknown format '.txt'; use .csv, .parquet, .mat"
    assert not (tmp_path / "out").exists()


def test_scenario_result_file_picks_the_format(scenario, tmp_path):
    path = tmp_path / "osc.yaml"
    path.write_text(scenario.read_text() + "result: {file: r.parquet}\n")
    result = CliRunner().invoke(main, ["run", str(path), "-q"])
    assert result.exit_code == 0, result.output
    assert pq.read_table(tmp_path / "r.parquet").column("time").to_numpy()[-1] == 1.0


@pytest.mark.parametrize("suffix", ["parquet", "mat"])
def test_failed_run_leaves_a_readable_file_up_to_the_failure(scenario, tmp_path, suffix):
    """The oscillator's CVODE fails at t = 0.5 (a force of 1e308): the rows before are in the file."""
    failing = tmp_path / "fail.yaml"
    failing.write_text(scenario.read_text().replace(
        "interface: ME}", "interface: ME, parameters: {F_step: 1.0e+308, t_step: 0.5}}"))
    out, kept = tmp_path / f"f.{suffix}", tmp_path / f"f.failed.{suffix}"
    result = CliRunner().invoke(main, ["run", str(failing), "-o", str(out)])
    assert result.exit_code == 1
    assert result.output.strip().splitlines()[-1].endswith(f"(results up to the failure in {kept})")
    assert not out.exists()  # kept under a name that says it failed
    out = kept
    time_column = (pq.read_table(out).column("time").to_numpy() if suffix == "parquet"
                   else scipy.io.loadmat(out)["time"].ravel())
    assert time_column[0] == 0.0 and 0.49 <= time_column[-1] <= 0.5
    assert np.all(np.diff(time_column) >= 0)


def test_interrupted_run_leaves_a_readable_parquet(oscillator, tmp_path):
    """A real ``deltafmi run`` stopped by Ctrl-C once a row group is on disk: the file gets its
    footer, and holds every step up to the interruption."""
    path = tmp_path / "long.yaml"
    path.write_text(f"experiment: {{stop: 1.0e+6, step: 1.0e-3}}\n"
                    f"components:\n  osc: {{fmu: {oscillator}, interface: CS}}\n"
                    "outputs: [osc.x, osc.v]\n")
    out = tmp_path / "long.parquet"
    code, _, stderr = interrupt_when([*DELTAFMI, "run", str(path), "-o", str(out)],
                                     lambda: bytes_in(out) > 4,  # more than Parquet's magic
                                     signal.SIGINT)
    assert code == 130, stderr
    assert "Traceback" not in stderr
    match = re.fullmatch(r"interrupted at t = (\S+) s \(results up to (\S+) in (.+)\)", stderr.strip().splitlines()[-1])
    assert match and match[3] == str(out)
    table = pq.read_table(out)
    t = table.column("time").to_numpy()
    assert t[-1] > 0 and float(match[2]) == pytest.approx(t[-1], rel=1e-9)
    assert np.array_equal(t, np.arange(len(t)) * 1e-3)  # every step up to there
    assert pq.read_schema(out).field("osc.x").metadata == {b"unit": b"m"}


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(), reason="signal handlers: main thread")
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_while_the_results_are_written_keeps_the_whole_run(scenario, results, tmp_path, monkeypatch,
                                                                   signum):
    """A .mat is written whole when the run ends: a signal that arrives then (a real signal, sent
    as the writing starts) broke the writing, and the run's rows were lost ("interrupted", no
    file). The writing goes on, the file holds the whole run (as the same run's without a signal),
    and the run ends as interrupted with 128 + the signal."""
    from deltafmi.master.results.writers import MatWriter

    write = MatWriter.close

    def close(self):
        os.kill(os.getpid(), signum)  # handled at the next line of Python: inside the writing
        write(self)

    monkeypatch.setattr(MatWriter, "close", close)
    out = tmp_path / "r.mat"
    result = CliRunner().invoke(main, ["run", str(scenario), "-o", str(out), "-q"])
    assert result.exit_code == 128 + signum, result.output
    assert result.output.strip().splitlines()[-1] == f"interrupted at t = 1 s (results up to 1 in {out})"
    whole, written = scipy.io.loadmat(results["mat"]), scipy.io.loadmat(out)
    assert whole["time"].ravel()[-1] == 1.0
    for name in ("time", *matlab_names(OUTPUTS)):
        assert np.array_equal(written[name], whole[name]), name


@pytest.mark.parametrize("suffix", ["csv", "parquet", "mat"])
def test_a_run_writes_through_a_symbolic_link(scenario, results, tmp_path, suffix):
    """``-o link`` where link points to an earlier result: the file it points to gets the run's
    rows (the same as a plain run's), the link stays a link, and the CSV's units are found
    through the link."""
    (tmp_path / "kept").mkdir()
    target = tmp_path / "kept" / f"r.{suffix}"
    target.write_text("an earlier result")
    link = tmp_path / f"link.{suffix}"
    link.symlink_to(target)
    result = CliRunner().invoke(main, ["run", str(scenario), "-o", str(link), "-q"])
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and link.resolve() == target.resolve()
    if suffix == "csv":
        assert target.read_bytes() == results["csv"].read_bytes()
        assert read_units(link) == read_units(results["csv"]) and read_units(link)
    elif suffix == "parquet":
        assert pq.read_table(target).to_pydict() == pq.read_table(results["parquet"]).to_pydict()
    else:
        mine, plain = scipy.io.loadmat(target), scipy.io.loadmat(results["mat"])
        names = [name for name in plain if not name.startswith("__")]
        assert names and all(np.array_equal(mine[name], plain[name]) for name in names)
