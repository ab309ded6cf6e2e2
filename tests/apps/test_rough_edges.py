"""The rough edges a new user meets with FMUs, result files and scenarios (issue 30, item 4): each
is one clear line naming the thing, a non-zero exit and no traceback.

* An FMU whose modelDescription.xml GUID is not its binary's: ``run`` quotes the FMU's own logged
  reason (ours, and a plain-C third-party one); ``validate`` refuses it; an FMU without its
  ``binaries/linux64`` library: ``validate`` and ``run`` say so.
* A full disk (a real, small tmpfs in a private mount namespace): CSV and Parquet keep only whole
  rows and stay readable, the .mat file is removed; one line says how many rows and up to when.
* Scenario errors print once each (``file:line: error: message``), for every command.
* Unconnected inputs: one warning per scenario; an input given a value is deliberately set; the
  shipped scenarios warn about nothing.
* An explicit ``factor``/``offset`` allows a connection between different units, even ``1.0``.
* ``run -q`` prints nothing on success.
"""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import read_csv

DELTAFMI = Path(sys.executable).parent / "deltafmi"
HERE = Path(__file__).resolve().parents[1]
EXAMPLES = sorted(p.stem for p in (HERE.parent / "scenarios").glob("*.yaml"))


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(DELTAFMI), *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=600)


def rewrite_fmu(source: Path, target: Path, edit=None, drop: str = "") -> Path:
    """A copy of ``source`` with modelDescription.xml passed through ``edit`` and the entries
    starting with ``drop`` left out."""
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as new:
        for item in old.infolist():
            if drop and item.filename.startswith(drop):
                continue
            data = old.read(item)
            if item.filename == "modelDescription.xml" and edit is not None:
                data = edit(data.decode()).encode()
            new.writestr(item, data)
    return target


def other_guid(text: str) -> str:
    return re.sub(r'guid="\{[0-9a-f]{8}', 'guid="{00000000', text, count=1)


@pytest.fixture(scope="module")
def osc(build_fmu_from_src) -> Path:
    return build_fmu_from_src("oscillator.py")


# --- FMUs whose GUID or binary is wrong --------------------------------------------------------

STUB_C = r"""
/* A third-party style FMU (plain C, not deltafmi) whose fmi2Instantiate checks the GUID the way
 * the FMI Reference FMUs do: a mismatch is logged through the importer's logger, then NULL. */
#include <stdio.h>
#include <string.h>
#define EXPORT __attribute__((visibility("default")))
typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct { Logger logger; void *allocate, *free, *stepFinished, *environment; } Callbacks;
#define GUID "{5a2b0d6e-1c1f-4e0e-9a55-0c2d7e3f4a10}"
EXPORT void *fmi2Instantiate(const char *name, int type, const char *guid, const char *resources,
                             const Callbacks *callbacks, int visible, int loggingOn) {
    char message[256];
    (void)type; (void)resources; (void)visible; (void)loggingOn;
    snprintf(message, sizeof message, "Wrong GUID %s. Expected %s.", guid ? guid : "(null)", GUID);
    if (callbacks && callbacks->logger) callbacks->logger(callbacks->environment, name, 3, "logStatusError", message);
    return NULL;
}
EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }
EXPORT void fmi2FreeInstance(void *c) { (void)c; }
#define STUB(name) EXPORT int name(void) { return 3; }
STUB(fmi2SetDebugLogging) STUB(fmi2SetupExperiment) STUB(fmi2EnterInitializationMode)
STUB(fmi2ExitInitializationMode) STUB(fmi2Terminate) STUB(fmi2Reset) STUB(fmi2GetReal) STUB(fmi2GetInteger)
STUB(fmi2GetBoolean) STUB(fmi2GetString) STUB(fmi2SetReal) STUB(fmi2SetInteger) STUB(fmi2SetBoolean)
STUB(fmi2SetString) STUB(fmi2GetFMUstate) STUB(fmi2SetFMUstate) STUB(fmi2FreeFMUstate)
STUB(fmi2SerializedFMUstateSize) STUB(fmi2SerializeFMUstate) STUB(fmi2DeSerializeFMUstate)
STUB(fmi2GetDirectionalDerivative) STUB(fmi2SetRealInputDerivatives) STUB(fmi2GetRealOutputDerivatives)
STUB(fmi2DoStep) STUB(fmi2CancelStep) STUB(fmi2GetStatus) STUB(fmi2GetRealStatus) STUB(fmi2GetIntegerStatus)
STUB(fmi2GetBooleanStatus) STUB(fmi2GetStringStatus)
"""

STUB_XML = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Stubborn" guid="{GUID}" generationTool="a C toolchain"
                     variableNamingConvention="structured" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="Stubborn" canHandleVariableCommunicationStepSize="true"/>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.1"/>
  <ModelVariables>
    <ScalarVariable name="y" valueReference="0" causality="output" variability="continuous" initial="exact">
      <Real start="0"/>
    </ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="1"/></Outputs>
  </ModelStructure>
</fmiModelDescription>
"""


@pytest.fixture(scope="module")
def stubborn(tmp_path_factory) -> Path:
    """The third-party FMU, its modelDescription.xml GUID not the one its binary expects."""
    folder = tmp_path_factory.mktemp("stubborn")
    (folder / "stub.c").write_text(STUB_C)
    subprocess.run(["cc", "-shared", "-fPIC", "-fvisibility=hidden", str(folder / "stub.c"), "-o",
                    str(folder / "Stubborn.so")], check=True)
    fmu = folder / "Stubborn.fmu"
    with zipfile.ZipFile(fmu, "w") as archive:
        archive.writestr("modelDescription.xml", STUB_XML.replace("{GUID}", "{11111111-2222-4333-8444-555555555555}"))
        archive.write(folder / "Stubborn.so", "binaries/linux64/Stubborn.so")
    return fmu


def one_component(folder: Path, fmu: Path, extra: str = "") -> Path:
    if fmu.parent != folder:
        shutil.copy(fmu, folder / fmu.name)
    scenario = folder / "s.yaml"
    scenario.write_text(f"experiment: {{stop: 0.1, step: 0.01}}\ncomponents:\n  a: {{fmu: {fmu.name}{extra}}}\n")
    return scenario


def test_run_quotes_the_reason_our_fmu_logs_when_its_guid_does_not_match(osc, tmp_path):
    bad = rewrite_fmu(osc, tmp_path / "bad.fmu", other_guid)
    done = cli("run", one_component(tmp_path, bad, ", parameters: {F: 0.0}"), cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr + done.stdout
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("Error: simulation failed at t = 0 s: a (bad.fmu): fmi2Instantiate failed: ")
    assert re.search(r"GUID \{00000000-[-0-9a-f]+\} does not match this FMU's \{[-0-9a-f]+\}", last), last
    assert "the modelDescription.xml and the binary disagree" in last


def test_run_quotes_what_a_third_party_fmu_logs_when_it_refuses_to_instantiate(stubborn, tmp_path):
    done = cli("run", one_component(tmp_path, stubborn), cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines()[-1] == (
        "Error: simulation failed at t = 0 s: a (Stubborn.fmu): fmi2Instantiate failed: Wrong GUID "
        "{11111111-2222-4333-8444-555555555555}. Expected {5a2b0d6e-1c1f-4e0e-9a55-0c2d7e3f4a10}.")


def test_validate_refuses_an_fmu_whose_guid_is_not_its_binarys(osc, stubborn, tmp_path):
    bad = rewrite_fmu(osc, tmp_path / "bad.fmu", other_guid)
    result = CliRunner().invoke(main, ["validate", str(bad)])
    assert result.exit_code == 1, result.output
    assert result.output.strip().splitlines()[-1].startswith(
        f"Error: {bad}: the GUID of modelDescription.xml, {{00000000-")
    assert "is not the one its binary was built with" in result.output
    # fmpy's validation alone passes it: only the XML is read
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(bad)) == []
    # a third-party FMU: found by instantiating it once, with what it logged
    result = CliRunner().invoke(main, ["validate", str(stubborn)])
    assert result.exit_code == 1, result.output
    assert "not built by deltafmi" in result.output
    assert result.output.strip().splitlines()[-1] == (
        f"Error: {stubborn}: fmi2Instantiate failed: Wrong GUID {{11111111-2222-4333-8444-555555555555}}. "
        "Expected {5a2b0d6e-1c1f-4e0e-9a55-0c2d7e3f4a10}.")
    # and a scenario naming our FMU
    scenario = one_component(tmp_path, bad, ", parameters: {F: 0.0}")
    result = CliRunner().invoke(main, ["validate", str(scenario)])
    assert result.exit_code == 2
    assert result.output.startswith(f"{scenario}:3: error: component 'a': FMU 'bad.fmu': the GUID of ")
    # linearize instantiates it too
    result = CliRunner().invoke(main, ["linearize", str(bad)])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert result.output.startswith(f"Error: '{bad}': fmi2Instantiate failed: RuntimeError: fmi2Instantiate: GUID ")
    # the FMU as built passes, instantiated once
    result = CliRunner().invoke(main, ["validate", str(osc)])
    assert result.exit_code == 0, result.output
    assert result.output.strip().splitlines()[-1] == f"{osc}: OK (instantiated and freed once)"


def test_an_fmu_without_its_linux64_binary_is_named_by_validate_and_run(osc, tmp_path):
    bare = rewrite_fmu(osc, tmp_path / "bare.fmu", drop="binaries/")
    result = CliRunner().invoke(main, ["validate", str(bare)])
    assert result.exit_code == 1
    assert result.output.strip().splitlines()[-1] == (
        f"Error: {bare}: no binary for this platform: binaries/linux64/Oscillator.so is missing (its binaries: none)")
    scenario = one_component(tmp_path, bare, ", parameters: {F: 0.0}")
    for command in ("run", "validate"):
        done = cli(command, scenario, cwd=tmp_path)
        assert done.returncode == 2, done.stderr
        assert done.stdout == ""
        assert done.stderr == (f"{scenario}:3: error: component 'a': FMU 'bare.fmu' cannot run here: no binary "
                               "for this platform: binaries/linux64/Oscillator.so is missing (its binaries: none)\n")
    # a binary under another name than the modelIdentifier: the same
    renamed = tmp_path / "renamed.fmu"
    with zipfile.ZipFile(osc) as old, zipfile.ZipFile(renamed, "w") as new:
        for item in old.infolist():
            new.writestr(item.filename.replace("linux64/Oscillator.so", "linux64/Other.so"), old.read(item))
    result = CliRunner().invoke(main, ["validate", str(renamed)])
    assert result.exit_code == 1
    assert ("binaries/linux64/Oscillator.so is missing (its binaries: binaries/linux64/Other.so, "
            "binaries/linux64/Oscillator_kernels.so)") in result.output  # the kernels: no FMI binary


# --- a full disk --------------------------------------------------------------------------------

LONG_RUN = """\
experiment: {stop: 20.0, step: 1.0e-4}
components:
  osc: {fmu: osc.fmu, parameters: {F: 0.0}}
outputs: [osc.x, osc.v, osc.energy, osc.impacts]
"""
FULL = re.compile(r"Error: (\S+): disk full after (\d+) rows \(t = (\S+) s\); the rows written are complete")


def in_small_tmpfs(tmp_path: Path, size: str, *args: str) -> tuple[subprocess.CompletedProcess, Path]:
    """``deltafmi ARGS`` in a private mount namespace where ``tmp_path/disk`` is a tmpfs of ``size``
    (``{disk}`` in ARGS names it); what it held at the end is copied to the returned folder."""
    disk, kept = tmp_path / "disk", tmp_path / "kept"
    disk.mkdir()
    kept.mkdir()
    script = (f'mount -t tmpfs -o size={size} tmpfs "{disk}" || exit 99\n"$@"\ncode=$?\n'
              f'cp -a "{disk}/." "{kept}/"\nexit $code\n')
    args = [a.replace("{disk}", str(disk)) for a in args]
    done = subprocess.run(["unshare", "-m", "sh", "-c", script, "sh", str(DELTAFMI), *args], cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)
    if done.returncode == 99 or "unshare failed" in done.stderr:
        pytest.skip(f"no private tmpfs here: {done.stderr.strip()}")
    return done, kept


@pytest.fixture(scope="module")
def long_run(osc, tmp_path_factory) -> tuple[Path, dict]:
    """The scenario, and its complete results (Parquet) on a disk with room."""
    folder = tmp_path_factory.mktemp("long_run")
    shutil.copy(osc, folder / "osc.fmu")
    (folder / "long.yaml").write_text(LONG_RUN)
    done = cli("run", folder / "long.yaml", "-q", "-o", folder / "all.parquet", cwd=folder)
    assert done.returncode == 0, done.stderr
    return folder / "long.yaml", pq.read_table(folder / "all.parquet").to_pydict()


def test_csv_on_a_full_disk_keeps_whole_rows_and_says_how_many(long_run, tmp_path):
    scenario, complete = long_run
    if shutil.which("unshare") is None:
        pytest.skip("no unshare")
    done, kept = in_small_tmpfs(tmp_path, "256k", "run", str(scenario), "-o", "{disk}/r.csv")
    assert done.returncode == 1, done.stderr
    assert done.stdout.count("\n") <= 1 and "Traceback" not in done.stderr
    assert len(done.stderr.splitlines()) == 1, done.stderr
    match = FULL.fullmatch(done.stderr.strip())
    assert match, done.stderr
    rows, until = int(match[2]), float(match[3])
    assert match[1] == f"{tmp_path}/disk/r.failed.csv"  # the rows of a failed run, under a name that says so
    text = (kept / "r.failed.csv").read_bytes()
    assert len(text) <= 256 * 1024 and text.endswith(b"\n")
    assert len(text) > 200 * 1024  # the disk was used, not given up early
    names, data = read_csv(kept / "r.failed.csv")
    assert names == ["time", "osc.x", "osc.v", "osc.energy", "osc.impacts"]
    assert data.shape == (rows, 5) and 1000 < rows < len(complete["time"])
    assert abs(data[-1, 0] - until) <= 5e-9 * until  # the message gives 9 significant digits
    # the rows kept are the run's rows, bit for bit
    for i, name in enumerate(names):
        assert np.array_equal(data[:, i], np.asarray(complete[name][:rows], dtype=float)), name


def test_parquet_on_a_full_disk_ends_with_a_readable_file(long_run, tmp_path):
    scenario, complete = long_run
    if shutil.which("unshare") is None:
        pytest.skip("no unshare")
    done, kept = in_small_tmpfs(tmp_path, "2m", "run", str(scenario), "-o", "{disk}/r.parquet")
    assert done.returncode == 1, done.stderr
    assert len(done.stderr.splitlines()) == 1, done.stderr
    match = FULL.fullmatch(done.stderr.strip())
    assert match, done.stderr
    rows = int(match[2])
    assert sorted(p.name for p in kept.iterdir()) == ["r.failed.parquet"]  # the space reserve went too
    table = pq.read_table(kept / "r.failed.parquet")
    assert table.num_rows == rows and 8192 <= rows < len(complete["time"])
    got = table.to_pydict()
    # the message gives the last row's time to 9 significant digits (which rows fit depends on when
    # the writer flushed: a row group every 8192 rows or half a second)
    assert f"{got['time'][-1]:.9g}" == match[3]
    for name in complete:
        assert got[name] == complete[name][:rows], name
    assert table.schema.field("osc.energy").metadata == {b"unit": b"J"}


def test_mat_on_a_full_disk_is_removed_and_says_so(long_run, tmp_path):
    scenario, complete = long_run
    if shutil.which("unshare") is None:
        pytest.skip("no unshare")
    done, kept = in_small_tmpfs(tmp_path, "256k", "run", str(scenario), "-o", "{disk}/r.mat")
    assert done.returncode == 1, done.stderr
    n = len(complete["time"])
    assert done.stderr == (f"Error: {tmp_path}/disk/r.mat: disk full: its {n} rows (t = 20 s) did not fit and the "
                           "file was removed\n")
    assert list(kept.iterdir()) == []


@pytest.mark.parametrize("command", [["build", "Oscillator", "-o", "{disk}/o.fmu"],
                                     ["export-ssp", "bouncing_ball", "-o", "{disk}/o.ssp"]])
def test_an_archive_that_does_not_fit_names_its_file_and_leaves_nothing(command, tmp_path):
    if shutil.which("unshare") is None:
        pytest.skip("no unshare")
    done, kept = in_small_tmpfs(tmp_path, "100k", *command)
    assert done.returncode == 1, done.stderr
    assert done.stderr.splitlines()[-1] == f"Error: {tmp_path}/disk/o{Path(command[-1]).suffix}: No space left on device"
    assert list(kept.iterdir()) == []


@pytest.mark.parametrize("args", [["examples"], ["info", "Oscillator"]])
def test_a_reader_that_has_gone_ends_the_command_quietly_as_sigpipe(args, tmp_path):
    """`deltafmi examples | head -1`: no "Error: Broken pipe", exit 141 (128 + SIGPIPE) as a
    shell's tools give; the reader here closes the pipe before the first line."""
    reader, writer = os.pipe()
    os.close(reader)
    try:
        done = subprocess.run([str(DELTAFMI), *args], cwd=tmp_path, stdout=writer, stderr=subprocess.PIPE, text=True,
                              timeout=600)
    finally:
        os.close(writer)
    assert done.returncode == 128 + signal.SIGPIPE, done.stderr
    assert done.stderr == "", done.stderr


# --- what the CLI prints ------------------------------------------------------------------------

def test_scenario_errors_print_once_for_every_command(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("experiment: {stop: 1.0, step: 0.1}\ncomponents:\n  a: {fmu: missing.fmu}\n"
                   "  b: {fmu: gone.fmu}\n")
    study = tmp_path / "study.yaml"
    study.write_text("scenario: bad.yaml\nvary:\n  grid:\n    a.k: [1.0, 2.0]\nmetrics:\n  e: {signal: a.energy, statistic: max}\n")
    expected = [f"{bad}:3: error: component 'a': FMU 'missing.fmu' not found",
                f"{bad}:4: error: component 'b': FMU 'gone.fmu' not found"]
    for args in (["run", bad], ["validate", bad], ["export-ssp", bad], ["linearize", bad], ["sweep", study],
                 ["sweep", study, "--dry-run"]):
        result = CliRunner().invoke(main, [str(a) for a in args])
        assert result.exit_code == 2, (args, result.output)
        lines = result.output.strip().splitlines()
        assert lines == expected, (args, result.output)
    one = tmp_path / "one.yaml"
    one.write_text("experiment: {stop: 1.0, step: 0.1}\ncomponents:\n  a: {fmu: missing.fmu}\n")
    result = CliRunner().invoke(main, ["run", str(one)])
    assert result.output == f"{one}:3: error: component 'a': FMU 'missing.fmu' not found\n"
    # other bad input keeps its one "Error: " line
    result = CliRunner().invoke(main, ["build", str(tmp_path / "nothing.py")])
    assert result.exit_code == 2
    assert len(result.output.strip().splitlines()) == 1 and result.output.lower().count("error:") == 1, result.output


TWO_OSCILLATORS = """\
experiment: {stop: 0.5, step: 0.01}
components:
  a: {fmu: osc.fmu}
  b: {fmu: osc.fmu}
  c: {fmu: osc.fmu, parameters: {F: 1.5}}
connections:
"""


def test_unconnected_inputs_warn_once_per_scenario_and_a_given_value_is_deliberate(osc, tmp_path):
    shutil.copy(osc, tmp_path / "osc.fmu")
    scenario = tmp_path / "s.yaml"
    scenario.write_text(TWO_OSCILLATORS + "  - {from: a.energy, to: b.F, factor: 0.1}\n")
    done = cli("run", scenario, "-o", tmp_path / "r.csv", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stderr == (f"{scenario}: warning: input(s) not connected, kept at their start values: a.F "
                           "(connect them, or give them a value under the component's parameters:)\n")
    scenario.write_text(TWO_OSCILLATORS.replace("a: {fmu: osc.fmu}", "a: {fmu: osc.fmu, parameters: {F: 0.0}}")
                        + "  - {from: a.energy, to: b.F, factor: 0.1}\n")
    done = cli("run", scenario, "-o", tmp_path / "r.csv", cwd=tmp_path)
    assert done.returncode == 0 and done.stderr == "", done.stderr


def test_every_shipped_scenario_validates_without_a_warning():
    assert len(EXAMPLES) >= 14
    said = {}
    for name in EXAMPLES:
        result = CliRunner().invoke(main, ["validate", name])
        assert result.exit_code == 0, result.output
        assert result.output.strip().splitlines()[-1].endswith(": OK")
        said[name] = [line for line in result.output.splitlines() if "warning" in line.lower()]
    assert said == {name: [] for name in EXAMPLES}


def test_an_explicit_factor_or_offset_allows_other_units_even_the_identity(osc, tmp_path):
    shutil.copy(osc, tmp_path / "osc.fmu")
    scenario = tmp_path / "s.yaml"
    for conversion, ok in (("", False), (", factor: 1.0", True), (", offset: 0.0", True), (", factor: 2.0", True)):
        scenario.write_text(TWO_OSCILLATORS + f"  - {{from: a.energy, to: b.F{conversion}}}\n")
        result = CliRunner().invoke(main, ["validate", str(scenario)])
        assert result.exit_code == (0 if ok else 2), (conversion, result.output)
        if not ok:
            assert result.output == (f"{scenario}:7: error: unit mismatch: 'a.energy' is in 'J' but 'b.F' expects "
                                     "'N' (convert with factor/offset)\n")


CHATTY = """\
experiment: {stop: 1.0, step: 0.05}
components:
  talker: {fmu: Chatty.fmu, interface: ME}
  osc: {fmu: osc.fmu}
"""


def test_quiet_run_prints_nothing_on_success(osc, tmp_path):
    from deltafmi.builder import build_fmu

    build_fmu(HERE / "components" / "chatty" / "model.py", tmp_path / "Chatty.fmu")
    shutil.copy(osc, tmp_path / "osc.fmu")
    (tmp_path / "s.yaml").write_text(CHATTY)  # osc.F unconnected; the talker logs at every level
    loud = cli("run", "s.yaml", "-o", "r.csv", cwd=tmp_path)
    assert loud.returncode == 0, loud.stderr
    assert "not connected" in loud.stderr and "warning: talker:" in loud.stderr  # there is something to hide
    quiet = cli("run", "s.yaml", "-o", "r.csv", "-q", cwd=tmp_path)
    assert quiet.returncode == 0
    assert (quiet.stdout, quiet.stderr) == ("", "")
    assert read_csv(tmp_path / "r.csv")[1][-1, 0] == pytest.approx(0.55)  # the talker ended the run


# --- an exception in a user's component ---------------------------------------------------------

BUGGY = '''"""A component with a bug in one hook, chosen by the parameter ``where``."""
from deltafmi.component import Component, Output, Parameter


class Buggy(Component):
    """Raises in outputs() (where = 0) or in its own do_step() (where = 1) once t > 0.05."""

    where = Parameter(0, type=int, description="0: outputs, 1: do_step")
    y = Output(variability="discrete", description="the time")

    def outputs(self, t):
        if self.where == 0 and t > 0.05:
            raise RuntimeError("my bug")  # line 13
        self.y = t

    def do_step(self, t, h):
        if self.where == 1 and t > 0.05:
            raise ValueError("bad step")  # line 18
'''


@pytest.mark.parametrize("where, shown", [(0, "RuntimeError: my bug (buggy.py:13 in outputs)"),
                                          (1, "ValueError: bad step (buggy.py:18 in do_step)")])
def test_an_exception_in_a_component_names_its_source_line_and_v_shows_the_traceback(tmp_path, where, shown):
    # the FMU's own message names the hook's line in the model source, also when the native layer
    # calls the hook itself (a component's own do_step); -v shows the whole traceback
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "buggy.py").write_text(BUGGY)
    (tmp_path / "s.yaml").write_text(
        "experiment: {stop: 0.1, step: 0.01}\ncomponents:\n"
        f"  b: {{source: models/buggy.py, parameters: {{where: {where}}}}}\n")
    short = cli("run", "s.yaml", "-o", "r.csv", cwd=tmp_path)
    assert short.returncode == 1
    assert shown in short.stderr and "Traceback" not in short.stderr
    full = cli("run", "s.yaml", "-o", "r.csv", "-v", cwd=tmp_path)
    assert full.returncode == 1
    assert "Traceback (most recent call last)" in full.stderr
    line = 13 if where == 0 else 18
    assert re.search(rf'File ".*/resources/model/buggy.py", line {line}, in {"outputs" if where == 0 else "do_step"}',
                     full.stderr), full.stderr


def test_an_fmu_is_known_by_its_extension_in_any_case(osc, tmp_path):
    upper = tmp_path / "OSC.FMU"
    shutil.copy(osc, upper)
    for command in (["validate", str(upper)], ["linearize", str(upper), "-o", str(tmp_path / "lin.npz")],
                    ["run", str(upper), "--stop", "0.1", "-q", "-o", str(tmp_path / "r.csv")]):
        result = CliRunner().invoke(main, command)
        assert result.exit_code == 0, (command, result.output)
    assert "OSC.FMU: OK" in CliRunner().invoke(main, ["validate", str(upper)]).output
