"""One rule for every command's output: folders missing on its path are made (as ``mkdir -p``)
and the command says so in one line, ``made the folder X for X/out (it did not exist)``; an
existing folder makes no such line."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main

PARTS = Path(__file__).resolve().parents[1] / "master" / "event_row_parts"


@pytest.fixture(scope="module")
def here(build_fmu_from_src, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("outputs")
    shutil.copy(build_fmu_from_src("oscillator.py"), folder / "osc.fmu")
    shutil.copy(PARTS / "clock.py", folder / "clock.py")
    (folder / "s.yaml").write_text("experiment: {stop: 0.05, step: 0.01}\ncomponents:\n  osc: {fmu: osc.fmu}\n"
                                   "outputs: [osc.x]\n")
    done = CliRunner().invoke(main, ["run", str(folder / "s.yaml"), "-q", "-o", str(folder / "r.csv")])
    assert done.exit_code == 0, done.output
    return folder


COMMANDS = {  # the command, with {out} its output in folders that do not exist yet
    "run": ["run", "{dir}/s.yaml", "-q", "-o", "{out}/r.csv"],
    "plot": ["plot", "{dir}/r.csv", "osc.x", "-o", "{out}/p.png"],
    "build": ["build", "{dir}/clock.py", "-o", "{out}/Clock.fmu"],
    "build_into_folder": ["build", "{dir}/clock.py", "-o", "{out}/"],
    "export-ssp": ["export-ssp", "{dir}/s.yaml", "-o", "{out}/s.ssp"],
    "export-fmu": ["export-fmu", "{dir}/s.yaml", "-o", "{out}/S.fmu"],
    "linearize": ["linearize", "{dir}/osc.fmu", "-o", "{out}/lin"],
    "examples_copy": ["examples", "copy", "bouncing_ball", "{out}"],
    "study-case": ["study-case", "gain_payload", "0", "-o", "{out}/case.yaml"],
}


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_command_makes_its_missing_folders_and_says_so(here, name):
    out = here / name / "made" / "here"
    args = [a.format(dir=here, out=out) for a in COMMANDS[name]]
    done = CliRunner().invoke(main, args)
    assert done.exit_code == 0, done.output
    assert "Traceback" not in done.output
    assert out.is_dir() and any(out.iterdir())  # the output is in the folder made
    folder_only = args[-1].endswith("/") or name == "examples_copy"
    what = f"the folder {out}" if folder_only else f"the folder {out} for {args[-1]}"
    assert f"made {what} (it did not exist)" in done.output.splitlines()
    if name == "examples_copy":  # it copies into an empty folder only: another one, there already
        (out / "again").mkdir()
        args[-1] = str(out / "again")
    again = CliRunner().invoke(main, args)  # now there: nothing to say
    assert again.exit_code == 0 and "made the folder" not in again.output, again.output
