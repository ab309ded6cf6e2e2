"""``deltafmi export-fmu`` and :func:`export_fmu`: a scenario as one Co-Simulation FMU.

The master runs inside the FMU (:mod:`deltafmi.master.system_fmu`): each ``doStep`` is the
scenario's communication steps, with its units, connections, algorithm and loop solving as
``deltafmi run`` has them. docs/system_fmu.md says what goes inside and what each host needs.
"""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Optional

import click

from deltafmi.builder.packager import build_fmu
from deltafmi.errors import BadInput
from deltafmi.apps.console import output_folders
from deltafmi.master.results.safe_file import check_writable
from deltafmi.master.scenario.resolve import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.system_fmu.source import write_system

__all__ = ["export_fmu", "export_fmu_command"]


def export_fmu(scenario: str | Path, output: Optional[str | Path] = None, *, fmi_version: int = 2,
               portable: bool = False, model_name: Optional[str] = None) -> Path:
    """Build the scenario (a shipped example's name or a YAML file) as one Co-Simulation FMU.

    Its outputs are the scenario's recorded variables, its inputs the unconnected inputs of its
    units and its parameters those the scenario sets, each under its name in the scenario
    (``plant.z[1]``, ``plant.payload``); ``exports:`` in the YAML chooses others. The FMU carries
    its units' FMUs; ``model_name`` (default: the scenario's file name in CamelCase) is its model
    identifier; ``output`` defaults to ``<model_name>.fmu``. Returns the FMU's path.
    """
    loaded = load_scenario(scenario)
    name = model_name or "".join(part.capitalize() for part in loaded.path.stem.replace("-", "_").split("_")) \
        or "System"
    target = Path(output) if output is not None else Path(f"{name}.fmu")
    if target.suffix.lower() != ".fmu":
        raise BadInput(f"-o {target}: an FMU file's name ends in .fmu")
    check_writable(target, "FMU file")
    system = resolve_system(loaded)
    with tempfile.TemporaryDirectory(prefix="deltafmi-system-") as folder:
        source, resources = write_system(system, Path(folder), name)
        # the master imports scipy only to solve algebraic loops: a portable FMU without any does without it
        unused = () if system.loops or system.init_loops else ("scipy",)
        return build_fmu(source, target, portable=portable, class_name=name, fmi_version=fmi_version,
                         resources=resources, leave_out=unused)


@click.command("export-fmu")
@click.argument("scenario")
@click.option("-o", "--output", type=click.Path(dir_okay=False), callback=output_folders,
              help="The FMU file to write (default: <Model>.fmu in the current folder).")
@click.option("--fmi-version", type=click.Choice(["2", "3"]), default="2", show_default=True,
              help="FMI version of the system FMU (its units keep theirs).")
@click.option("--portable", is_flag=True,
              help="Bundle the interpreter and the packages the master imports (runs with no Python installed).")
@click.option("--model-name", help="Model identifier of the FMU (default: the scenario's name in CamelCase).")
@click.option("--validate/--no-validate", default=True, show_default=True,
              help="Check the FMU's modelDescription.xml with fmpy.")
def export_fmu_command(scenario: str, output: Optional[str], fmi_version: str, portable: bool,
                       model_name: Optional[str], validate: bool) -> None:
    """Export SCENARIO (a shipped example's name or a YAML file) as one Co-Simulation FMU.

    \b
    Examples:
      deltafmi export-fmu delta_tracking -o Tracking.fmu
      deltafmi export-fmu my_loop.yaml --fmi-version 3 -o MyLoop.fmu
    """
    from .build_commands import validate_fmu_file

    path = export_fmu(scenario, output, fmi_version=int(fmi_version), portable=portable, model_name=model_name)
    if validate:
        validate_fmu_file(path)
    click.echo(f"built {path}")
