"""The package layout: the import contracts between the layers hold (docs/architecture.md), the
master's sub-packages import only what their job needs, nothing is left flat in deltafmi.master,
``import deltafmi`` imports nothing and resolves its public API lazily, and the robot FMUs share
one declaration of the robot's parameters."""
from __future__ import annotations

import json
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description

import deltafmi
import deltafmi.master
import deltafmi.models

COSIM = Path(deltafmi.master.__file__).parent
ROOT = Path(__file__).resolve().parents[1]

#: sub-package -> the sub-packages it must not import (its job does not need them)
INDEPENDENT = {
    "scenario": {"stepping", "ssp", "linearize", "results", "commands", "live"},
    "ssp": {"stepping", "linearize", "results", "commands"},
    "results": {"stepping", "ssp", "linearize", "commands", "live"},
    "live": {"stepping", "ssp", "linearize", "commands"},
    "stepping": {"ssp", "linearize", "commands"},
    "linearize": {"ssp"},
    "system_fmu": {"ssp", "linearize", "commands"},
}


def _imported_after(code: str) -> set[str]:
    """Names of the modules a fresh interpreter holds after running ``code``."""
    out = subprocess.run([sys.executable, "-c", code + "\nimport json, sys; print(json.dumps(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True).stdout
    return set(json.loads(out.splitlines()[-1]))


def test_the_sub_packages_are_all_there():
    assert {m.name for m in pkgutil.iter_modules([str(COSIM)]) if m.ispkg} == set(INDEPENDENT)


@pytest.mark.parametrize("package", sorted(INDEPENDENT))
def test_a_sub_package_imports_none_it_does_not_need(package):
    modules = [f"deltafmi.master.{package}.{m.name}" for m in pkgutil.iter_modules([str(COSIM / package)])]
    assert modules, package
    loaded = _imported_after("".join(f"import {m}\n" for m in modules))
    assert set(modules) <= loaded
    strays = {m for m in loaded for other in INDEPENDENT[package]
              if m == f"deltafmi.master.{other}" or m.startswith(f"deltafmi.master.{other}.")}
    assert not strays, f"importing deltafmi.master.{package} imports {sorted(strays)}"


def test_no_module_is_left_flat_in_cosim():
    flat = sorted(p.name for p in COSIM.glob("*.py"))
    assert flat == ["__init__.py", "simulate.py"]  # the API's entry point (the commands are deltafmi.apps')
    assert not list(COSIM.glob("*.json")) and not (COSIM / "native").exists()


def test_import_deltafmi_imports_nothing_else():
    """deltafmi/__init__.py is bundled into every FMU: importing it must cost nothing."""
    code = "import sys\nbefore = set(sys.modules)\nimport deltafmi\nprint(sorted(set(sys.modules) - before))"
    added = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert added.strip() == "['deltafmi']"


def test_every_public_name_resolves_to_its_module():
    names = deltafmi.__all__
    assert {"load_scenario", "Scenario", "resolve_system", "Master", "build_fmu", "sweep_study",
            "linearize_fmu", "export_ssp", "ScenarioError"} <= set(names)
    # one public name per job: read_result reads every format, sweep_study runs a study
    assert not {"read_csv", "run_study"} & set(names)
    for name in names:
        value = getattr(deltafmi, name)
        assert value.__module__ == deltafmi._API[name] and value.__name__ == name, name
        assert name in dir(deltafmi)
    from deltafmi.master.stepping.master import Master
    assert deltafmi.Master is Master
    with pytest.raises(AttributeError, match="has no attribute 'Mastr'"):
        deltafmi.Mastr  # noqa: B018


def test_the_robot_fmus_declare_the_same_robot_parameters(build_fmu_from_src):
    """DeltaRobot, DeltaRobotContact and DeltaRobotBox: one declaration of the 13 robot
    parameters (deltafmi.models.robot_parameters), the same names, types, units, defaults, bounds,
    descriptions and variability in all three modelDescriptions, first among their parameters."""
    from deltafmi.models.robot_parameters import DECLARATIONS

    def robot_parameters(source: str) -> list:
        md = read_model_description(str(build_fmu_from_src(source)))
        parameters = [v for v in md.modelVariables if v.causality == "parameter"]
        return [(v.name, v.type, v.unit, v.start, v.min, v.max, v.description, v.variability)
                for v in parameters[:len(DECLARATIONS)]]

    robot = robot_parameters("delta_robot.py")
    assert [p[0] for p in robot] == list(DECLARATIONS)
    assert robot_parameters("delta_robot_contact.py") == robot_parameters("delta_robot_box.py") == robot


def test_the_import_contracts_hold_and_no_module_imports_itself():
    """tools/lint_imports.py: import-linter's contracts of pyproject.toml (the layers, the runtime's
    standard library and numpy, the physics and the models on their own, no cycles between
    siblings) and no cycle among modules at all, imports inside functions counted."""
    run = subprocess.run([sys.executable, str(ROOT / "tools" / "lint_imports.py")], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    assert "Contracts: 5 kept, 0 broken." in run.stdout
    assert "\n0 import cycle(s) among " in run.stdout


def test_the_layers_are_the_packages_the_design_names():
    package = Path(deltafmi.__file__).parent
    assert sorted(p.name for p in package.iterdir() if (p / "__init__.py").is_file()) == \
        ["apps", "builder", "component", "master", "physics", "runtime"]
    assert sorted(p.name for p in package.glob("*.py")) == ["__init__.py", "errors.py", "files.py", "shipped.py",
                                                            "toolchain.py"]
    assert (ROOT / "fmu_src" / "delta_robot.py").is_file() and (ROOT / "scenarios" / "delta_tracking.yaml").is_file()
    assert Path(deltafmi.models.__file__).parent == ROOT / "fmu_src"
