"""FMUs of ours in one process share their byte-identical deltafmi modules, and only those.

Each FMU records a closure key for every module it carries (deltafmi.builder.shared_modules);
boot.py lends a module already imported by an earlier FMU under the same key instead of importing
the FMU's own copy again. Checked here, in one process through fmpy: two different models built
by this deltafmi share their runtime modules and compute what they compute alone (the oscillator
against its closed form); a copy whose runtime module differs (as one built by another deltafmi
version) shares none of the modules that reach the differing file, and every module whose key is
unchanged still is shared; a copy edited after its build (its recorded keys stale) and a portable
FMU share nothing.
"""
from __future__ import annotations

import importlib
import json
import shutil
import sys
from pathlib import Path

import fmpy
import numpy as np
import pytest

from conftest import unzip
from deltafmi.builder.shared_modules import PYTHON_PREFIX, carried_digests, module_keys
from oscillator_analytic import solution

# the registry the boot code of every FMU shares (see deltafmi/runtime/boot.py)
REGISTRY = "_deltafmi_fmu_registry"


def instantiate(directory: Path, name: str) -> fmpy.fmi2.FMU2Slave:
    md = fmpy.read_model_description(str(directory))
    fmu = fmpy.fmi2.FMU2Slave(guid=md.guid, unzipDirectory=str(directory),
                              modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate()
    return fmu


def modules_of(directory: Path) -> dict:
    """What the FMU unpacked in ``directory`` gets when it imports each module it carries (its
    own copy or one lent), by name."""
    info, _, _, context = sys.modules[REGISTRY].loaded[str((directory / "resources").resolve())]
    with context():
        return {name: importlib.import_module(name) for name in recorded_keys(directory)}


def recorded_keys(directory: Path) -> dict:
    return json.loads((directory / "resources" / "deltafmi.json").read_text())["shared_modules"]


def test_the_keys_follow_what_a_module_reaches(tmp_path):
    """A module's key changes with its own file and with any file it imports, not with others."""
    package = tmp_path / "deltafmi"
    (package / "runtime").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "runtime" / "__init__.py").write_text("")
    (package / "runtime" / "low.py").write_text("X = 1\n")
    (package / "runtime" / "mid.py").write_text("from .low import X\n")
    (package / "runtime" / "apart.py").write_text("Y = 2\n")
    (package / "master").mkdir()
    (package / "master" / "__init__.py").write_text("")
    (package / "master" / "loop.py").write_text("from deltafmi.runtime.low import X\n")  # finds files beside it

    def keys() -> dict:
        return module_keys([(path, PYTHON_PREFIX + path.relative_to(tmp_path).as_posix())
                            for path in sorted(package.rglob("*.py"))])

    before = keys()
    # no packages, and none of the master's modules (a scenario exported as one FMU carries them)
    assert set(before) == {"deltafmi.runtime.low", "deltafmi.runtime.mid", "deltafmi.runtime.apart"}
    assert len(set(before.values())) == 3  # one key per module, even for modules of the same closure
    (package / "runtime" / "low.py").write_text("X = 3\n")
    after = keys()
    assert after["deltafmi.runtime.low"] != before["deltafmi.runtime.low"]
    assert after["deltafmi.runtime.mid"] != before["deltafmi.runtime.mid"]  # it imports low
    assert after["deltafmi.runtime.apart"] == before["deltafmi.runtime.apart"]
    (package / "runtime" / "__init__.py").write_text("# changed\n")
    assert all(keys()[name] != after[name] for name in after)  # the package is on every module's path


def test_two_models_share_their_runtime_and_compute_as_alone(build_fmu_from_src, tmp_path):
    oscillator = unzip(build_fmu_from_src("oscillator.py"), tmp_path / "oscillator")
    trajectory = unzip(build_fmu_from_src("trajectory.py"), tmp_path / "trajectory")
    fmus = [instantiate(trajectory, "trajectory"), instantiate(oscillator, "oscillator")]
    try:
        mine, theirs = modules_of(oscillator), modules_of(trajectory)
        keys, their_keys = recorded_keys(oscillator), recorded_keys(trajectory)
        common = [name for name in mine if name in theirs and keys[name] == their_keys[name]]
        assert "deltafmi.runtime.instance" in common and "deltafmi.runtime.base" in common
        for name in common:
            assert mine[name] is theirs[name], name
        loaded = sys.modules[REGISTRY].loaded
        instance_class = {name: loaded[str((directory / "resources").resolve())][2]
                          for name, directory in (("oscillator", oscillator), ("trajectory", trajectory))}
        assert instance_class["oscillator"] is instance_class["trajectory"]  # FmuInstance
    finally:
        for fmu in fmus:
            fmu.freeInstance()
    # the oscillator, started after the trajectory lent it its runtime, against its closed form
    result = fmpy.simulate_fmu(str(oscillator), stop_time=2.0, output_interval=0.01, output=["x", "v"])
    x, v, _ = solution(result["time"])
    np.testing.assert_allclose(result["x"], x, atol=2e-5)
    np.testing.assert_allclose(result["v"], v, atol=2e-4)


def test_a_differing_runtime_file_is_never_shared(build_fmu_from_src, tmp_path):
    """A copy of the oscillator whose runtime's partials.py differs, its keys recorded as a build
    by that other version records them: what reaches partials.py is its own, the rest shared."""
    fmu = build_fmu_from_src("oscillator.py")
    same = unzip(fmu, tmp_path / "same")
    other = unzip(fmu, tmp_path / "other")
    python = other / "resources" / "python"
    changed = python / "deltafmi" / "runtime" / "partials.py"
    changed.write_text(changed.read_text() + "\nOTHER_VERSION = True\n")
    for stale in (changed.parent / "__pycache__").glob("partials.*"):
        stale.unlink()  # the FMU's bytecode is unchecked: it would run the old file
    info = json.loads((other / "resources" / "deltafmi.json").read_text())
    files = [(path, f"resources/python/{path.relative_to(python).as_posix()}") for path in python.rglob("*")
             if path.is_file() and "__pycache__" not in path.parts]
    info["shared_modules"], info["shared_files"] = module_keys(files), carried_digests(files)
    (other / "resources" / "deltafmi.json").write_text(json.dumps(info))
    fmus = [instantiate(same, "same"), instantiate(other, "other")]
    try:
        mine, theirs = modules_of(other), modules_of(same)
        keys, their_keys = recorded_keys(other), recorded_keys(same)
        assert getattr(mine["deltafmi.runtime.partials"], "OTHER_VERSION", False)
        assert not hasattr(theirs["deltafmi.runtime.partials"], "OTHER_VERSION")
        differing = {name for name in keys if keys[name] != their_keys[name]}
        assert {"deltafmi.runtime.partials", "deltafmi.runtime.instance"} <= differing
        assert set(keys) - differing  # some modules do not reach partials.py: those are shared
        for name in set(mine) & set(theirs):
            assert (mine[name] is theirs[name]) == (name not in differing), name
    finally:
        for fmu in fmus:
            fmu.freeInstance()


@pytest.mark.parametrize("edited_first", [False, True])
def test_a_file_edited_after_the_build_is_never_shared(build_fmu_from_src, tmp_path, edited_first):
    """An FMU whose carried runtime file was edited after the build (its keys left as recorded)
    runs its edit, whichever FMU starts first, and lends none of it to an unedited copy."""
    fmu = build_fmu_from_src("oscillator.py")
    clean = unzip(fmu, tmp_path / "clean")
    edited = unzip(fmu, tmp_path / "edited")
    changed = edited / "resources" / "python" / "deltafmi" / "runtime" / "partials.py"
    changed.write_text(changed.read_text() + "\nEDITED = True\n")
    for stale in (changed.parent / "__pycache__").glob("partials.*"):
        stale.unlink()  # the FMU's bytecode is unchecked: it would run the old file
    order = [(edited, "edited"), (clean, "clean")] if edited_first else [(clean, "clean"), (edited, "edited")]
    fmus = [instantiate(directory, name) for directory, name in order]
    try:
        assert getattr(modules_of(edited)["deltafmi.runtime.partials"], "EDITED", False)
        assert not hasattr(modules_of(clean)["deltafmi.runtime.partials"], "EDITED")
    finally:
        for instance in fmus:
            instance.freeInstance()


def test_a_portable_fmu_shares_nothing(build_fmu_from_src, tmp_path):
    """Marked portable, an FMU imports every module of its own (they find its libraries beside them)."""
    fmu = build_fmu_from_src("oscillator.py")
    plain = unzip(fmu, tmp_path / "plain")
    portable = unzip(fmu, tmp_path / "portable")
    config = portable / "resources" / "python.cfg"
    config.write_text(config.read_text() + "\nportable=1\n")
    fmus = [instantiate(plain, "plain"), instantiate(portable, "portable")]
    try:
        mine, theirs = modules_of(portable), modules_of(plain)
        assert mine and all(mine[name] is not theirs.get(name) for name in mine)
    finally:
        for fmu in fmus:
            fmu.freeInstance()
