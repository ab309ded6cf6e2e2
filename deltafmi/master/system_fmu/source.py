"""Write what a scenario exported as one FMU is built from: the component source (a
:class:`~deltafmi.master.system_fmu.inside.SystemComponent` declaring the exported variables) and
the files its ``resources/`` carries: the scenario, each component given by its FMU, and those FMUs.
"""
from __future__ import annotations

import re
import shutil
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple

import yaml

from deltafmi.errors import BadInput
from deltafmi.shipped import is_shipped

from ..scenario.system import Port, ResolvedComponent, System
from .inside import SystemComponent

__all__ = ["exportable", "write_system"]

#: keys of a scenario component that say where its FMU comes from: the FMU carried replaces them
_WHERE_FROM = ("fmu", "source", "fmi_version", "resources")
#: what a scenario says that a run inside an FMU has no use for (results, live I/O, the export itself)
_OUTSIDE_ONLY = ("result", "live", "streams", "exports", "fmi_version")
_PYTHON_TYPES = {"Real": "float", "Integer": "int", "Boolean": "bool"}


def exportable(system: System) -> Optional[str]:
    """Why ``system`` cannot be exported as one FMU, or None."""
    scenario = system.scenario
    if scenario.path.suffix.lower() not in (".yaml", ".yml"):
        return f"{scenario.path}: export-fmu takes a YAML scenario (run an SSP or an FMU as it is)"
    if system.live or scenario.live or scenario.streams:
        return f"{scenario.path}: a scenario with live sources or streams runs only under deltafmi run"
    if scenario.master.adaptive.enabled:
        return (f"{scenario.path}: master.adaptive: a scenario exported as one FMU steps on the fixed grid of its "
                "experiment.step")
    if scenario.master.realtime.enabled:
        return f"{scenario.path}: master.realtime: an exported scenario runs at its importer's pace"
    return None


def write_system(system: System, folder: Path, class_name: str) -> Tuple[Path, List[Path]]:
    """Write the component source of ``system`` as one FMU into ``folder`` and the files its
    resources carry; returns (source, resources). Raises :class:`BadInput` when the scenario
    cannot be exported (:func:`exportable`)."""
    why = exportable(system)
    if why:
        raise BadInput(why)
    if not class_name.isidentifier():
        raise BadInput(f"'{class_name}' cannot name the FMU's model: use letters, digits and _")
    folder.mkdir(parents=True, exist_ok=True)
    data = yaml.safe_load(system.scenario.path.read_text(encoding="utf-8"))
    resources = [folder / SystemComponent.scenario_file]
    for component in system.components:
        carried = folder / f"{component.name}.fmu"
        shutil.copyfile(component.fmu, carried)
        resources.append(carried)
        spec = {k: v for k, v in (data["components"][component.name] or {}).items() if k not in _WHERE_FROM}
        data["components"][component.name] = {"fmu": carried.name, **spec}
    for key in _OUTSIDE_ONLY:
        data.pop(key, None)
    (data.get("master") or {}).pop("realtime", None)
    resources[0].write_text(f"# {system.scenario.path.name} as carried by the FMU built with deltafmi export-fmu\n"
                            + yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    source = folder / f"{class_name.lower()}_system.py"
    source.write_text(_component_source(system, class_name), encoding="utf-8")
    return source, resources


def _component_source(system: System, class_name: str) -> str:
    scenario = system.scenario
    by_name = {c.name: c for c in system.components}
    experiment = scenario.experiment
    tolerance = f", tolerance={experiment.tolerance!r}" if experiment.tolerance is not None else ""
    description = " ".join((scenario.description or f"The scenario {scenario.path.name}").split())
    # what export-fmu takes to build it again: a shipped example by its name, from any folder
    named = scenario.path.stem if is_shipped(scenario.path) else scenario.path.name
    lines = [
        f'"""{named} exported as one Co-Simulation FMU by deltafmi export-fmu."""',
        "from deltafmi.component import Experiment, Input, Output, Parameter",
        "from deltafmi.master.system_fmu.inside import SystemComponent",
        "",
        "",
        f"class {class_name}(SystemComponent):",
        f"    {_quoted_doc(description)}",
        "",
        f"    default_experiment = Experiment(start={experiment.start!r}, stop={experiment.stop!r}, "
        f"step={experiment.step!r}{tolerance})",
    ]
    tables: Dict[str, List[Tuple[str, str]]] = {"outputs": [], "inputs": [], "parameters": []}
    starts = {port.ref: value for c in system.components for port, value in c.start_values}
    index = 0
    for kind, declaration, ports in (("outputs", "Output", system.interface.outputs),
                                     ("inputs", "Input", system.interface.inputs),
                                     ("parameters", "Parameter", system.interface.parameters)):
        for port in ports:
            attribute = f"v{index}_{re.sub(r'[^0-9A-Za-z_]', '_', port.ref)}"
            index += 1
            tables[kind].append((attribute, port.ref))
            lines.append(f"    {attribute} = {declaration}({_arguments(by_name[port.component], port, starts, kind)})")
    for kind, rows in tables.items():
        lines.append(f"    {kind}_exported = (" + "".join(f"({a!r}, {r!r}), " for a, r in rows) + ")")
    return "\n".join(lines) + "\n"


def _arguments(component: ResolvedComponent, port: Port, starts: Dict[str, Any], kind: str) -> str:
    var = component.info.variables[port.name]
    python_type = _PYTHON_TYPES[port.type]
    start = starts.get(port.ref, var.start)
    if kind == "outputs":
        start = None
    arguments = [] if start is None else [repr(_typed(start, python_type))]
    arguments.append(f"type={python_type}")
    arguments.append(f"name={port.ref!r}")
    if port.unit and port.type == "Real":
        arguments.append(f"unit={port.unit!r}")
    text = f"{port.component}: {var.description}" if var.description else port.ref
    arguments.append(f"description={text!r}")
    if kind == "parameters":
        for bound in ("min", "max"):
            value = getattr(var, bound)
            if value is not None and port.type != "Boolean":
                arguments.append(f"{bound}={_typed(value, python_type)!r}")
    return ", ".join(arguments)


def _typed(value: Any, python_type: str) -> Any:
    if python_type == "bool":
        return value if isinstance(value, bool) else str(value).strip().lower() in ("true", "1")
    if python_type == "int":
        return int(value)
    return float(value)


def _quoted_doc(text: str) -> str:
    return '"""' + text.replace("\\", "\\\\").replace('"""', "'''") + '"""'
