"""The model library and the examples as parts of the package: examples listed, run by name from
any folder and copied to edit; packaged models built by class name and named in scenarios as
``deltafmi.models:Class``; components named as ``file.py:Class`` or ``package.module:Class``."""
from __future__ import annotations

import ast
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from fmpy import read_model_description

import deltafmi.models
from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns
from deltafmi.shipped import SCENARIOS_DIR, examples

MODELS_DIR = Path(deltafmi.models.__file__).parent


def _invoke(*args: str):
    return CliRunner().invoke(main, list(args))


def test_the_model_table_names_every_packaged_component():
    """MODELS (what `build DeltaRobot` and `deltafmi.models:X` look up) lists exactly the modules of
    deltafmi/models that define a component class, each under its class name."""
    defined = {}
    for path in MODELS_DIR.glob("*.py"):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_") \
                    and path.stem not in ("robot_parameters", "contact_plant", "circuit_parts", "delta_arm", "__init__"):
                defined[node.name] = path.stem
    assert defined == deltafmi.models.MODELS
    assert deltafmi.models.Oscillator.__module__ == "deltafmi.models.oscillator"
    with pytest.raises(AttributeError):
        deltafmi.models.NoSuchModel  # noqa: B018


def test_examples_lists_every_shipped_scenario_and_study():
    result = _invoke("examples")
    assert result.exit_code == 0, result.output
    shipped = sorted(p.stem for p in SCENARIOS_DIR.glob("*.yaml")) + sorted(p.stem for p in (SCENARIOS_DIR / "studies").glob("*.yaml"))
    assert [e.name for e in examples()] == shipped and len(shipped) == len(set(shipped)) >= 16
    for e in examples():
        line = next(line for line in result.output.splitlines() if line.split()[:1] == [e.name])
        assert len(line.split(maxsplit=1)[1]) > 10  # a one-line summary from the file's description


def test_every_shipped_scenario_names_packaged_components():
    for path in SCENARIOS_DIR.glob("*.yaml"):
        for name, component in yaml.safe_load(path.read_text())["components"].items():
            assert component["source"].startswith("deltafmi.models:"), (path.name, name)


def test_an_example_runs_by_name_from_any_folder_and_writes_here(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = _invoke("run", "delta_tracking", "--stop", "0.2", "-q")
    assert result.exit_code == 0, result.output
    by_name = columns(tmp_path / "delta_tracking.csv")
    assert by_name["time"][-1] == pytest.approx(0.2)
    # the same scenario named by its path gives the same bits
    assert _invoke("run", str(SCENARIOS_DIR / "delta_tracking.yaml"), "--stop", "0.2", "-q",
                   "-o", "by_path.csv").exit_code == 0
    by_path = columns(tmp_path / "by_path.csv")
    assert all(np.array_equal(by_name[k], by_path[k]) for k in by_name)
    # the wrist starts at rest at the first waypoint and follows it to micrometres while it dwells
    assert np.max(np.abs(by_name["plant.z[3]"] + 1.0)) < 1e-5
    assert not list(SCENARIOS_DIR.glob("*.csv"))  # nothing written into the package


@pytest.mark.parametrize("argv, message", [
    (["run", "delta_trackin"], "no example called 'delta_trackin' (did you mean 'delta_tracking'"),
    (["run", "gain_payload"], "'gain_payload' is an example study, not a scenario"),
    (["sweep", "delta_tracking", "--dry-run"], "'delta_tracking' is an example scenario, not a study"),
    (["build", "DeltaRobott"], "'DeltaRobott' is neither a file nor a packaged model (did you mean 'DeltaRobot'"),
    (["build", "deltafmi.models:Nope"], "deltafmi.models has no component class 'Nope'"),
    (["build", "no_such_module:Plant"], "cannot import no_such_module"),
    (["examples", "copy", "nope", "x"], "no example called 'nope'"),
])
def test_a_wrong_name_is_one_clear_line(tmp_path, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    result = _invoke(*argv)
    assert result.exit_code != 0 and message in result.output, result.output
    assert "Traceback" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)


_WRONG_CLASS = """
import sys
from deltafmi.builder.sources import ComponentSourceError, module_component
try:
    module_component(sys.argv[1])
except ComponentSourceError as exc:
    print(exc)
print(sorted(m for m in sys.modules if m.startswith("deltafmi.models.")))
"""


def test_a_wrong_class_of_the_packaged_models_is_named_without_importing_them(tmp_path):
    """The models are imported one by one when asked for: the message that a class is not among
    them (with the likeliest name) comes from their names alone, in a fresh process."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _WRONG_CLASS, "deltafmi.models:DeltaRobott"], capture_output=True,
                         text=True, check=True, cwd=tmp_path).stdout.splitlines()
    assert out[0] == ("'deltafmi.models:DeltaRobott': deltafmi.models has no component class 'DeltaRobott' "
                      "(did you mean 'DeltaRobot' or 'DeltaRobotBox' or 'DeltaRobotContact'?)")
    assert out[1] == "[]"


def test_build_a_packaged_model_by_class_name_or_module_reference(tmp_path):
    for argument in ("Oscillator", "deltafmi.models:Oscillator"):
        out = tmp_path / f"{argument.replace(':', '_')}.fmu"
        result = _invoke("build", argument, "-o", str(out))
        assert result.exit_code == 0, result.output
        md = read_model_description(str(out))
        assert md.modelName == "Oscillator" and md.coSimulation and md.modelExchange


def test_a_file_defining_two_components_builds_the_one_named(tmp_path):
    source = tmp_path / "two.py"
    source.write_text(textwrap.dedent('''\
        from deltafmi.component import Component, Output, Parameter

        class First(Component):
            k = Parameter(1.0)
            y = Output(unit="m")
            def outputs(self, t):
                self.y = self.k

        class Second(Component):
            k = Parameter(2.0)
            y = Output(unit="m")
            def outputs(self, t):
                self.y = 2 * self.k
        '''))
    result = _invoke("build", str(source), "-o", str(tmp_path / "x.fmu"))
    assert result.exit_code != 0 and "expected exactly one Component subclass, found First, Second" in result.output
    result = _invoke("build", f"{source}:Second", "-o", str(tmp_path / "second.fmu"))
    assert result.exit_code == 0, result.output
    assert read_model_description(str(tmp_path / "second.fmu")).modelName == "Second"


def test_a_copied_example_is_what_runs_and_edits_take_effect(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = _invoke("examples", "copy", "delta_tracking", "mine")
    assert result.exit_code == 0, result.output
    copied = {p.relative_to(tmp_path / "mine").as_posix() for p in (tmp_path / "mine").rglob("*") if p.is_file()}
    assert copied == {"delta_tracking.yaml", "models/trajectory.py", "models/delta_controller.py", "models/delta_robot.py"}
    text = (tmp_path / "mine" / "delta_tracking.yaml").read_text()
    assert "source: models/delta_robot.py" in text and "deltafmi.models:" not in text
    assert text.splitlines()[0] == (SCENARIOS_DIR / "delta_tracking.yaml").read_text().splitlines()[0]  # comments kept
    assert _invoke("examples", "copy", "delta_tracking", "mine").exit_code != 0  # never overwrites

    assert _invoke("run", "delta_tracking", "--stop", "0.1", "-q", "-o", "shipped.csv").exit_code == 0
    ran = _invoke("run", "mine/delta_tracking.yaml", "--stop", "0.1", "-o", "copy.csv")
    assert ran.exit_code == 0 and "building" not in ran.output  # unedited copies: the cached FMUs
    shipped, copy = columns(tmp_path / "shipped.csv"), columns(tmp_path / "copy.csv")
    assert all(np.array_equal(shipped[k], copy[k]) for k in shipped)

    # an edit to the copied plant (a faster Baumgarte pole) changes how the loops' residual decays
    plant = tmp_path / "mine" / "models" / "delta_robot.py"
    plant.write_text(plant.read_text().replace("pole = Parameter(5.0", "pole = Parameter(40.0", 1))
    assert _invoke("run", "mine/delta_tracking.yaml", "--stop", "0.1", "-q", "-o", "edited.csv").exit_code == 0
    edited = columns(tmp_path / "edited.csv")
    assert not np.array_equal(edited["plant.residual"], shipped["plant.residual"])
    assert np.max(np.abs(edited["plant.z[3]"] - shipped["plant.z[3]"])) < 1e-6  # same robot, same motion


def test_a_copied_study_names_its_copied_scenario(tmp_path):
    result = _invoke("examples", "copy", "gain_payload", str(tmp_path / "study"))
    assert result.exit_code == 0, result.output
    study = yaml.safe_load((tmp_path / "study" / "gain_payload.yaml").read_text())
    assert study["scenario"] == "delta_tracking.yaml" and (tmp_path / "study" / "delta_tracking.yaml").is_file()
    assert result.stdout.strip().splitlines()[-1].startswith("run it: deltafmi sweep ")


def test_a_bare_name_runs_the_copy_in_this_folder_else_the_example(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    # a folder named like the example is no error: the name is the shipped example
    assert _invoke("examples", "copy", "delta_tracking", "delta_tracking").exit_code == 0
    for command in (["run", "delta_tracking", "--stop", "0.01", "-q", "-o", "shipped.csv"],
                    ["validate", "delta_tracking"]):
        result = _invoke(*command)
        assert result.exit_code == 0, result.output
    # a copy made here (`examples copy NAME .`) is what the name means in this folder
    assert _invoke("examples", "copy", "delta_tracking", ".").exit_code == 0
    here = tmp_path / "delta_tracking.yaml"
    here.write_text(here.read_text().replace("stop: ", "stop: 0.02 #", 1))
    result = _invoke("run", "delta_tracking", "-q", "-o", "local.csv")
    assert result.exit_code == 0, result.output
    assert columns(tmp_path / "local.csv")["time"][-1] == pytest.approx(0.02)
