"""An FMU carries the deltafmi modules its model imports and the runtime needs, nothing more.

The set comes from reading import statements (deltafmi.export.reach); these tests hold it against
what Python actually imports, against the archives built from deltafmi/models, and against the cache key.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import numpy as np
import pytest

from deltafmi.export.kernels import kernel_groups, kernel_modules, mypyc_version
from deltafmi.export.packager import load_component_class, runtime_modules
from deltafmi.mechanics import delta as d

from conftest import FMU_SRC, MODEL_FILES, ROOT, unzip

SOURCES = MODEL_FILES
EXT_SUFFIX = sysconfig.get_config_var("EXT_SUFFIX")
needs_mypyc = pytest.mark.skipif(mypyc_version() is None, reason="mypy (mypyc) is not installed: no compiled kernels")

# Import the model as boot.py does (model source + the runtime), then list deltafmi's modules.
_TRACE = """
import importlib, importlib.util, json, sys
importlib.import_module("deltafmi.component.instance")
spec = importlib.util.spec_from_file_location("model_under_test", sys.argv[1])
spec.loader.exec_module(importlib.util.module_from_spec(spec))
print(json.dumps(sorted(m for m in sys.modules if m == "deltafmi" or m.startswith("deltafmi."))))
"""


def _archive_modules(fmu: Path) -> set[str]:
    """Module names of the deltafmi sources an FMU carries."""
    prefix = "resources/python/"
    return {name[len(prefix):-3].replace("/", ".").removesuffix(".__init__")
            for name in zipfile.ZipFile(fmu).namelist()
            if name.startswith(prefix + "deltafmi/") and name.endswith(".py")}


@pytest.mark.parametrize("source", SOURCES)
def test_the_static_set_covers_what_python_imports(source):
    """Everything importing the model and the runtime loads is in the set an FMU carries."""
    if "deltafmi.runtime.equations" in (FMU_SRC / source).read_text():
        load_component_class(FMU_SRC / source)  # compiles its equations: the build cache has them now
    out = subprocess.run([sys.executable, "-c", _TRACE, str(FMU_SRC / source)], capture_output=True,
                         text=True, check=True, cwd=ROOT)
    imported = set(json.loads(out.stdout))
    carried = set(runtime_modules(FMU_SRC / source))
    assert "deltafmi.component.instance" in imported
    assert imported <= carried, f"imported but not carried: {sorted(imported - carried)}"


# Run an FMU in fmpy (CS, then ME) and list every deltafmi module the process looked for: a
# finder first on sys.meta_path sees each import, also those inside the FMU's module context.
_RUN = """
import json, sys
seen = set()
class Recorder:
    @staticmethod
    def find_spec(name, path=None, target=None):
        if name == "deltafmi" or name.startswith("deltafmi."):
            seen.add(name)
sys.meta_path.insert(0, Recorder)
import fmpy
for kind in ("CoSimulation", "ModelExchange"):
    fmpy.simulate_fmu(sys.argv[1], fmi_type=kind, stop_time=0.01)
print(json.dumps(sorted(seen)))
"""


@pytest.mark.parametrize("source, has_states", [
    ("oscillator.py", True), ("delta_robot.py", True), ("bouncing_ball_restitution.py", True),
    ("delta_controller.py", False), ("trajectory.py", False)])
def test_what_a_run_imports_is_in_the_fmu(build_fmu_from_src, source, has_states):
    fmu = build_fmu_from_src(source)
    out = subprocess.run([sys.executable, "-I", "-c", _RUN, str(fmu)], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    imported = {m for m in json.loads(out.stdout) if m != "deltafmi.component._values" and "__mypyc" not in m}
    # the CS solver, imported only when a step integrates states
    assert ("deltafmi.component.cvode" in imported) == has_states
    missing = imported - _archive_modules(fmu)
    assert not missing, f"a run imported modules the FMU does not carry: {sorted(missing)}"


def test_oscillator_carries_no_mechanics_and_no_kernels(build_fmu_from_src):
    fmu = build_fmu_from_src("oscillator.py")
    names = zipfile.ZipFile(fmu).namelist()
    assert not [n for n in names if "mechanics" in n]
    assert not [n for n in names if "__mypyc" in n or n.endswith(EXT_SUFFIX)]  # (_values.abi3.so is the runtime's)
    assert _archive_modules(fmu) == set(runtime_modules(FMU_SRC / "oscillator.py"))
    assert fmu.stat().st_size <= 300_000, f"{fmu.stat().st_size} bytes"


@pytest.mark.parametrize("source", [s for s in SOURCES if not any(
    m.startswith("deltafmi.mechanics.delta") for m in runtime_modules(FMU_SRC / s))])
def test_fmus_of_models_without_delta_robot_code_are_small(build_fmu_from_src, source):
    fmu = build_fmu_from_src(source)
    assert not [n for n in zipfile.ZipFile(fmu).namelist() if "mechanics/delta" in n or "__mypyc" in n]
    # ~300 kB of runtime and binary, and the model's compiled kernels: their library and C (30-100 kB)
    assert fmu.stat().st_size <= 450_000, f"{fmu.stat().st_size} bytes"


@pytest.mark.parametrize("source, kernels", [
    ("delta_robot.py", {"dynamics", "kinematics", "jacobian"}),
    # deltafmi.mechanics.delta's __init__ re-exports the plant: importing .control loads it
    ("delta_controller.py", {"control_law", "dynamics", "kinematics"}),
    ("bouncing_ball.py", set()),
])
@needs_mypyc
def test_an_fmu_carries_the_kernels_of_the_modules_it_reaches(build_fmu_from_src, source, kernels):
    fmu = build_fmu_from_src(source)
    names = zipfile.ZipFile(fmu).namelist()
    folder = "resources/python/deltafmi/mechanics/delta/"
    shims = {n[len(folder):-len(EXT_SUFFIX)] for n in names
             if n.startswith(folder) and n.endswith(EXT_SUFFIX) and "__mypyc" not in n}
    assert shims == kernels
    # one shared library per mypyc group of the carried kernels, none of other groups
    groups = {tuple(group) for group in kernel_groups() for name in group if name.rpartition(".")[2] in kernels}
    assert len([n for n in names if "__mypyc" in n]) == len(groups)
    # and no other module's kernels: what goes in follows the carried modules
    assert {m.rpartition(".")[2] for m in set(kernel_modules()) & _archive_modules(fmu)} == kernels


@needs_mypyc
def test_the_robot_fmus_compiled_kernels_load_from_the_fmu_alone(build_fmu_from_src, tmp_path):
    """In a fresh interpreter that finds deltafmi only in the FMU, the plant modules are the
    shipped mypyc extensions (so their group library is in the FMU) and give the pure-Python
    library's derivatives to round-off."""
    python_dir = unzip(build_fmu_from_src("delta_robot.py"), tmp_path / "robot") / "resources" / "python"
    rng = np.random.default_rng(5)
    x = np.concatenate([d.inverse_kinematics(d.RL5, [0.1, -0.2, -0.9]), rng.normal(0.0, 1.0, 9)]).tolist()
    u = [40.0, -25.0, 10.0]
    script = f"""
import json, sys
sys.path.insert(0, {str(python_dir)!r})
import deltafmi
from deltafmi.mechanics.delta import dynamics, jacobian, kinematics, params
assert deltafmi.__file__.startswith({str(python_dir)!r}), deltafmi.__file__
print(json.dumps({{"files": [m.__file__ for m in (dynamics, jacobian, kinematics)],
                  "dx": list(dynamics.state_derivative(params.RL5, {x!r}, {u!r}, [0.0, 0.0, 0.0]))}}))
"""
    out = subprocess.run([sys.executable, "-I", "-c", script], capture_output=True, text=True, check=True,
                         cwd=tmp_path)
    result = json.loads(out.stdout)
    assert all(f.endswith(EXT_SUFFIX) for f in result["files"]), result["files"]
    np.testing.assert_allclose(result["dx"], d.state_derivative(d.RL5, np.array(x), np.array(u), np.zeros(3)),
                               rtol=1e-12, atol=1e-12)


def test_content_key_follows_only_the_files_an_fmu_carries(tmp_path):
    """Editing a module that neither the Oscillator nor the bouncing ball reaches keeps their
    cached FMUs; editing one changes the keys of exactly the FMUs that carry it.
    (Runs on a copy of the package, found first on PYTHONPATH.)"""
    shutil.copytree(ROOT / "deltafmi", tmp_path / "deltafmi", ignore=shutil.ignore_patterns("__pycache__", "*.so"))
    script = f"""
import json
from pathlib import Path
import deltafmi
from deltafmi.export.packager import content_key
assert deltafmi.__file__.startswith({str(tmp_path)!r}), deltafmi.__file__
print(json.dumps([content_key(Path({str(FMU_SRC)!r}) / name) for name in ("oscillator.py", "bouncing_ball.py")]))
"""

    def keys() -> list[str]:
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True,
                             cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(tmp_path)})
        return json.loads(out.stdout)

    def touch(relative: str) -> None:
        with open(tmp_path / "deltafmi" / relative, "a", encoding="utf-8") as f:
            f.write("\n# edited\n")

    oscillator, ball = keys()
    touch("mechanics/delta/dynamics.py")  # neither carries the robot
    assert keys() == [oscillator, ball]
    touch("mechanics/examples/bouncing_ball.py")
    same_oscillator, new_ball = keys()
    assert same_oscillator == oscillator and new_ball != ball
    ball = new_ball
    touch("component/base.py")  # both carry the runtime
    new_oscillator, new_ball = keys()
    assert new_oscillator != oscillator and new_ball != ball
