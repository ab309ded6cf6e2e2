"""No traceback anywhere: every command, driven as a stranger would with outputs it cannot write,
binary files for inputs and broken FMUs, ends with one line and a documented exit code (2 for bad
input, 1 for a failure), and ``run``, ``info`` and ``validate`` give the same code for one input."""
from __future__ import annotations

import os
import re
import zipfile
from pathlib import Path

import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main

UNWRITABLE = "/sys/deltafmi-test"  # a folder no one, root included, can create files in


def _rewrite(source: Path, target: Path, edit=None, extra: str = "", drop: str = "") -> Path:
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as new:
        for item in old.infolist():
            if drop and item.filename.startswith(drop):
                continue
            data = old.read(item.filename)
            if item.filename == "modelDescription.xml" and edit is not None:
                data = edit(data.decode()).encode()
            new.writestr(item.filename, data)
        if extra:
            new.writestr(zipfile.ZipInfo(extra), b"outside")
    return target


@pytest.fixture(scope="module")
def inputs(build_fmu_from_src, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("stranger")
    osc = build_fmu_from_src("oscillator.py")
    _rewrite(osc, folder / "absolute.fmu", extra="/tmp/deltafmi-outside.txt")
    _rewrite(osc, folder / "dotdot.fmu", extra="../outside.txt")
    _rewrite(osc, folder / "fmi1.fmu", edit=lambda t: t.replace('fmiVersion="2.0"', 'fmiVersion="1.0"'))
    _rewrite(osc, folder / "badvr.fmu", edit=lambda t: re.sub(r'valueReference="\d+"', 'valueReference="abc"', t,
                                                               count=1))
    _rewrite(osc, folder / "nomd.fmu", drop="modelDescription.xml")
    _rewrite(osc, folder / "badxml.fmu", edit=lambda t: t[: len(t) // 2])
    with zipfile.ZipFile(osc) as old, zipfile.ZipFile(folder / "bomb.fmu", "w", zipfile.ZIP_DEFLATED) as new:
        for item in old.infolist():
            data = old.read(item.filename)
            if item.filename == "modelDescription.xml":  # 48 MB of blanks inside the root element
                root = data.index(b"<ModelExchange")
                data = data[:root] + b" " * (48 << 20) + data[root:]
            new.writestr(item.filename, data)
    (folder / "garbage.fmu").write_bytes(os.urandom(4000))
    data = osc.read_bytes()
    (folder / "truncated.fmu").write_bytes(data[: len(data) // 2])
    binary = bytes(range(256)) * 16
    for name in ("binary.yaml", "binary.csv", "binary.parquet", "binary.mat", "binary.py"):
        (folder / name).write_bytes(binary)
    (folder / "afile").write_text("a file, not a folder\n")
    os.mkfifo(folder / "pipe.csv")
    (folder / "syntax.py").write_text("class X(:\n")
    (folder / "adir.fmu").mkdir()
    (folder / "empty.csv").write_text("")
    (folder / "one.yaml").write_text(f"experiment: {{stop: 0.01, step: 1.0e-3}}\ncomponents:\n  osc: {{fmu: {osc}}}\n")
    good = CliRunner().invoke(main, ["run", "delta_tracking", "--stop", "0.05", "-q", "-o", str(folder / "r.csv")])
    assert good.exit_code == 0, good.output
    return folder


BROKEN = {
    "absolute": "unsafe: its archive entry '/tmp/deltafmi-outside.txt' would be unpacked outside the FMU's folder",
    "dotdot": "unsafe: its archive entry '../outside.txt' would be unpacked outside the FMU's folder",
    "fmi1": "an FMI 1.0 FMU: deltafmi runs FMI 2.0 and FMI 3.0 FMUs",
    "badvr": "modelDescription.xml: variable 'x' has valueReference 'abc', not an unsigned integer",
    "nomd": "its archive has no modelDescription.xml",
    "badxml": "modelDescription.xml is not well-formed XML",
    "bomb": "its modelDescription.xml would unpack to 48 MB from",  # KB and ratio: as zlib packs them
    "garbage": "not a zip archive",
    "truncated": "not a zip archive",
}


def _one_line(done, code: int) -> str:
    assert "Traceback" not in done.output, done.output
    assert done.exit_code == code, done.output
    assert isinstance(done.exception, SystemExit) or done.exception is None, repr(done.exception)
    return done.output.strip().splitlines()[-1]


@pytest.mark.parametrize("broken", sorted(BROKEN))
def test_a_broken_fmu_is_the_same_one_line_and_exit_2_for_run_info_and_validate(inputs, broken):
    fmu = inputs / f"{broken}.fmu"
    for command in ("run", "info", "validate"):
        last = _one_line(CliRunner().invoke(main, [command, str(fmu)]), 2)
        assert f"{fmu}" in last and "cannot read it as an FMU: " + BROKEN[broken] in last, (command, last)
    assert not Path("/tmp/deltafmi-outside.txt").exists()


def test_a_broken_fmu_in_a_scenario_names_the_component(inputs, tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(f"experiment: {{stop: 1.0, step: 0.1}}\ncomponents:\n  a: {{fmu: {inputs / 'fmi1.fmu'}}}\n")
    last = _one_line(CliRunner().invoke(main, ["run", str(scenario)]), 2)
    assert last == (f"{scenario}:3: error: component 'a': cannot read FMU '{inputs / 'fmi1.fmu'}': an FMI 1.0 FMU: "
                    "deltafmi runs FMI 2.0 and FMI 3.0 FMUs (export it as FMI 2.0 or 3.0)")


@pytest.mark.parametrize("args, code, text", [
    (["run", "delta_tracking", "-o", ""], 2, "-o '': an empty file name"),
    (["run", "delta_tracking", "--stop", "0.01", "-o", f"{UNWRITABLE}/r.mat"], 2, "cannot write in /sys"),
    (["run", "delta_tracking", "--stop", "0.01", "-o", "{dir}/afile/r.csv"], 2, "afile is a file, not a folder"),
    (["sweep", "gain_payload", "-o", f"{UNWRITABLE}/t.parquet"], 2, "results table '/sys/deltafmi-test/t.parquet': "
                                                                   "cannot write in /sys"),
    (["plot", "{dir}/r.csv", "plant.z[3]", "-o", f"{UNWRITABLE}/p.png"], 2, "/sys/deltafmi-test"),
    (["build", "Oscillator", "-o", f"{UNWRITABLE}/o.fmu"], 2, "FMU file '/sys/deltafmi-test/o.fmu': cannot write"),
    (["build", "--all", "-o", "{dir}/afile"], 2, "writes one FMU each into a folder, and"),
    (["export-ssp", "delta_tracking", "-o", f"{UNWRITABLE}/d.ssp"], 2, "SSP archive '/sys/deltafmi-test/d.ssp'"),
    (["linearize", "Oscillator", "-q", "-o", f"{UNWRITABLE}/lin"], 2, "/sys/deltafmi-test"),
    (["examples", "copy", "delta_tracking", f"{UNWRITABLE}/ex"], 2, "/sys/deltafmi-test"),
    (["study-case", "gain_payload", "0", "-o", f"{UNWRITABLE}/c.yaml"], 2, "/sys/deltafmi-test"),
    (["compat", "export", f"{UNWRITABLE}/c"], 2, "/sys/deltafmi-test"),
    (["run", "{dir}/binary.yaml"], 2, "not a scenario: not text (byte 128 is not UTF-8)"),
    (["validate", "{dir}/binary.yaml"], 2, "not a scenario: not text"),
    (["export-ssp", "{dir}/binary.yaml"], 2, "not a scenario: not text"),
    (["linearize", "{dir}/binary.yaml"], 2, "not a scenario: not text"),
    (["sweep", "{dir}/binary.yaml"], 2, "not a study: not text"),
    (["study-case", "{dir}/binary.yaml", "0", "-o", "{dir}/c.yaml"], 2, "not a study: not text"),
    (["plot", "{dir}/binary.csv", "x", "-o", "{dir}/p.png"], 2, "cannot read '{dir}/binary.csv' as a result file: "
                                                             "not text (byte 128 is not UTF-8)"),
    (["plot", "{dir}/binary.parquet", "x", "-o", "{dir}/p.png"], 2, "as a result file"),
    (["plot", "{dir}/binary.mat", "x", "-o", "{dir}/p.png"], 2, "as a result file"),
    (["animate", "{dir}/binary.csv", "-o", "{dir}/a.gif"], 2, "as a result file"),
    (["plot-study", "{dir}/binary.parquet", "-o", "{dir}/p.png"], 2, "as a study's results"),
    (["build", "{dir}/binary.yaml"], 2, "a component's source is a Python file (.py)"),
    (["build", "{dir}/binary.py"], 2, "importing it failed"),
    (["info", "{dir}/binary.py"], 2, "importing it failed"),
    (["linearize", "{dir}/binary.py"], 2, "importing it failed"),
    (["run", "{dir}/r.csv"], 2, "a scenario must be a YAML mapping"),
    (["run", "delta_tracking", "--stop", "0.01", "-o", "{dir}/pipe.csv"], 2,
     "result file '{dir}/pipe.csv': not a regular file (a device, a pipe or a socket)"),
    (["run", "{dir}/syntax.py"], 2, "not a scenario: a Python file (a component's source"),
    (["build", "{dir}/syntax.py"], 2, "importing it failed: {dir}/syntax.py:1: invalid syntax"),
    (["info", "{dir}"], 2, "a folder, not an FMU file"),
    (["run", "{dir}/adir.fmu"], 2, "a folder, not an FMU file"),
    (["plot", "{dir}/empty.csv", "x", "-o", "{dir}/p.png"], 2, "as a result file: it is empty (0 bytes)"),
    (["run", "{dir}/one.yaml", "--stop", "1e308"], 2, "1e+308 s in steps of 0.001 s: more communication steps "
                                                      "than a run can count"),
    (["run", "{dir}/one.yaml", "--set", "osc=1"], 2, "'osc' is the component: set one of its variables, osc.NAME"),
])
def test_every_command_ends_with_one_line_never_a_traceback(inputs, args, code, text):
    args = [a.replace("{dir}", str(inputs)) for a in args]
    last = _one_line(CliRunner().invoke(main, args), code)
    assert text.replace("{dir}", str(inputs)) in last, last


def test_an_unexpected_error_is_one_line_that_says_it_is_a_bug(capsys):
    from deltafmi.apps.cli import report_unexpected
    assert report_unexpected(AttributeError("'NoneType' object has no attribute 'x'")) == 1
    assert capsys.readouterr().err == ("Error: internal error, AttributeError: 'NoneType' object has no attribute "
                                       "'x' (this is a bug in deltafmi; DELTAFMI_TRACEBACK=1 shows where)\n")


@pytest.mark.parametrize("command", ["run", "validate", "sweep"])
def test_a_file_of_utf8_control_characters_is_one_line_naming_its_line(tmp_path, command):
    """Bytes that decode as UTF-8 but that YAML never holds (NUL, most controls): one line naming
    the file and the line, exit 2 (was an internal error from the YAML reader)."""
    path = tmp_path / "nul.yaml"
    path.write_bytes(b"description: x\n\x00\x01binary")
    last = _one_line(CliRunner().invoke(main, [command, str(path)]), 2)
    assert f"{path}:2" in last and "not text: character #x0000 is not allowed in YAML" in last, last


def test_a_result_that_cannot_be_put_in_place_says_where_its_rows_are(inputs, tmp_path):
    """An immutable result file (chattr +i): the run's rows stay in the temporary file beside it,
    which the one line names; the earlier file is as it was."""
    import subprocess

    from deltafmi.master.results.csv_file import columns

    target = tmp_path / "locked.csv"
    target.write_text("earlier\n")
    if subprocess.run(["chattr", "+i", str(target)], capture_output=True).returncode != 0:
        pytest.skip("chattr +i needs root and a file system that has it")
    try:
        done = CliRunner().invoke(main, ["run", str(inputs / "one.yaml"), "-q", "-o", str(target)])
    finally:
        subprocess.run(["chattr", "-i", str(target)], check=True)
    last = _one_line(done, 2)
    kept = re.search(r"cannot put the finished file in its place \(.+\); its rows are in (\S+\.tmp)$", last)
    assert kept, last
    assert target.read_text() == "earlier\n"
    assert len(columns(kept[1])["time"]) == 11  # 0 to 0.01 s in steps of 1 ms
