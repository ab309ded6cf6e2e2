"""Shared fixtures: FMUs built from the packaged models (deltafmi/models) once per session, the compiled C host."""
from __future__ import annotations

import os
import subprocess
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FMU_SRC = ROOT / "fmu_src"
#: the file names of the packaged models (deltafmi.models), one component each
MODEL_FILES = sorted(f"{module}.py" for module in __import__("deltafmi.models").models.MODELS.values())
NATIVE = ROOT / "deltafmi" / "runtime" / "native"


@pytest.fixture(scope="session")
def build_fmu_from_src(tmp_path_factory):
    """``build("oscillator.py") -> Path`` of a freshly built FMU (built once per session)."""
    from deltafmi.builder import build_fmu

    out = tmp_path_factory.mktemp("fmus")
    built: dict[str, Path] = {}

    def build(name: str) -> Path:
        if name not in built:
            built[name] = build_fmu(FMU_SRC / name, out / f"{Path(name).stem}.fmu")
        return built[name]

    return build


@pytest.fixture(scope="session")
def portable_oscillator_fmu() -> Path:
    """The portable Oscillator FMU (``deltafmi build --portable``), from the build cache."""
    from deltafmi.builder.packager import build_cached
    return build_cached(FMU_SRC / "oscillator.py", portable=True)


@pytest.fixture(scope="session")
def portable_delta_robot_fmu() -> Path:
    """The portable DeltaRobot FMU (CVODE, numpy, compiled kernels), from the build cache."""
    from deltafmi.builder.packager import build_cached
    return build_cached(FMU_SRC / "delta_robot.py", portable=True)


@pytest.fixture(scope="session")
def c_host(tmp_path_factory) -> Path:
    """The plain-C FMI importer of tests/c_host, compiled for this session."""
    exe = tmp_path_factory.mktemp("c_host") / "host"
    subprocess.run(["cc", "-O2", "-Wall", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "host.c"),
                    "-o", str(exe), "-ldl", "-lm"], check=True)
    return exe


def unzip(fmu: Path, target: Path) -> Path:
    """Extract an FMU and return the directory."""
    with zipfile.ZipFile(fmu) as z:
        z.extractall(target)
    return target


def clean_env(**extra: str) -> dict:
    """An environment with no Python variables and no LD_PRELOAD: a plain C host."""
    env = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}
    env.update(extra)
    return env


def start_model_exchange(fmu) -> None:
    """Take an fmpy ``FMU2Model`` from instantiation to continuous-time mode at t = 0."""
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.newDiscreteStates()
    fmu.enterContinuousTimeMode()
