"""The installed product: the wheel built from a clean copy, installed into a fresh virtual
environment outside the checkout, run from an empty folder by a user without a C compiler.

``tools/build_wheel.py`` builds the wheel (git's files only, setup.py's prebuilt layer, auditwheel's
manylinux tag; the layer's pieces are compiled into this session's build cache first, and the
wheel's build copies them from there: ``$DELTAFMI_CACHE_SEED``); uv installs it and its
dependencies into a new venv (from the registry or uv's cache). The commands then run with ``PATH`` holding only that venv's ``bin`` (no ``cc``, ``gcc``
or ``$CC``: deltafmi looks the compiler up on ``PATH``, as setuptools does) and ``HOME``
a fresh folder (so the per-user cache is ``$HOME/.cache/deltafmi``, empty). Marked ``wheel``
(``-m "not wheel"`` leaves it out); about a minute, most of it the wheel's build; the install needs the
registry or uv's cache.
"""
from __future__ import annotations

import csv
import math
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from uv import find_uv_bin

pytestmark = pytest.mark.wheel

ROOT = Path(__file__).resolve().parents[2]
G = 9.81


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    from deltafmi.builder.prebuild import build_pieces
    from deltafmi.toolchain import cache_dir

    # the prebuilt layer's pieces into this session's build cache (other tests use them too), from
    # which the wheel's build copies them rather than compiling them a second time
    build_pieces()
    out = tmp_path_factory.mktemp("dist")
    result = subprocess.run([sys.executable, str(ROOT / "tools" / "build_wheel.py"), "-o", str(out)],
                            capture_output=True, text=True, env={**os.environ, "DELTAFMI_CACHE_SEED": str(cache_dir())})
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return Path(result.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def user(wheel, tmp_path_factory):
    """(run, venv): ``run(*args, cwd=...)`` runs ``deltafmi args`` as the wheel's user."""
    base = tmp_path_factory.mktemp("user")
    venv = base / "venv"
    # a venv without pip, into which uv installs the wheel and the dependencies it declares, from
    # the registry or uv's cache, with no bytecode compiled ahead (Python compiles what the
    # commands import): the same installation as pip's, without pip's 15-20 CPU-s of reading the
    # index's thousands of files per project
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    install = subprocess.run([find_uv_bin(), "pip", "install", "-q", "--python", str(venv / "bin" / "python"),
                              str(wheel)], capture_output=True, text=True)
    assert install.returncode == 0, install.stderr[-3000:]
    home = base / "home"
    home.mkdir()
    env = {"HOME": str(home), "PATH": str(venv / "bin"), "LANG": "C.UTF-8", "MPLBACKEND": "Agg"}
    for compiler in ("cc", "gcc", "clang"):
        assert shutil.which(compiler, path=env["PATH"]) is None

    def run(*args: str, cwd: Path) -> subprocess.CompletedProcess:
        return subprocess.run([str(venv / "bin" / "deltafmi"), *args], cwd=cwd, env=env, capture_output=True,
                              text=True, timeout=300)
    return run, venv, home


def _package_dir(venv: Path) -> Path:
    (package,) = venv.glob("lib/python3.*/site-packages/deltafmi")
    return package


def _files(folder: Path) -> set[str]:
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*") if "__pycache__" not in p.parts}


def _columns(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return {name: np.array([float(row[i]) for row in rows[1:]]) for i, name in enumerate(rows[0])}


def test_the_wheel_is_a_manylinux_wheel_with_prebuilt_binaries_models_and_examples(wheel):
    tag = f"cp{sys.version_info.major}{sys.version_info.minor}"
    assert re.fullmatch(rf"deltafmi-[0-9.]+-{tag}-{tag}-(manylinux[0-9]*_x86_64\.)*manylinux_2_\d+_x86_64\.whl",
                        wheel.name), wheel.name
    names = zipfile.ZipFile(wheel).namelist()
    prebuilt = [n for n in names if n.startswith("deltafmi/_prebuilt/")]
    for piece in ("/fmu.so", "/_values.abi3.so", "/fixed_step.so", "/erk.so", "/csv_rows.so", "/system_step.so",
                  "/DeltaRobot_kernels.so", "/DeltaController_kernels.so"):
        assert any(piece in n for n in prebuilt), piece
    # native C only: the one Python extension module is the runtime's value access (stable ABI)
    assert [n for n in prebuilt if n.endswith(".so") and ".cpython-" in n] == []
    assert {"deltafmi/models/delta_robot.py", "deltafmi/models/bouncing_ball.py",
            "deltafmi/scenarios/delta_tracking.yaml", "deltafmi/scenarios/studies/gain_payload.yaml",
            "deltafmi/docs/api.md", "deltafmi/docs/troubleshooting.md", "deltafmi/docs/delta_tracking.png"} <= set(names)
    assert not [n for n in names if n.endswith(".fmu") or n.startswith(("build/", "tests/"))]


def test_the_examples_run_from_an_empty_folder_without_a_compiler(user, tmp_path):
    run, venv, home = user
    package_files = _files(_package_dir(venv))
    listed = run("examples", cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    assert re.search(r"^\s*delta_tracking\b.+", listed.stdout, re.M)
    guides = run("guides", cwd=tmp_path)  # the README's guides, where the wheel put them
    assert guides.returncode == 0 and re.search(r"^api\.md\s+The Python API$", guides.stdout, re.M), guides.stdout
    assert guides.stdout.strip().endswith(str(_package_dir(venv) / "docs"))

    first = run("run", "delta_tracking", "--stop", "0.3", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    building = [line for line in first.stderr.splitlines() if line.startswith("building ")]
    assert building == [f"building {name} FMU (cached afterwards in ~/.cache/deltafmi/fmus) ..."
                        for name in ("Trajectory", "DeltaController", "DeltaRobot")]
    assert "Traceback" not in first.stderr and "instead of its compiled kernels" not in first.stderr
    assert _files(tmp_path) == {"delta_tracking.csv", "delta_tracking.csv.units.json"}  # its units beside it
    z = _columns(tmp_path / "delta_tracking.csv")
    assert z["time"][-1] == pytest.approx(0.3)
    # the robot starts at rest where the reference starts, and tracks it to a few micrometres
    for i in (1, 2, 3):
        assert z[f"plant.z[{i}]"][0] == pytest.approx(z[f"trajectory.r[{i}]"][0], abs=1e-12)
    assert z["plant.z[3]"][0] == pytest.approx(-1.0, abs=1e-12)
    error = max(np.max(np.abs(z[f"plant.z[{i}]"] - z[f"trajectory.r[{i}]"])) for i in (1, 2, 3))
    assert 0 < error < 2e-5

    # the FMUs are cached per user, and carry the prebuilt compiled kernels
    robot = list((home / ".cache" / "deltafmi" / "fmus").glob("*/DeltaRobot.fmu"))
    assert len(robot) == 1
    assert {"binaries/linux64/DeltaRobot.so", "binaries/linux64/DeltaRobot_kernels.so"} <= set(
        zipfile.ZipFile(robot[0]).namelist())
    again = run("run", "delta_tracking", "--stop", "0.3", "-o", "again.csv", cwd=tmp_path)
    assert again.returncode == 0 and "building" not in again.stderr

    ball = run("run", "bouncing_ball", cwd=tmp_path)
    assert ball.returncode == 0, ball.stderr
    b = _columns(tmp_path / "bouncing_ball.csv")
    t = b["time"]
    falling = t < math.sqrt(2 / G) - 0.01  # before the first impact: free fall from 1 m
    assert np.allclose(b["restitution.q"][falling], 1 - G * t[falling] ** 2 / 2, atol=1e-7, rtol=0)
    # e = 0.8: the first rebound rises to e^2 * 1 m
    first_flight = (t > 0.5) & (t < 1.1)
    assert np.max(b["restitution.q"][first_flight]) == pytest.approx(0.64, abs=1e-3)
    assert _files(_package_dir(venv)) == package_files  # nothing written into the installed package


def test_an_edited_copy_runs_without_a_compiler_and_matches_the_packaged_models(user, tmp_path):
    run, _, _ = user
    copied = run("examples", "copy", "delta_tracking", "d", cwd=tmp_path)
    assert copied.returncode == 0, copied.stderr
    robot = tmp_path / "d" / "models" / "delta_robot.py"
    robot.write_text(robot.read_text() + "\n# edited by the user\n")
    mine = run("run", "d/delta_tracking.yaml", "--stop", "0.2", "-o", "mine.csv", cwd=tmp_path)
    assert mine.returncode == 0, mine.stderr
    assert "building DeltaRobot FMU (cached afterwards" in mine.stderr  # the edited source: a new FMU
    packaged = run("run", "delta_tracking", "--stop", "0.2", "-o", "packaged.csv", cwd=tmp_path)
    assert packaged.returncode == 0, packaged.stderr
    a, b = _columns(tmp_path / "mine.csv"), _columns(tmp_path / "packaged.csv")
    assert a.keys() == b.keys() and len(a["time"]) == 201
    for name in a:  # same binary, same kernels, same model: the same numbers
        assert np.array_equal(a[name], b[name]), name


def test_an_equation_model_builds_with_its_prebuilt_kernels(user, tmp_path):
    """An equation model's kernels are C generated from the module its equations compile to, which
    the build cache keeps: the C names that module alone, so the wheel's prebuilt kernels (made in
    the build's folder) are the ones the user's build asks for."""
    run, _, _ = user
    built = run("build", "BouncingBallEquations", "-o", "ball.fmu", cwd=tmp_path)
    assert built.returncode == 0, built.stderr
    assert "instead of its compiled kernels" not in built.stderr, built.stderr
    assert "binaries/linux64/BouncingBallEquations_kernels.so" in zipfile.ZipFile(tmp_path / "ball.fmu").namelist()


def test_without_the_prebuilt_layer_a_build_says_it_needs_a_compiler(user, tmp_path):
    """What a checkout without a compiler meets: the wheel's layer moved away, a fresh cache."""
    run, venv, home = user
    prebuilt = _package_dir(venv) / "_prebuilt"
    hidden = tmp_path / "hidden"
    shutil.move(prebuilt, hidden)
    shutil.rmtree(home / ".cache", ignore_errors=True)
    try:
        (tmp_path / "mine.py").write_text((_package_dir(venv) / "models" / "oscillator.py").read_text())
        built = run("build", "mine.py", "-o", "mine.fmu", cwd=tmp_path)
        ran = run("run", "delta_tracking", "--stop", "0.1", cwd=tmp_path)
    finally:
        shutil.move(hidden, prebuilt)
    assert built.returncode != 0
    assert built.stderr.strip() == ("Error: mine.py: building needs a C compiler (cc not found; install gcc or set "
                                    "CC); the packaged models need none when deltafmi is installed from its wheel, "
                                    "which carries them prebuilt")
    assert ran.returncode == 2 and "Traceback" not in ran.stderr
    assert "building needs a C compiler (cc not found; install gcc or set CC)" in ran.stderr.splitlines()[0]
    assert not (tmp_path / "mine.fmu").exists()
