"""An FMU carries the deltafmi modules its model imports and the runtime needs, nothing more.

The set comes from reading import statements (deltafmi.builder.reach); these tests hold it against
what Python actually imports, against the archives built from deltafmi/models, and against the cache key.
"""
from __future__ import annotations

import importlib.util
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

from deltafmi.builder.packager import load_component_class, runtime_modules
from deltafmi.physics import delta as d

from conftest import FMU_SRC, MODEL_FILES, ROOT, unzip

SOURCES = MODEL_FILES
EXT_SUFFIX = sysconfig.get_config_var("EXT_SUFFIX")

# Import the model as boot.py does (model source + the runtime), then list deltafmi's modules.
_TRACE = """
import importlib, importlib.util, json, sys
importlib.import_module("deltafmi.runtime.instance")
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
    assert "deltafmi.runtime.instance" in imported
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
    imported = {m for m in json.loads(out.stdout) if m != "deltafmi.runtime._values"}
    # the CS solver, imported only when a step integrates states
    assert ("deltafmi.runtime.cvode" in imported) == has_states
    missing = imported - _archive_modules(fmu)
    assert not missing, f"a run imported modules the FMU does not carry: {sorted(missing)}"


# Instantiate an FMU in fmpy (unpacked afresh) and list the files Python compiled from source
_COMPILED = """
import builtins, json, sys
compiled, compile_source = [], builtins.compile
def recording(source, filename, *args, **kwargs):
    compiled.append(str(filename))
    return compile_source(source, filename, *args, **kwargs)
builtins.compile = recording
import fmpy
fmpy.simulate_fmu(sys.argv[1], stop_time=0.01)
print(json.dumps(compiled))
"""


def test_the_bridge_boots_from_the_bytecode_the_fmu_carries(build_fmu_from_src):
    """The FMU carries the bytecode of its deltafmi_boot.py as of its runtime's modules (unchecked
    hash: an FMU is unpacked afresh for a run), and the bridge imports the file rather than
    running its text: no instantiation parses and compiles the boot code."""
    fmu = build_fmu_from_src("oscillator.py")
    assert "resources/__pycache__/" + Path(importlib.util.cache_from_source("deltafmi_boot.py")).name \
        in zipfile.ZipFile(fmu).namelist()
    out = subprocess.run([sys.executable, "-I", "-c", _COMPILED, str(fmu)], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    compiled = json.loads(out.stdout.strip().splitlines()[-1])
    assert any(name.endswith("oscillator.py") for name in compiled)  # the model's source: no bytecode carried
    assert [name for name in compiled if "deltafmi_boot" in name or "/python/deltafmi/" in name] == []


def test_oscillator_carries_no_mechanics_and_no_kernels(build_fmu_from_src):
    fmu = build_fmu_from_src("oscillator.py")
    names = zipfile.ZipFile(fmu).namelist()
    assert not [n for n in names if "mechanics" in n]
    assert not [n for n in names if n.endswith(EXT_SUFFIX)]  # (_values.abi3.so is the runtime's)
    assert _archive_modules(fmu) == set(runtime_modules(FMU_SRC / "oscillator.py"))
    # the runtime's sources, their bytecode and the binary: 352 kB (the budget grew with the
    # runtime: events from inputs, a component's own C step, modules shared between FMUs,
    # compiled functions, the boot code's bytecode, 13 kB; serialized states checked before
    # they load, 2.5 kB)
    assert fmu.stat().st_size <= 360_000, f"{fmu.stat().st_size} bytes"


@pytest.mark.parametrize("source", [s for s in SOURCES if not any(
    m.startswith("deltafmi.physics.delta") for m in runtime_modules(FMU_SRC / s))])
def test_fmus_of_models_without_delta_robot_code_are_small(build_fmu_from_src, source):
    fmu = build_fmu_from_src(source)
    assert not [n for n in zipfile.ZipFile(fmu).namelist() if "physics/delta" in n]
    # ~352 kB of runtime and binary, and the model's compiled kernels: their library and C (30-140 kB)
    assert fmu.stat().st_size <= 500_000, f"{fmu.stat().st_size} bytes"


@pytest.mark.parametrize("source, mechanics", [
    ("delta_robot.py", {"dynamics", "kinematics", "jacobian"}),
    # deltafmi.physics.delta's __init__ re-exports the plant: importing .control loads it
    ("delta_controller.py", {"control_law", "dynamics", "kinematics"}),
    ("bouncing_ball.py", set()),
])
def test_an_fmus_only_compiled_code_is_its_binaries_and_the_value_access(build_fmu_from_src, source, mechanics):
    """The mechanics modules a model reaches go in as source; its compiled kernels are the C
    library generated from them, beside the FMI binary; the one Python extension module is the
    runtime's value access."""
    fmu = build_fmu_from_src(source)
    names = zipfile.ZipFile(fmu).namelist()
    folder = "resources/python/deltafmi/physics/delta/"
    assert {n[len(folder):-3] for n in names if n.startswith(folder) and n.endswith(".py")} >= mechanics
    assert [n for n in names if n.startswith("resources/python/") and n.endswith(".so")] == [
        "resources/python/deltafmi/runtime/_values.abi3.so"]
    model = json.loads(zipfile.ZipFile(fmu).read("resources/native_kernels.json"))["library"]
    assert model in names and model.startswith("binaries/") and model.endswith("_kernels.so")


def test_the_robot_fmus_mechanics_load_from_the_fmu_alone(build_fmu_from_src, tmp_path):
    """In a fresh interpreter that finds deltafmi only in the FMU, the plant modules are the
    FMU's sources and give the library's derivatives, bit for bit."""
    python_dir = unzip(build_fmu_from_src("delta_robot.py"), tmp_path / "robot") / "resources" / "python"
    rng = np.random.default_rng(5)
    x = np.concatenate([d.inverse_kinematics(d.RL5, [0.1, -0.2, -0.9]), rng.normal(0.0, 1.0, 9)]).tolist()
    u = [40.0, -25.0, 10.0]
    script = f"""
import json, sys
sys.path.insert(0, {str(python_dir)!r})
import deltafmi
from deltafmi.physics.delta import dynamics, jacobian, kinematics, params
assert deltafmi.__file__.startswith({str(python_dir)!r}), deltafmi.__file__
print(json.dumps({{"files": [m.__file__ for m in (dynamics, jacobian, kinematics)],
                  "dx": list(dynamics.state_derivative(params.RL5, {x!r}, {u!r}, [0.0, 0.0, 0.0]))}}))
"""
    out = subprocess.run([sys.executable, "-I", "-c", script], capture_output=True, text=True, check=True,
                         cwd=tmp_path)
    result = json.loads(out.stdout)
    assert all(f.startswith(str(python_dir)) and f.endswith(".py") for f in result["files"]), result["files"]
    np.testing.assert_array_equal(result["dx"], d.state_derivative(d.RL5, x, u, [0.0, 0.0, 0.0]))


def test_content_key_follows_only_the_files_an_fmu_carries(tmp_path):
    """Editing a module that neither the Oscillator nor the bouncing ball reaches keeps their
    cached FMUs; editing one changes the keys of exactly the FMUs that carry it.
    (Runs on a copy of the package, found first on PYTHONPATH.)"""
    shutil.copytree(ROOT / "deltafmi", tmp_path / "deltafmi", ignore=shutil.ignore_patterns("__pycache__", "*.so"))
    script = f"""
import json
from pathlib import Path
import deltafmi
from deltafmi.builder.packager import content_key
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
    touch("physics/delta/dynamics.py")  # neither carries the robot
    assert keys() == [oscillator, ball]
    touch("physics/contact_problems/bouncing_ball.py")
    same_oscillator, new_ball = keys()
    assert same_oscillator == oscillator and new_ball != ball
    ball = new_ball
    touch("runtime/base.py")  # both carry the runtime
    new_oscillator, new_ball = keys()
    assert new_oscillator != oscillator and new_ball != ball
