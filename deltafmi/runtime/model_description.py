"""Write ``modelDescription.xml`` (FMI 2.0) for a component class: both interfaces in one FMU.

What both versions share (the header, units, log categories, default experiment, the dependencies
of outputs and derivatives, the initial unknowns and the value spellings) is here too, for
:mod:`.model_description3`."""
from __future__ import annotations

import datetime
import math
import re
import xml.etree.ElementTree as ET
from typing import Iterable, Optional

from .. import __version__
from .base import Component
from .checks import feedthrough_of
from .fmu_logging import CATEGORIES, LOG_ALL
from .layout import ScalarVariable

__all__ = ["add_derivatives_annotation", "add_enumeration_items", "add_log_categories_and_experiment",
           "add_unit_definitions", "dependency_attributes", "derivative_dependencies", "enumeration_name",
           "enumeration_types", "header_attributes", "initial_unknowns", "integer_attributes", "model_description_xml",
           "output_dependencies", "real_attributes", "xml_attributes", "xml_value"]

# SI base-unit exponents for the units the project uses; others are declared without exponents.
_BASE_UNITS: dict[str, dict[str, int]] = {
    "m": {"m": 1}, "m/s": {"m": 1, "s": -1}, "m/s2": {"m": 1, "s": -2}, "m/s3": {"m": 1, "s": -3},
    "rad": {"rad": 1}, "rad/s": {"rad": 1, "s": -1}, "rad/s2": {"rad": 1, "s": -2},
    "s": {"s": 1}, "1/s": {"s": -1}, "kg": {"kg": 1}, "kg.m2": {"kg": 1, "m": 2},
    "N": {"kg": 1, "m": 1, "s": -2}, "N/s": {"kg": 1, "m": 1, "s": -3},
    "N.m": {"kg": 1, "m": 2, "s": -2}, "N.m/s": {"kg": 1, "m": 2, "s": -3}, "J": {"kg": 1, "m": 2, "s": -2},
    "W": {"kg": 1, "m": 2, "s": -3}, "N/m": {"kg": 1, "s": -2}, "N.s/m": {"kg": 1, "s": -1},
    "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1}, "kg.m/s": {"kg": 1, "m": 1, "s": -1},
    "1/s2": {"s": -2}, "1/s3": {"s": -3}, "m.s": {"m": 1, "s": 1},
}
#: <LogCategories>: the FMI 2.0 names where the standard has one (the Reference FMUs' logEvents,
#: logStatusError), ours for the component and the solver; see fmu_logging and docs/logging.md
LOG_CATEGORIES = CATEGORIES + (LOG_ALL,)


def header_attributes(cls: type[Component], version: str, **token: str) -> dict:
    """Attributes of ``<fmiModelDescription>`` that both versions write, with the model's token
    (``guid`` in FMI 2.0, ``instantiationToken`` in FMI 3.0) after its name."""
    return xml_attributes(
        fmiVersion=version, modelName=cls.fmi_model_name(), **token, description=_description(cls),
        author=cls.author or None, version=cls.version, generationTool=f"deltafmi {__version__}",
        generationDateAndTime=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        variableNamingConvention="structured")


def model_description_xml(cls: type[Component], guid: str) -> bytes:
    """The complete ``modelDescription.xml`` of ``cls`` as UTF-8 bytes."""
    layout = cls._layout
    name = cls.fmi_model_name()
    root = ET.Element("fmiModelDescription", dict(
        **header_attributes(cls, "2.0", guid=guid), numberOfEventIndicators=str(cls.n_event_indicators)))
    common = dict(modelIdentifier=name, needsExecutionTool="false", canGetAndSetFMUstate="true",
                  canSerializeFMUstate="true" if cls.can_serialize_state else "false", canNotUseMemoryManagementFunctions="true",
                  providesDirectionalDerivative="true")
    if cls.co_simulation_only:
        common.update(providesDirectionalDerivative="false")
    else:
        ET.SubElement(root, "ModelExchange", xml_attributes(
            **common, completedIntegratorStepNotNeeded="false" if cls.watches_drift() else "true"))
    ET.SubElement(root, "CoSimulation", xml_attributes(
        **common, canHandleVariableCommunicationStepSize="true", canInterpolateInputs="false",
        maxOutputDerivativeOrder="0", canRunAsynchronuously="false"))

    add_unit_definitions(root, cls)
    enumerations = enumeration_types(cls)
    if enumerations:
        types = ET.SubElement(root, "TypeDefinitions")
        for name, members in enumerations.items():
            add_enumeration_items(ET.SubElement(ET.SubElement(types, "SimpleType", name=name), "Enumeration"), members)
    add_log_categories_and_experiment(root, cls)
    tool = ET.SubElement(ET.SubElement(root, "VendorAnnotations"), "Tool", name="deltafmi")
    add_derivatives_annotation(tool, cls)

    variables = ET.SubElement(root, "ModelVariables")
    for scalar in layout.scalars:
        _scalar_variable(variables, scalar)
    _model_structure(root, cls)
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def _scalar_variable(parent: ET.Element, s: ScalarVariable) -> None:
    element = ET.SubElement(parent, "ScalarVariable", xml_attributes(
        name=s.name, valueReference=str(s.value_reference), description=s.description or None,
        causality=s.causality, variability=s.variability, initial=s.initial))
    typed = xml_attributes(start=None if s.initial == "calculated" or s.start is None else xml_value(s.start))
    if s.fmi_type == "Real":
        typed.update(real_attributes(s))
        if s.derivative_of is not None:
            typed["derivative"] = str(s.derivative_of)
    elif s.fmi_type in ("Integer", "Enumeration"):
        typed.update(integer_attributes(s))
    if s.fmi_type == "Enumeration":
        typed = {"declaredType": enumeration_name(s.declaration.type), **typed}
    ET.SubElement(element, s.fmi_type, typed)


def real_attributes(s: ScalarVariable) -> dict:
    """unit, min, max and nominal of a real variable (where given)."""
    return xml_attributes(unit=s.unit or None, min=xml_optional(s.min), max=xml_optional(s.max),
                          nominal=xml_optional(s.nominal))


def integer_attributes(s: ScalarVariable) -> dict:
    """min and max of an integer or enumeration variable (where given)."""
    return xml_attributes(min=xml_optional_int(s.min), max=xml_optional_int(s.max))


def enumeration_name(kind: type) -> str:
    """The type name of an Enumeration declaration's IntEnum in the model description."""
    return kind.__qualname__


def enumeration_types(cls: type[Component]) -> dict[str, type]:
    """The IntEnum classes the component's declarations use, by type name, in declaration order."""
    found: dict[str, type] = {}
    for decl in cls._layout.declarations:
        if decl.fmi_type == "Enumeration":
            name = enumeration_name(decl.type)
            if found.setdefault(name, decl.type) is not decl.type:
                raise ValueError(f"{cls.__qualname__}: two enumerations are both named {name}")
    return found


def add_enumeration_items(parent: ET.Element, members: type) -> None:
    for member in members:
        ET.SubElement(parent, "Item", name=member.name, value=str(int(member)))


def add_unit_definitions(root: ET.Element, cls: type[Component]) -> None:
    """``<UnitDefinitions>``: every unit a variable uses, with SI base-unit exponents where known."""
    units = sorted({s.unit for s in cls._layout.scalars if s.unit})
    if units:
        defs = ET.SubElement(root, "UnitDefinitions")
        for unit in units:
            element = ET.SubElement(defs, "Unit", name=unit)
            if unit in _BASE_UNITS:
                ET.SubElement(element, "BaseUnit", {k: str(v) for k, v in _BASE_UNITS[unit].items()})


def add_log_categories_and_experiment(root: ET.Element, cls: type[Component], fmi_version: int = 2) -> None:
    """``<LogCategories>`` (their descriptions naming the statuses of ``fmi_version``) and
    ``<DefaultExperiment>``."""
    cats = ET.SubElement(root, "LogCategories")
    for cat, text in LOG_CATEGORIES:
        ET.SubElement(cats, "Category", name=cat, description=re.sub(r"\bfmi2(?=[A-Z])", f"fmi{fmi_version}", text))
    exp = cls.default_experiment
    ET.SubElement(root, "DefaultExperiment", startTime=xml_number(exp.start), stopTime=xml_number(exp.stop),
                  tolerance=xml_number(exp.tolerance), stepSize=xml_number(exp.step))


def add_derivatives_annotation(tool: ET.Element, cls: type[Component]) -> None:
    """Our vendor annotation: how the directional derivatives of d der(x)/dx are computed."""
    # an importer's solver gains nothing from the FMU's own central differences over its
    # difference quotients (and pays twice the calls)
    ET.SubElement(tool, "DirectionalDerivatives",
                  derivatives="exact" if cls.provides_jacobian() else "central differences")


def output_dependencies(cls: type[Component]) -> dict[int, list[int]]:
    """Value references of the knowns (states, inputs) each output scalar depends on, keyed by
    the output's value reference: all of them unless ``direct_feedthrough`` narrows the inputs."""
    layout = cls._layout
    states = list(range(layout.nx))
    inputs_by_decl: dict[str, list[int]] = {}
    for s in layout.scalars:
        if s.causality == "input":
            inputs_by_decl.setdefault(s.declaration.name, []).append(s.value_reference)
    all_inputs = [i for group in inputs_by_decl.values() for i in group]
    feedthrough = feedthrough_of(cls)
    return {s.value_reference: states + (all_inputs if feedthrough is None else
                                         [i for name in feedthrough.get(s.declaration.name, [])
                                          for i in inputs_by_decl[name]])
            for s in layout.scalars if s.causality == "output"}


def derivative_dependencies(cls: type[Component]) -> list[int]:
    """Value references of the knowns every state derivative depends on: all states and inputs."""
    layout = cls._layout
    return list(range(layout.nx)) + [s.value_reference for s in layout.scalars if s.causality == "input"]


def initial_unknowns(cls: type[Component]) -> list[ScalarVariable]:
    """The scalars computed in initialization mode: calculated outputs, state derivatives and
    calculated states, in value-reference order."""
    return [s for s in cls._layout.scalars if (s.causality == "output" and s.initial in ("approx", "calculated"))
            or s.derivative_of is not None
            or (s.causality == "local" and s.variability == "continuous" and s.initial in ("approx", "calculated"))]


def _model_structure(root: ET.Element, cls: type[Component]) -> None:
    layout = cls._layout
    structure = ET.SubElement(root, "ModelStructure")
    outputs = output_dependencies(cls)
    if outputs:
        element = ET.SubElement(structure, "Outputs")
        for vr, deps in outputs.items():
            ET.SubElement(element, "Unknown", _deps(vr + 1, [d + 1 for d in deps]))
    derivatives = [s for s in layout.scalars if s.derivative_of is not None]
    if derivatives:
        element = ET.SubElement(structure, "Derivatives")
        deps = [d + 1 for d in derivative_dependencies(cls)]
        for s in derivatives:
            ET.SubElement(element, "Unknown", _deps(s.value_reference + 1, deps))
    initial = initial_unknowns(cls)
    if initial:
        element = ET.SubElement(structure, "InitialUnknowns")
        for s in initial:
            ET.SubElement(element, "Unknown", index=str(s.value_reference + 1))


def _deps(index: int, deps: list[int]) -> dict:
    # FMI 2.0 indices are value references + 1: the variables are listed in value-reference order
    return dependency_attributes({"index": str(index)}, deps)


def dependency_attributes(unknown: dict, deps: Iterable[int]) -> dict:
    """``unknown`` (the attribute naming it) with its sorted ``dependencies``, all ``dependent``."""
    deps = sorted(set(deps))
    return {**unknown, "dependencies": " ".join(map(str, deps)),
            "dependenciesKind": " ".join("dependent" for _ in deps)}


def _description(cls: type) -> Optional[str]:
    doc = (cls.__doc__ or "").strip()
    return doc.splitlines()[0].strip() if doc else None


def xml_attributes(**kwargs: Optional[str]) -> dict:
    return {k: v for k, v in kwargs.items() if v is not None}


def xml_number(x: float) -> str:
    """xs:double spelling: INF, -INF and NaN rather than Python's inf/nan."""
    x = float(x)
    if math.isinf(x):
        return "INF" if x > 0 else "-INF"
    return "NaN" if math.isnan(x) else repr(x)


def xml_value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return xml_number(v)
    return str(int(v)) if isinstance(v, int) else str(v)  # an IntEnum member as its value


def xml_optional(x: Optional[float]) -> Optional[str]:
    return None if x is None else xml_number(x)


def xml_optional_int(x: Optional[float]) -> Optional[str]:
    return None if x is None else str(int(x))
