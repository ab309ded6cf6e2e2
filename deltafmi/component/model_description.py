"""Write ``modelDescription.xml`` (FMI 2.0) for a component class: both interfaces in one FMU."""
from __future__ import annotations

import datetime
import math
import xml.etree.ElementTree as ET
from typing import Optional

from .. import __version__
from .base import Component
from .checks import feedthrough_of
from .fmu_logging import CATEGORIES, LOG_ALL
from .layout import ScalarVariable

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


def model_description_xml(cls: type[Component], guid: str) -> bytes:
    """The complete ``modelDescription.xml`` of ``cls`` as UTF-8 bytes."""
    layout = cls._layout
    name = cls.fmi_model_name()
    root = ET.Element("fmiModelDescription", _attrs(
        fmiVersion="2.0", modelName=name, guid=guid, description=_description(cls),
        author=cls.author or None, version=cls.version, generationTool=f"deltafmi {__version__}",
        generationDateAndTime=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        variableNamingConvention="structured", numberOfEventIndicators=str(cls.n_event_indicators)))
    common = dict(modelIdentifier=name, needsExecutionTool="false", canGetAndSetFMUstate="true",
                  canSerializeFMUstate="true", canNotUseMemoryManagementFunctions="true",
                  providesDirectionalDerivative="true")
    ET.SubElement(root, "ModelExchange", _attrs(
        **common, completedIntegratorStepNotNeeded="false" if cls.watches_drift() else "true"))
    ET.SubElement(root, "CoSimulation", _attrs(
        **common, canHandleVariableCommunicationStepSize="true", canInterpolateInputs="false",
        maxOutputDerivativeOrder="0", canRunAsynchronuously="false"))

    units = sorted({s.unit for s in layout.scalars if s.unit})
    if units:
        defs = ET.SubElement(root, "UnitDefinitions")
        for unit in units:
            element = ET.SubElement(defs, "Unit", name=unit)
            if unit in _BASE_UNITS:
                ET.SubElement(element, "BaseUnit", {k: str(v) for k, v in _BASE_UNITS[unit].items()})
    cats = ET.SubElement(root, "LogCategories")
    for cat, text in LOG_CATEGORIES:
        ET.SubElement(cats, "Category", name=cat, description=text)
    exp = cls.default_experiment
    ET.SubElement(root, "DefaultExperiment", startTime=_num(exp.start), stopTime=_num(exp.stop),
                  tolerance=_num(exp.tolerance), stepSize=_num(exp.step))
    # how fmi2GetDirectionalDerivative gets d der(x)/dx: an importer's solver gains nothing from
    # the FMU's own central differences over its difference quotients (and pays twice the calls)
    tool = ET.SubElement(ET.SubElement(root, "VendorAnnotations"), "Tool", name="deltafmi")
    ET.SubElement(tool, "DirectionalDerivatives",
                  derivatives="exact" if cls.provides_jacobian() else "central differences")

    variables = ET.SubElement(root, "ModelVariables")
    for scalar in layout.scalars:
        _scalar_variable(variables, scalar)
    _model_structure(root, cls)
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def _scalar_variable(parent: ET.Element, s: ScalarVariable) -> None:
    element = ET.SubElement(parent, "ScalarVariable", _attrs(
        name=s.name, valueReference=str(s.value_reference), description=s.description or None,
        causality=s.causality, variability=s.variability, initial=s.initial))
    typed = _attrs(start=None if s.initial == "calculated" or s.start is None else _value(s.start))
    if s.fmi_type == "Real":
        typed.update(_attrs(unit=s.unit or None, min=_opt(s.min), max=_opt(s.max), nominal=_opt(s.nominal)))
        if s.derivative_of is not None:
            typed["derivative"] = str(s.derivative_of)
    elif s.fmi_type == "Integer":
        typed.update(_attrs(min=_opt_int(s.min), max=_opt_int(s.max)))
    ET.SubElement(element, s.fmi_type, typed)


def _model_structure(root: ET.Element, cls: type[Component]) -> None:
    layout = cls._layout
    index = {s.name: i + 1 for i, s in enumerate(layout.scalars)}
    states = [i + 1 for i in range(layout.nx)]
    inputs_by_decl = {s.declaration.name: [] for s in layout.scalars if s.causality == "input"}
    for s in layout.scalars:
        if s.causality == "input":
            inputs_by_decl[s.declaration.name].append(index[s.name])
    all_inputs = [i for group in inputs_by_decl.values() for i in group]
    feedthrough = feedthrough_of(cls)

    def output_deps(s: ScalarVariable) -> list[int]:
        if feedthrough is None:
            return states + all_inputs
        return states + [i for name in feedthrough.get(s.declaration.name, []) for i in inputs_by_decl[name]]

    structure = ET.SubElement(root, "ModelStructure")
    outputs = [s for s in layout.scalars if s.causality == "output"]
    if outputs:
        element = ET.SubElement(structure, "Outputs")
        for s in outputs:
            ET.SubElement(element, "Unknown", _deps(index[s.name], output_deps(s)))
    derivatives = [s for s in layout.scalars if s.derivative_of is not None]
    if derivatives:
        element = ET.SubElement(structure, "Derivatives")
        for s in derivatives:
            ET.SubElement(element, "Unknown", _deps(index[s.name], states + all_inputs))
    initial = [s for s in layout.scalars if (s.causality == "output" and s.initial in ("approx", "calculated"))
               or s.derivative_of is not None
               or (s.causality == "local" and s.variability == "continuous" and s.initial in ("approx", "calculated")
                   and s.derivative_of is None)]
    if initial:
        element = ET.SubElement(structure, "InitialUnknowns")
        for s in sorted(initial, key=lambda s: index[s.name]):
            ET.SubElement(element, "Unknown", index=str(index[s.name]))


def _deps(index: int, deps: list[int]) -> dict:
    deps = sorted(set(deps))
    return {"index": str(index), "dependencies": " ".join(map(str, deps)),
            "dependenciesKind": " ".join("dependent" for _ in deps)}


def _description(cls: type) -> Optional[str]:
    doc = (cls.__doc__ or "").strip()
    return doc.splitlines()[0].strip() if doc else None


def _attrs(**kwargs: Optional[str]) -> dict:
    return {k: v for k, v in kwargs.items() if v is not None}


def _num(x: float) -> str:
    """xs:double spelling: INF, -INF and NaN rather than Python's inf/nan."""
    x = float(x)
    if math.isinf(x):
        return "INF" if x > 0 else "-INF"
    return "NaN" if math.isnan(x) else repr(x)


def _value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return _num(v)
    return str(v)


def _opt(x: Optional[float]) -> Optional[str]:
    return None if x is None else _num(x)


def _opt_int(x: Optional[float]) -> Optional[str]:
    return None if x is None else str(int(x))
