"""CLI commands ``deltafmi build`` and ``deltafmi info``, and ``deltafmi validate`` of one FMU."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Optional

import click

from deltafmi.errors import BadInput

from deltafmi.builder.packager import ComponentSourceError, build_fmu
from deltafmi.builder.requirements import runtime_requirement
from deltafmi.apps.console import output_folders

__all__ = ["build", "info", "validate_fmu_file"]


@click.command()
@click.argument("sources", nargs=-1)
@click.option("-o", "--output", type=click.Path(), callback=output_folders,
              help="Output .fmu file, or a directory (existing, or ending in '/') that gets <Model>.fmu; "
                   "always a directory with several sources or --all.")
@click.option("--all", "build_all", is_flag=True, help="Build every packaged model (deltafmi.models).")
@click.option("--validate/--no-validate", default=True, show_default=True,
              help="Check each FMU's modelDescription.xml with fmpy.")
@click.option("--portable", is_flag=True,
              help="Bundle the interpreter, standard library and packages the model imports, so that the FMU "
                   "runs on a Linux x86_64 machine with no Python (glibc no older than this one's).")
@click.option("--fmi-version", type=click.Choice(["2", "3"]), default="2", show_default=True,
              help="FMI version of the FMUs: 2 (FMI 2.0) or 3 (FMI 3.0, array variables).")
@click.option("--resource", "resources", multiple=True, type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="A file to copy into the FMU's resources/ folder, where its component reads it "
                   "(self.resources_dir); repeatable.")
def build(sources: tuple[str, ...], output: Optional[str], build_all: bool, validate: bool, portable: bool,
          fmi_version: str, resources: tuple[Path, ...]) -> None:
    """Build FMUs (Model Exchange + Co-Simulation) from components.

    Each of SOURCES is a packaged model's class name (DeltaRobot), a component source file
    (my_plant.py, or my_plant.py:MyPlant when it defines several) or a class in an importable
    module (package.module:Class).

    \b
    Examples:
      deltafmi build DeltaRobot -o DeltaRobot.fmu
      deltafmi build my_plant.py -o build/fmus/
      deltafmi build --all -o build/fmus
      deltafmi build --all --fmi-version 3 -o build/fmus3/
      deltafmi build DeltaRobot --portable -o DeltaRobot.fmu
      deltafmi build MpcController --resource mpc_press_model.npz -o MpcController.fmu
    """
    from deltafmi.builder.sources import find_component, packaged_model_names

    if build_all:
        sources = tuple(packaged_model_names())
    if not sources:
        raise click.UsageError("give a component (a packaged model's class name, a .py file) or --all")
    # a directory when it exists or its text ends in '/' (pathlib drops that '/')
    to_directory = output is not None and (len(sources) > 1 or build_all or Path(output).is_dir()
                                           or output.endswith(("/", os.sep)))
    folder = Path(output) if to_directory else None
    from deltafmi.master.results.safe_file import check_writable
    if folder is not None and folder.exists() and not folder.is_dir():
        raise BadInput(f"-o {output}: building {'every packaged model' if build_all else 'several components'} "
                       f"writes one FMU each into a folder, and {output} is a file")
    if output is not None:
        check_writable(folder / "Model.fmu" if folder is not None else Path(output), "FMU file")
    for text in sources:
        source = find_component(text)
        target = folder / f"{source.path.stem}.fmu.tmp" if folder else (Path(output) if output else None)
        path = build_fmu(source.path, target, portable=portable, class_name=source.class_name,
                         fmi_version=int(fmi_version), resources=resources)
        if folder:  # name the FMU after its model identifier
            final = folder / _model_identifier(path)
            path.replace(final)
            path = final
        if validate:
            from fmpy.validation import validate_fmu
            problems = validate_fmu(str(path))
            if problems:
                raise click.ClickException(f"{path}: fmpy validate found problems:\n" + "\n".join(problems))
        click.echo(f"built {path}" + (f" (portable, {path.stat().st_size / 1e6:.1f} MB)" if portable else ""))


def _model_identifier(fmu: Path) -> str:
    from fmpy import read_model_description
    return f"{read_model_description(str(fmu)).coSimulation.modelIdentifier}.fmu"


@click.command()
@click.argument("target")
def info(target: str) -> None:
    """Show an FMU's interfaces, default experiment and variables.

    TARGET is an .fmu file, or a component as ``deltafmi build`` takes it (a packaged model's class
    name, a source .py): its FMU from the build cache.

    \b
    Examples:
      deltafmi info build/fmus/DeltaRobot.fmu
      deltafmi info DeltaRobot
    """
    fmu = _fmu_of(target)
    md = _readable(fmu).md
    interfaces = [name for name, present in (("Model Exchange", md.modelExchange), ("Co-Simulation", md.coSimulation),
                                             ("Scheduled Execution", getattr(md, "scheduledExecution", None)))
                  if present]
    click.echo(f"{md.modelName}  (FMI {md.fmiVersion}, {', '.join(interfaces)})")
    if md.description:
        click.echo(f"  {md.description}")
    click.echo(f"  generated by {md.generationTool}, GUID {md.guid}")
    click.echo(f"  continuous states: {md.numberOfContinuousStates}, event indicators: {md.numberOfEventIndicators}")
    for line in runtime_requirement(fmu).describe():
        click.echo(f"  {line}")
    exp = md.defaultExperiment
    if exp:
        click.echo(f"  default experiment: start {exp.startTime}, stop {exp.stopTime}, "
                   f"step {exp.stepSize}, tolerance {exp.tolerance}")
    clocks = _clocks(fmu)
    if clocks:
        click.echo(f"  clocks: {', '.join(clocks)}")
    kernels, functions = _compiled_kernels(fmu)
    if kernels:
        click.echo(f"  compiled kernels (C, no Python between events): {', '.join(kernels)}")
    if functions:
        click.echo(f"  compiled functions (C its Python calls): {', '.join(functions)}")
    rows = [(v.name, v.causality, v.variability, _type_text(v), "" if v.start is None else str(v.start),
             v.unit or (v.declaredType.unit if v.declaredType else "") or "", v.description or "")
            for v in md.modelVariables
            if v.type != "Clock" and (v.causality in ("parameter", "input", "output") or v.derivative is None)]
    header = ("name", "causality", "variability", "type", "start", "unit", "description")
    widths = [max(len(header[i]), *(len(r[i]) for r in rows)) if rows else len(header[i]) for i in range(6)]
    click.echo("")
    click.echo("  ".join(h.ljust(w) for h, w in zip(header[:6], widths)) + "  " + header[6])
    click.echo("  ".join("-" * w for w in widths) + "  " + "-" * 11)
    for row in rows:
        click.echo("  ".join(c.ljust(w) for c, w in zip(row[:6], widths)) + "  " + row[6])


def _type_text(variable: Any) -> str:
    """A variable's type, with its shape if it is an FMI 3.0 array: ``Float64[3]``, ``Float64[2,3]``."""
    if not variable.dimensions:
        return variable.type
    return f"{variable.type}[{','.join(str(n) for n in variable.shape)}]"


def _clocks(fmu: Path) -> list:
    """The FMI 3.0 Clocks of ``fmu``, each as ``name (causality, intervalVariability, interval ...)``
    (read from the XML: fmpy keeps no interval)."""
    import xml.etree.ElementTree as ET
    import zipfile
    with zipfile.ZipFile(fmu) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
    found = []
    for clock in root.iterfind("ModelVariables/Clock"):
        details = [clock.get("causality", "local"), clock.get("intervalVariability", "")]
        for attribute, label in (("intervalDecimal", "interval"), ("shiftDecimal", "shift")):
            if clock.get(attribute) is not None:
                details.append(f"{label} {float(clock.get(attribute)):g} s")
        found.append(f"{clock.get('name')} ({', '.join(d for d in details if d)})")
    return found


def _compiled_kernels(fmu: Path) -> tuple[list, list]:
    """The roles of the compiled kernels ``fmu`` carries (deltafmi.runtime.native_kernels) and the
    names of its compiled functions (deltafmi.runtime.native_functions)."""
    import json
    import zipfile

    from deltafmi.runtime.native_kernels import DESCRIPTION
    with zipfile.ZipFile(fmu) as archive:
        if f"resources/{DESCRIPTION}" not in archive.namelist():
            return [], []
        description = json.loads(archive.read(f"resources/{DESCRIPTION}"))
    return [role.replace("_", " ") for role in description["kernels"]], list(description.get("functions", {}))


def _fmu_of(target: str) -> Path:
    """The .fmu file ``target`` names, or the cached FMU of the component it names."""
    path = Path(target)
    if path.is_file() and path.suffix.lower() != ".py":
        return path
    if path.is_dir():
        raise BadInput(f"{target}: a folder, not an FMU file (an FMU is one .fmu file, a zip archive)")
    if path.suffix.lower() == ".fmu":
        raise BadInput(f"{target}: no such FMU file")
    from deltafmi.builder.packager import build_cached
    from deltafmi.builder.sources import find_component
    try:
        source = find_component(target)
        return build_cached(source.path, class_name=source.class_name)
    except ComponentSourceError as exc:
        raise BadInput(f"{exc}; info takes an .fmu file or a component "
                       "(`deltafmi build DeltaRobot -o DeltaRobot.fmu` writes one)") from None


def _readable(fmu: Path) -> Any:
    """The FMU's :class:`~deltafmi.master.scenario.modelinfo.ModelInfo`; :class:`BadInput` (exit 2,
    as ``run`` says it) when the file is not an FMU deltafmi can read."""
    from deltafmi.master.scenario.modelinfo import model_info
    try:
        return model_info(str(fmu))
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions for broken archives
        raise BadInput(f"{fmu}: cannot read it as an FMU: {exc}") from None


def validate_fmu_file(fmu: Path) -> None:
    """``deltafmi validate X.fmu``: fmpy's validation (the XML), the binary for this platform, a
    deltafmi FMU's GUID against its binary's, what the FMU needs to run and whether this machine
    has it, and one trial fmi2Instantiate; a ClickException (exit 1) at the first that fails
    (:class:`BadInput`, exit 2, for a file that is not an FMU, as ``run`` and ``info`` say it)."""
    from deltafmi.master.scenario.fmu_checks import binary_problem, guid_problem, validation_problems
    from deltafmi.master.stepping.fmu_trial import instantiation_problem
    if fmu.is_dir():
        raise BadInput(f"{fmu}: a folder, not an FMU file (an FMU is one .fmu file, a zip archive)")
    if not fmu.is_file():
        raise BadInput(f"{fmu}: no such FMU file")
    md = _readable(fmu).md
    try:
        problems = validation_problems(fmu)
        requirement = runtime_requirement(fmu)
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions for broken archives
        raise BadInput(f"{fmu}: cannot read it as an FMU: {exc}") from None
    for line in requirement.describe():
        click.echo(f"{fmu}: {line}")
    if problems:
        raise click.ClickException(f"{fmu}: fmpy validate found problems:\n" + "\n".join(problems))
    identifiers = [i.modelIdentifier for i in (md.coSimulation, md.modelExchange) if i is not None]
    problem = binary_problem(fmu, identifiers, md.fmiVersion.startswith("3")) or guid_problem(fmu, md.guid)
    if problem:
        raise click.ClickException(f"{fmu}: {problem}")
    if not requirement.runs_here:
        raise click.ClickException(f"{fmu}: valid, but it cannot start on this machine")
    problem = instantiation_problem(fmu)
    if problem:
        raise click.ClickException(f"{fmu}: {problem}")
    click.echo(f"{fmu}: OK (instantiated and freed once)")
