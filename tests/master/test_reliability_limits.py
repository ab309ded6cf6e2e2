"""Limits instead of hangs: non-finite times refused by ``validate`` and ``run`` alike, a step count
or a study's case count beyond a limit refused with the number and how to raise it, YAML aliases
bounded, a binary file named as a scenario refused in one line."""
from __future__ import annotations

import re
import signal
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.scenario.spec import MAX_STEPS, too_many_steps

ROOT = Path(__file__).resolve().parents[2]
FLAGSHIP = (ROOT / "scenarios" / "delta_tracking.yaml").read_text()


def _flagship_with(tmp_path: Path, key: str, value: str) -> Path:
    text, n = re.subn(rf"(?m)^(\s*){key}: .*$", rf"\g<1>{key}: {value}", FLAGSHIP, count=1)
    if not n:
        text = FLAGSHIP.replace("experiment:\n", f"experiment:\n  {key}: {value}\n", 1)
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return path


def _line_of(path: Path, key: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if line.strip().startswith(f"{key}:"))


@pytest.mark.parametrize("key, value, shown", [("stop", ".inf", "inf"), ("stop", ".nan", "nan"),
                                               ("step", ".inf", "inf"), ("step", ".nan", "nan"),
                                               ("start", "-.inf", "-inf")])
def test_non_finite_times_are_refused_by_validate_and_run_alike(tmp_path, key, value, shown):
    path = _flagship_with(tmp_path, key, value)
    expected = f"{path}:{_line_of(path, key)}: error: experiment.{key} ({shown}) must be a finite number"
    for args in (["validate", str(path)], ["run", str(path), "-o", str(tmp_path / "r.csv")]):
        command = args[0]
        done = CliRunner().invoke(main, args)
        assert done.exit_code == 2, (command, done.output)
        assert done.output.strip().splitlines()[-1] == expected, (command, done.output)
    assert not (tmp_path / "r.csv").exists()


def test_a_step_count_no_float_counts_names_no_limit_to_raise(tmp_path):
    """1 s in steps of 1e-300 s: more steps than 2^53, where consecutive step numbers are one
    float; the message said to raise max_steps to a 301-digit number. It says the run cannot count
    them, as for a span of 1e308 s."""
    done = CliRunner().invoke(main, ["run", "delta_tracking", "--step", "1e-300", "--stop", "1",
                                     "-o", str(tmp_path / "r.csv")])
    assert done.exit_code == 2, done.output
    assert done.output.strip().splitlines()[-1] == (
        "Error: 1 s in steps of 1e-300 s: more communication steps than a run can count; shorten the span or "
        "lengthen the step")


def test_a_step_count_beyond_the_limit_is_refused_with_the_count_and_the_override(tmp_path):
    path = _flagship_with(tmp_path, "step", "1.0e-12")
    done = CliRunner().invoke(main, ["validate", str(path)])
    assert done.exit_code == 2
    assert done.output.strip().splitlines()[-1] == (
        f"{path}:{_line_of(path, 'step')}: error: experiment.step: 3.5e+12 communication steps (3.5 s in steps of "
        "1e-12 s), more than the 1e+09 a run may take; to run them all, raise the limit (master: "
        "{max_steps: 3500000000000})")
    # the same from the command line's --step, before anything runs
    done = CliRunner().invoke(main, ["run", "delta_tracking", "--step", "1e-12", "-o", str(tmp_path / "r.csv")])
    assert done.exit_code == 2 and "3.5e+12 communication steps" in done.output, done.output
    # the override the message names lets it through the check
    raised = path.read_text().replace("master:", "master:\n  max_steps: 3500000000000", 1)
    assert "max_steps" in raised
    path.write_text(raised)
    done = CliRunner().invoke(main, ["validate", str(path)])
    assert "communication steps" not in done.output, done.output


def test_the_limit_counts_steps_as_the_master_does():
    assert too_many_steps(0.0, 1.0, 1e-9, MAX_STEPS) is None  # exactly the limit
    assert too_many_steps(0.0, 1.0, 0.999e-9, MAX_STEPS) is not None
    assert too_many_steps(0.0, 1.0e6, 1.0e-3, MAX_STEPS) is None  # the long runs the tests interrupt


def test_a_study_beyond_the_case_limit_is_refused_at_once_also_by_dry_run(tmp_path):
    (tmp_path / "s.yaml").write_text(FLAGSHIP)
    study = tmp_path / "big.yaml"
    study.write_text("scenario: s.yaml\nvary:\n  grid:\n"
                     "    controller.pole: {from: 1, to: 1000000, num: 1000000}\n"
                     "    plant.payload: {from: 0, to: 1, step: 1.0e-6}\n"
                     "metrics:\n  e: {signal: plant.z - trajectory.r, statistic: max}\n")
    started = time.monotonic()
    done = CliRunner().invoke(main, ["sweep", str(study), "--dry-run"])
    assert time.monotonic() - started < 60  # no list of a trillion cases is made
    assert done.exit_code == 2, done.output
    assert done.output.strip().splitlines()[-1] == (
        f"{study}:2: error: the study has 1,000,001,000,000 cases (1,000,000 x 1,000,001), more than the "
        "1,000,000 a study may have; to plan them all, raise the limit (max_cases: 1000001000000)")


def test_a_non_finite_grid_bound_is_one_line(tmp_path):
    (tmp_path / "s.yaml").write_text(FLAGSHIP)
    study = tmp_path / "nan.yaml"
    study.write_text("scenario: s.yaml\nvary:\n  grid:\n    controller.pole: {from: 1, to: .nan, num: 3}\n"
                     "metrics:\n  e: {signal: plant.z - trajectory.r, statistic: max}\n")
    done = CliRunner().invoke(main, ["sweep", str(study), "--dry-run"])
    assert done.exit_code == 2, done.output
    assert done.output.strip().splitlines()[-1] == \
        f"{study}:4: error: grid 'controller.pole': 'to' (nan) must be a finite number"


BOMB = "".join(f"{b}: &{b} [{', '.join([f'*{a}'] * 9)}]\n" for a, b in zip("abcdefgh", "bcdefghi"))


@pytest.mark.parametrize("command", ["validate", "run", "sweep"])
def test_a_yaml_alias_bomb_is_refused_in_a_moment(tmp_path, command):
    path = tmp_path / "bomb.yaml"
    path.write_text("a: &a [x, x, x, x, x, x, x, x, x]\n" + BOMB + "experiment: {stop: 1, step: 0.1}\n")
    started = time.monotonic()
    done = CliRunner().invoke(main, [command, str(path)])
    assert time.monotonic() - started < 30
    assert done.exit_code == 2, done.output
    assert re.fullmatch(rf"{re.escape(str(path))}:\d+: error: the YAML expands to more than 200,000 values "
                        r"\(aliases such as \*a repeat what &a names, again and again\): not a scenario or a study",
                        done.output.strip().splitlines()[-1]), done.output


def test_a_long_yaml_file_without_aliases_is_refused_for_its_length(tmp_path):
    """A file that writes out more than 200,000 values itself, no alias in it, was refused with
    the alias bomb's message (aliases repeating what &a names); it says the file holds too many."""
    path = tmp_path / "long.yaml"
    path.write_text("experiment: {stop: 1, step: 0.1}\nparameters:\n" +
                    "".join(f"  p{i}: [{i}, {i}]\n" for i in range(70_000)))
    done = CliRunner().invoke(main, ["validate", str(path)])
    assert done.exit_code == 2, done.output
    assert re.fullmatch(rf"{re.escape(str(path))}:\d+: error: the YAML holds more than 200,000 values: not a "
                        r"scenario or a study", done.output.strip().splitlines()[-1]), done.output


@pytest.mark.parametrize("command", ["validate", "run", "sweep"])
def test_a_binary_file_as_the_scenario_is_one_line(tmp_path, command):
    path = tmp_path / "photo.yaml"
    path.write_bytes(bytes(range(256)) * 8)
    done = CliRunner().invoke(main, [command, str(path)])
    assert done.exit_code == 2, done.output
    document = "study" if command == "sweep" else "scenario"
    assert done.output.strip().splitlines()[-1] == (
        f"{path}: error: not a {document}: not text (byte 128 is not UTF-8); a scenario or study is a YAML file")


def test_a_long_run_ends_on_sigterm_with_its_rows(tmp_path):
    """SIGTERM once the run steps (its result file open): it ends between two steps, exit 143."""
    from signal_runs import DELTAFMI, bytes_in, interrupt_when
    path = tmp_path / "long.yaml"
    path.write_text(FLAGSHIP.replace("stop: 3.5", "stop: 1.0e+5", 1))
    out = tmp_path / "r.csv"
    code, _, stderr = interrupt_when([*DELTAFMI, "run", str(path), "-o", str(out)], lambda: bytes_in(out) > 1000,
                                     signal.SIGTERM)
    assert code == 143, stderr
    assert "Traceback" not in stderr and stderr.strip().splitlines()[-1].startswith("interrupted at t = ")
    assert out.read_text().count("\n") > 2  # the run's rows, moved into place


def test_sigterm_while_an_fmu_is_built_is_one_line_and_exit_143(tmp_path):
    """Outside a run's stepping (here while a fresh cache builds the scenario's FMUs) a signal
    ends the command with one line and 128 + the signal, not a silent death."""
    import os
    import subprocess

    from signal_runs import DELTAFMI
    log = tmp_path / "stderr.txt"
    env = {**os.environ, "DELTAFMI_CACHE": str(tmp_path / "cache")}  # nothing cached: it builds
    with open(log, "w") as stderr:
        process = subprocess.Popen([*DELTAFMI, "run", "delta_tracking", "-o", str(tmp_path / "r.csv")],
                                   stdout=subprocess.DEVNULL, stderr=stderr, env=env, cwd=tmp_path)
        try:
            deadline = time.monotonic() + 600
            while "building" not in log.read_text():
                assert process.poll() is None and time.monotonic() < deadline, log.read_text()
                time.sleep(0.05)
            process.send_signal(signal.SIGTERM)
            process.wait(timeout=600)
        finally:
            if process.poll() is None:
                process.kill()
    text = log.read_text()
    assert process.returncode == 143, text
    assert "Traceback" not in text and text.strip().splitlines()[-1] == "interrupted (SIGTERM)"
    assert not (tmp_path / "r.csv").exists()
