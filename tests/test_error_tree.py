"""One error tree: every error class deltafmi defines derives from DeltaFmiError, which knows no
click; each carries its exit code, and the command line alone turns an error into its message."""
from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

import deltafmi
from deltafmi.apps.cli import main, report
from deltafmi.errors import BadInput, DeltaFmiError, Interrupted, ResultWriteError, ScenarioError, SimulationError

PACKAGE = Path(deltafmi.__file__).parent
#: exceptions that are not errors a caller sees: control flow inside one module, a run ending as
#: an FMU asked, and the boot code's own (it runs inside an FMU and imports nothing of deltafmi)
NOT_ERRORS = {"_Converged", "_OutOfBudget", "_TooMany", "_Twice", "Terminated", "FmuStartError"}


def _exception_classes() -> list[tuple[str, str]]:
    """(module, class) of every class in deltafmi whose bases look like an exception's."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        module = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        for node in tree.body:
            if not isinstance(node, ast.ClassDef):
                continue
            bases = [ast.unparse(b).rsplit(".", 1)[-1] for b in node.bases]
            if any(b.endswith(("Error", "Exception", "Failure", "Interrupted", "NotFound", "Input", "Behind",
                               "Joystick")) for b in bases):
                found.append((module, node.name))
    return found


def test_every_error_class_derives_from_one_base():
    classes = _exception_classes()
    names = {name for _, name in classes}
    # the twenty or so of today, under their names
    assert {"ScenarioError", "BadInput", "SimulationError", "ResultWriteError", "Interrupted",
            "ComponentSourceError", "ResourceError", "BuildError", "NoCompilerError", "CodegenError",
            "FmuFailure", "LoopFailure", "RungeKuttaError", "CvodeError", "SundialsNotFound",
            "UnknownVariable", "UnknownSignal", "YamlSyntaxError", "MalformedDatagram", "FellBehind",
            "NoJoystick"} <= names
    for module, name in classes:
        if name in NOT_ERRORS:
            continue
        cls = getattr(importlib.import_module(module), name)
        assert issubclass(cls, DeltaFmiError), f"{module}.{name}"
        assert not issubclass(cls, click.ClickException), f"{module}.{name}"
        assert cls.exit_code in (1, 2, 130), f"{module}.{name}"


def test_the_errors_keep_the_builtin_bases_callers_catch():
    from deltafmi.runtime.sundials import SundialsNotFound
    from deltafmi.master.scenario.modelinfo import UnknownVariable
    from deltafmi.master.stepping.unit_base import FmuFailure
    from deltafmi.toolchain import BuildError, NoCompilerError
    from deltafmi.builder.sources import ComponentSourceError
    assert issubclass(FmuFailure, RuntimeError) and issubclass(BuildError, RuntimeError)
    assert issubclass(ComponentSourceError, ValueError) and issubclass(UnknownVariable, LookupError)
    assert issubclass(SundialsNotFound, ImportError) and issubclass(NoCompilerError, BuildError)
    assert deltafmi.DeltaFmiError is DeltaFmiError and "DeltaFmiError" in deltafmi.__all__


def test_the_errors_module_imports_no_click():
    code = "import sys\nimport deltafmi.errors\nprint('click' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
    assert "click" not in (PACKAGE / "errors.py").read_text()


def test_each_class_carries_its_exit_code():
    from deltafmi.toolchain import BuildError
    from deltafmi.builder.sources import ComponentSourceError
    assert BadInput.exit_code == ScenarioError.exit_code == ComponentSourceError.exit_code == 2
    assert SimulationError.exit_code == ResultWriteError.exit_code == BuildError.exit_code == 1
    assert Interrupted("stopped", 2).exit_code == 130 and Interrupted("stopped", 15).exit_code == 143
    assert Interrupted("stopped", 1).exit_code == 129 and Interrupted.exit_code == 130
    error = SimulationError("simulation failed at t = 1 s")
    assert str(error) == error.message == error.format_message() == "simulation failed at t = 1 s"
    error.message = "changed"  # simulate() rewrites a message: str() follows
    assert str(error) == "changed"


def test_the_cli_maps_every_error_in_one_place(capsys):
    from deltafmi.toolchain import BuildError
    assert report(BuildError("gcc: not found")) == 1
    assert capsys.readouterr().err == "Error: gcc: not found\n"
    assert report(Interrupted("interrupted at t = 2 s: 10 rows kept", 15)) == 143
    assert capsys.readouterr().err == "interrupted at t = 2 s: 10 rows kept\n"
    from deltafmi.errors import Diagnostic
    two = ScenarioError([Diagnostic("s.yaml", 3, "no such component 'x'"), Diagnostic("s.yaml", 5, "bad step")])
    assert report(two) == 2
    assert capsys.readouterr().err == "s.yaml:3: error: no such component 'x'\ns.yaml:5: error: bad step\n"


@pytest.mark.parametrize("args, code, text", [
    (["run", "no_such.yaml"], 2, "no_such.yaml"),
    (["build", "NoSuchModel"], 2, "Error: "),
    (["linearize", "deltafmi.models:NoSuch"], 2, "Error: "),
])
def test_commands_exit_with_the_error_s_code_and_one_line(args, code, text):
    result = CliRunner().invoke(main, args)
    assert result.exit_code == code, result.output
    assert text in result.output and "Traceback" not in result.output
    assert not isinstance(result.exception, DeltaFmiError)  # turned into an exit, not left to escape
