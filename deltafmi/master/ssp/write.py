"""Write a resolved scenario as an SSP 1.0 archive (``deltafmi export-ssp``).

The archive holds ``SystemStructure.ssd`` and every FMU under ``resources/`` (components given
by ``source:`` are the FMUs the build cache made for them). The SSD has one component per
scenario component (``implementation`` from its interface), the connected variables as
connectors, one scalar connection per connected variable (``ssc:LinearTransformation`` when
the connection has a factor or offset), the start values as an inline ``ssv:ParameterSet``,
and the start and stop time as ``DefaultExperiment``. Everything else a scenario says goes
into ``com.deltafmi`` annotations (see :mod:`.format`), so reading the archive back
(:mod:`.read`) gives a scenario that runs to the same samples. FMI 3.0 components go in as they
are; SSP 1.0 connectors are scalar, so an FMI 3.0 array's connected elements are connectors
``q[1]``, ``q[2]``, ... and its 64-bit integers are ``ssc:Integer``.
"""
from __future__ import annotations

import datetime
import hashlib
import math
import os
import zipfile
from dataclasses import asdict
from pathlib import Path
from typing import Any, Dict, Iterable, List, Tuple

from lxml import etree

import deltafmi
from deltafmi.files import replaced_atomically

from ..scenario.system import ResolvedComponent, Port, System
from ..scenario.spec import Adaptive, Scenario
from .format import (ANNOTATION_TYPE, FMU_MIME_TYPE, NAMESPACES, OSP_ANNOTATION_TYPE, SSD_NAME,
                         tag)

__all__ = ["export_ssp"]

#: name of the parameter set of every component (Ecos applies parameter sets by name)
PARAMETER_SET_NAME = "start values"


def export_ssp(system: System, output: Path) -> Path:
    """Write ``system`` as the SSP archive ``output`` (replaced atomically); returns its path."""
    from ..scenario.live_components import refuse_live

    refuse_live(system, "an SSP archive")
    output = Path(output)
    sources = _archive_names(system.components)
    ssd = etree.tostring(ssd_tree(system, sources), xml_declaration=True, encoding="UTF-8",
                         pretty_print=True)
    with replaced_atomically(output) as tmp:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr(SSD_NAME, ssd)
            for path, name in sorted(set(sources.values()), key=lambda item: item[1]):
                # an FMU is a zip already: store it
                archive.write(path, name, compress_type=zipfile.ZIP_STORED)
    return output


def ssd_tree(system: System, sources: Dict[str, Tuple[Path, str]]) -> etree._Element:
    """The ``SystemStructureDescription`` element; ``sources`` maps a component name to its
    FMU file and that file's name in the archive."""
    scenario = system.scenario
    name, _ = _origin(scenario)
    root = etree.Element(tag("ssd", "SystemStructureDescription"), nsmap=NAMESPACES)
    root.set("version", "1.0")
    root.set("name", name)
    root.set("generationTool", f"deltafmi {deltafmi.__version__}")
    root.set("generationDateAndTime",
             datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z"))
    sys_element = _sub(root, "ssd", "System", name=name)
    if scenario.description:
        sys_element.set("description", scenario.description)
    elements = _sub(sys_element, "ssd", "Elements")
    for component in system.components:
        _component(elements, component, sources[component.name][1], system)
    if system.links:
        connections = _sub(sys_element, "ssd", "Connections")
        for link in system.links:
            connection = _sub(connections, "ssd", "Connection",
                              startElement=link.source.component, startConnector=link.source.name,
                              endElement=link.target.component, endConnector=link.target.name)
            converts = link.source.unit and link.target.unit and link.source.unit != link.target.unit
            if link.factor != 1.0 or link.offset != 0.0 or converts:  # a unit change is a deliberate conversion
                # both attributes always: Ecos reads a missing one as 0
                _sub(connection, "ssc", "LinearTransformation", factor=_real(link.factor), offset=_real(link.offset))
    enumerations = _enumerations(system)
    if enumerations:
        element = _sub(root, "ssd", "Enumerations")
        for name, items in enumerations.items():
            enumeration = _sub(element, "ssc", "Enumeration", name=name)
            for item, value in items.items():
                _sub(enumeration, "ssc", "Item", name=item, value=str(value))
    _default_experiment(root, system)
    _results(root, system)
    return root


def _component(parent: etree._Element, component: ResolvedComponent, source: str, system: System) -> None:
    spec = component.spec
    element = _sub(parent, "ssd", "Component", name=component.name, type=FMU_MIME_TYPE, source=source,
                   implementation="ModelExchange" if component.interface == "ME" else "CoSimulation")
    ports = _connected_ports(component, system)
    if ports:
        connectors = _sub(element, "ssd", "Connectors")
        for port, kind in ports:
            connector = _sub(connectors, "ssd", "Connector", name=port.name, kind=kind)
            if port.enumeration:
                _sub(connector, "ssc", "Enumeration", name=port.enumeration)
            else:
                _sub(connector, "ssc", _SSC_TYPES.get(port.type, port.type))
    if component.start_values:
        binding = _sub(_sub(element, "ssd", "ParameterBindings"), "ssd", "ParameterBinding")
        parameter_set = _sub(_sub(binding, "ssd", "ParameterValues"), "ssv", "ParameterSet",
                             version="1.0", name=PARAMETER_SET_NAME)
        parameters = _sub(parameter_set, "ssv", "Parameters")
        for port, value in component.start_values:
            kind, text = _parameter_value(component, port, value)
            _sub(_sub(parameters, "ssv", "Parameter", name=port.name), "ssv", kind, value=text)
    annotations: List[Tuple[str, etree._Element]] = []
    if spec.step_multiple != 1 or spec.solver:
        ours = etree.Element(tag("dfmi", "Component"))
        if spec.step_multiple != 1:
            ours.set("step_multiple", str(spec.step_multiple))
        if spec.solver:
            _sub(ours, "dfmi", "Solver", **{key: _text(value) for key, value in spec.solver.items()})
        annotations.append((ANNOTATION_TYPE, ours))
    if spec.step_multiple != 1:  # libcosim steps the component every step_multiple base steps
        hint = etree.Element(tag("osp", "StepSizeHint"),
                             value=_real(spec.step_multiple * system.scenario.experiment.step))
        annotations.append((OSP_ANNOTATION_TYPE, hint))
    _annotations(element, annotations)


def _connected_ports(component: ResolvedComponent, system: System) -> List[Tuple[Port, str]]:
    """The component's connected variables with their connector kind, in modelDescription order."""
    found: Dict[str, Tuple[Port, str]] = {}
    for link in system.links:
        if link.source.component == component.name:
            found.setdefault(link.source.name, (link.source, "output"))
        if link.target.component == component.name:
            found.setdefault(link.target.name, (link.target, "input"))
    order = {name: i for i, name in enumerate(component.info.variables)}  # FMI 3.0 arrays: their elements
    return sorted(found.values(), key=lambda item: order[item[0].name])


#: the SSP 1.0 type of each bus: FMI 3.0's wide integers are SSP Integers (SSP 1.0 knows no others)
_SSC_TYPES = {"Int64": "Integer", "UInt64": "Integer"}


def _parameter_value(component: ResolvedComponent, port: Port, value: Any) -> Tuple[str, str]:
    """(ssv element name, value text) of a start value."""
    enumeration = component.info.enumeration(port.name)
    if enumeration is not None:  # SSV names the item
        return "Enumeration", {number: item for item, number in enumeration[1].items()}[value]
    if port.type == "Real":
        return "Real", _real(value)
    return _SSC_TYPES.get(port.type, port.type), _text(value)


def _enumerations(system: System) -> Dict[str, Dict[str, int]]:
    """Enumeration types of the connected variables (the types ssc:Enumeration connectors name)."""
    found: Dict[str, Dict[str, int]] = {}
    by_name = {c.name: c for c in system.components}
    for link in system.links:
        for port in (link.source, link.target):
            if port.enumeration:
                enumeration = by_name[port.component].info.enumeration(port.name)
                assert enumeration is not None  # the port has an enumeration type
                found.setdefault(port.enumeration, dict(enumeration[1]))
    return found


def _default_experiment(root: etree._Element, system: System) -> None:
    scenario = system.scenario
    experiment = _sub(root, "ssd", "DefaultExperiment", startTime=_real(scenario.experiment.start),
                      stopTime=_real(scenario.experiment.stop))
    master = etree.Element(tag("dfmi", "Master"), step=_real(scenario.experiment.step),
                           algorithm=scenario.master.algorithm)
    if scenario.master.allow_nan:
        master.set("allow_nan", "true")
    adaptive = scenario.master.adaptive
    if adaptive != Adaptive():
        _sub(master, "dfmi", "Adaptive",
             **{key: _text(value) for key, value in asdict(adaptive).items() if value is not None})
    osp = etree.Element(tag("osp", "Algorithm"))
    _sub(osp, "osp", "FixedStepAlgorithm", baseStepSize=_real(scenario.experiment.step))
    _annotations(experiment, [(ANNOTATION_TYPE, master), (OSP_ANNOTATION_TYPE, osp)])


def _results(root: etree._Element, system: System) -> None:
    """What to record and where: the scenario's ``outputs`` patterns and ``result`` settings."""
    scenario = system.scenario
    name, folder = _origin(scenario)
    result = scenario.result
    ours = etree.Element(tag("dfmi", "Results"), every=str(result.every), format=result.format)
    if result.file != Path(name + ".csv"):  # not the default: keep it, relative
        ours.set("file", Path(os.path.relpath(result.file, folder)).as_posix())
    for output in scenario.outputs:
        _sub(ours, "dfmi", "Record", pattern=output.pattern)
    _annotations(root, [(ANNOTATION_TYPE, ours)])


def _origin(scenario: Scenario) -> Tuple[str, Path]:
    """Name and folder of the scenario's file: for one read from an SSP archive, the archive's
    (its path is ``<archive>/SystemStructure.ssd``), as the reader resolves the result file."""
    path = scenario.path
    if path.name == SSD_NAME and path.parent.suffix.lower() == ".ssp":
        path = path.parent
    return path.stem, path.parent


def _annotations(parent: etree._Element, annotations: Iterable[Tuple[str, etree._Element]]) -> None:
    """``ssd:Annotations`` with one ``ssc:Annotation`` (one child each, as SSP 1.0 allows) per item."""
    annotations = list(annotations)
    if annotations:
        element = _sub(parent, "ssd", "Annotations")
        for kind, content in annotations:
            _sub(element, "ssc", "Annotation", type=kind).append(content)


def _archive_names(components: List[ResolvedComponent]) -> Dict[str, Tuple[Path, str]]:
    """Component name -> (FMU file, ``resources/<name>.fmu``); one archive entry per distinct FMU."""
    by_digest: Dict[str, str] = {}
    taken: set = set()
    names: Dict[str, Tuple[Path, str]] = {}
    for component in components:
        digest = hashlib.sha256(component.fmu.read_bytes()).hexdigest()
        if digest not in by_digest:
            stem, name, n = component.fmu.stem, f"resources/{component.fmu.name}", 1
            while name in taken:
                n += 1
                name = f"resources/{stem}_{n}.fmu"
            taken.add(name)
            by_digest[digest] = name
        names[component.name] = (component.fmu, by_digest[digest])
    return names


def _sub(parent: etree._Element, prefix: str, element: str, **attributes: str) -> etree._Element:
    return etree.SubElement(parent, tag(prefix, element), attributes)


def _real(value: Any) -> str:
    """An xs:double that reads back bit for bit (repr), INF/-INF/NaN as XML Schema spells them."""
    value = float(value)
    if math.isnan(value):
        return "NaN"
    if math.isinf(value):
        return "INF" if value > 0 else "-INF"
    return repr(value)


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return _real(value)
    return str(value)
