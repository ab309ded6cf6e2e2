"""The command line imports what a command uses and nothing more: ``deltafmi --help`` lists every
command without importing one, and a cached run imports neither scipy, nor the builder, nor the
commands it does not run."""
from __future__ import annotations

import importlib
import inspect
import json
import os
import subprocess
import sys

import click
from click.testing import CliRunner

from deltafmi.apps.cli import COMMANDS, main

#: what a child prints: the modules loaded after running the command given (``standalone_mode``
#: off: the command returns instead of exiting)
_PROBE = """
import json, sys
from deltafmi.apps.cli import main
main(sys.argv[1:], standalone_mode=False)
print(json.dumps(sorted(sys.modules)), file=sys.__stderr__)
registry = sys.modules.get("_deltafmi_fmu_registry")
loaded = registry.loaded.values() if registry is not None else ()
# the FMUs' own module objects: their FmuInstance classes, one per copy of the runtime imported
print(json.dumps(len({id(entry[2]) for entry in loaded})) + " runtime copies of " + str(len(loaded)), file=sys.__stderr__)
"""


def loaded_by(*argv: str) -> set[str]:
    """The modules loaded in a fresh interpreter by ``deltafmi ARGV``."""
    done = subprocess.run([sys.executable, "-c", _PROBE, *argv], capture_output=True, text=True,
                          env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}, timeout=600)
    assert done.returncode == 0, done.stderr
    return set(json.loads(done.stderr.strip().splitlines()[-2]))


def runtime_copies(*argv: str) -> tuple[int, int]:
    """(runtime copies imported, FMUs loaded) in a fresh interpreter by ``deltafmi ARGV``."""
    done = subprocess.run([sys.executable, "-c", _PROBE, *argv], capture_output=True, text=True,
                          env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}, timeout=600)
    assert done.returncode == 0, done.stderr
    copies, *_, fmus = done.stderr.strip().splitlines()[-1].split()
    return int(copies), int(fmus)


def test_each_listed_help_is_the_commands_own_first_paragraph():
    for name, (module, attribute, text) in COMMANDS.items():
        command = getattr(importlib.import_module(module), attribute)
        assert isinstance(command, click.Command) and command.name == name
        assert text == inspect.cleandoc(command.help).split("\n\n")[0].replace("\n", " "), name


def test_help_lists_every_command_as_click_would():
    shown = CliRunner().invoke(main, ["--help"]).output
    listed = [line.split()[0] for line in shown.split("Commands:")[1].splitlines() if line.strip()]
    assert listed == sorted(COMMANDS)
    for name, (module, attribute, _) in COMMANDS.items():
        command = getattr(importlib.import_module(module), attribute)
        row = next(line for line in shown.splitlines() if line.strip().startswith(name + " "))
        assert row.split(None, 1)[1] == command.get_short_help_str(limit=80 - 6 - max(map(len, COMMANDS)))


def test_an_unknown_command_is_bad_input():
    result = CliRunner().invoke(main, ["rnu"])
    assert result.exit_code == 2 and "No such command 'rnu'" in result.output


def test_help_imports_no_command_and_not_numpy():
    loaded = loaded_by("--help")
    assert not {module for module, _, _ in COMMANDS.values()} & loaded
    assert "numpy" not in loaded and "deltafmi.runtime" not in loaded


def test_examples_imports_neither_numpy_nor_the_master():
    loaded = loaded_by("examples")
    assert "numpy" not in loaded and "yaml" in loaded
    assert not [m for m in loaded if m.startswith(("deltafmi.master.stepping.", "deltafmi.master.scenario."))
                and m not in ("deltafmi.master.stepping.stop_signals", "deltafmi.master.scenario.fmu_source")]


def test_a_cached_run_imports_only_what_it_uses(tmp_path):
    argv = ("run", "delta_tracking", "-q", "--stop", "0.01", "-o", str(tmp_path / "r.csv"))
    loaded_by(*argv)  # builds (or finds) the FMUs, records their stamps, validates the scenario once
    loaded = loaded_by(*argv)
    unused = ["scipy", "dask", "distributed", "matplotlib", "jsonschema", "deltafmi.apps.compat",
              "deltafmi.apps.studies", "deltafmi.builder.packager", "deltafmi.builder.codegen",
              "deltafmi.models.delta_robot", "yaml", "concurrent.futures",  # a scenario parsed before: no YAML
              "deltafmi.runtime.cvode", "deltafmi.runtime.sundials"]  # the robot's ME unit runs on RK4, not CVODE
    assert [name for name in unused if name in loaded] == []
    assert "deltafmi.master.stepping.master" in loaded


def test_the_fmus_of_a_run_import_one_runtime(tmp_path):
    """The flagship's three FMUs, built by this deltafmi, carry byte-identical runtime modules:
    the first FMU imports them, the others get the same module objects (boot.py's module pool)."""
    argv = ("run", "delta_tracking", "-q", "--stop", "0.01", "-o", str(tmp_path / "r.csv"))
    loaded_by(*argv)  # builds (or finds) the FMUs
    assert runtime_copies(*argv) == (1, 3)
