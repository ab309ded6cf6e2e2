"""``deltafmi info`` and ``deltafmi validate X.fmu`` say whether an FMU is portable and, if not,
which Python it needs and whether this machine has it."""
from __future__ import annotations

import platform
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from deltafmi.cli import main


def _python_without_numpy() -> str | None:
    """A CPython on this machine that cannot import numpy (pyenv's bare interpreters)."""
    for candidate in sorted(Path("/root/.pyenv/versions").glob("3.1*/bin/python3")):
        if subprocess.run([str(candidate), "-c", "import numpy"], capture_output=True).returncode != 0:
            return str(candidate)
    return None


def test_validate_names_the_interpreter_a_plain_fmu_needs(build_fmu_from_src):
    fmu = build_fmu_from_src("oscillator.py")
    result = CliRunner().invoke(main, ["validate", str(fmu)])
    assert result.exit_code == 0, result.output
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    assert f"not portable: in a host that runs no Python it starts CPython {version}" in result.output
    assert "deltafmi build oscillator.py --portable" in result.output
    assert "this machine: has what it needs" in result.output


def test_validate_fails_when_the_named_interpreter_lacks_numpy(build_fmu_from_src, monkeypatch):
    bare = _python_without_numpy()
    if bare is None:
        pytest.skip("every Python on this machine has numpy: no interpreter to be missing it")
    fmu = build_fmu_from_src("oscillator.py")
    monkeypatch.setenv("DELTAFMI_PYTHON", bare)
    result = CliRunner().invoke(main, ["validate", str(fmu)])
    assert result.exit_code == 1
    assert f"cannot start it: {bare} cannot import numpy" in result.output
    assert "Traceback" not in result.output


def test_info_and_validate_of_a_portable_fmu_state_its_glibc_floor(portable_oscillator_fmu):
    from deltafmi.export.requirements import read_config

    floor = read_config(portable_oscillator_fmu)["glibc"]
    for command in ("info", "validate"):
        result = CliRunner().invoke(main, [command, str(portable_oscillator_fmu)])
        assert result.exit_code == 0, result.output
        assert "portable: carries CPython" in result.output
        assert f"glibc {floor} or newer, no Python" in result.output
    have = tuple(int(x) for x in platform.libc_ver()[1].split("."))
    assert tuple(int(x) for x in floor.split(".")) <= have  # built here, so it runs here


def test_validate_of_a_missing_file_is_an_error_not_a_traceback(tmp_path):
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "nothing.fmu")])
    assert result.exit_code == 1
    assert "no such file" in result.output
