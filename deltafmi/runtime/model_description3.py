"""Write ``modelDescription.xml`` (FMI 3.0) for a component class: both interfaces in one FMU.

The same component as the FMI 2.0 writer (:mod:`.model_description`) describes, in FMI 3.0's
terms: a declaration (scalar or 1-D array) is ONE variable whose value reference is that of its
first scalar (``q`` with ``<Dimension start="9"/>``), a state array's derivatives one variable
``der(q)``; after all scalars come ``time`` (the independent variable FMI 3.0 requires), the
Clocks and one Float64 variable per event indicator, since ``<EventIndicator>`` names variables.
The dependencies are FMI 2.0's (:func:`.model_description.output_dependencies`), each known scalar
mapped to the variable holding it, plus ``time``, which FMI 3.0 lists explicitly.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Iterable

from .base import Component
from .clocks import Clock, clock_driven
from .layout import Layout, ScalarVariable
from .model_description import (add_derivatives_annotation, add_enumeration_items, add_log_categories_and_experiment,
                                add_unit_definitions, dependency_attributes, derivative_dependencies, enumeration_name,
                                enumeration_types, header_attributes, initial_unknowns, integer_attributes,
                                output_dependencies, real_attributes, xml_attributes, xml_value)

__all__ = ["model_description3_xml"]

_TYPES3 = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String",
           "Enumeration": "Enumeration"}
#: name of event indicator i (1-based) as a variable
EVENT_INDICATOR_NAME = "_eventIndicator{}"


def has_events(cls: type[Component]) -> bool:
    """Whether the component has events in Co-Simulation: state events (event indicators), time
    events or discrete updates (step events for drift are Model Exchange's: in Co-Simulation the
    solver projects the states itself)."""
    return bool(cls.n_event_indicators or cls.update is not Component.update
                or cls.next_time_event is not Component.next_time_event)


def model_description3_xml(cls: type[Component], token: str) -> bytes:
    """The complete FMI 3.0 ``modelDescription.xml`` of ``cls`` as UTF-8 bytes; ``token`` is the
    instantiationToken."""
    layout = cls._layout
    _check_names(cls)
    root = ET.Element("fmiModelDescription", header_attributes(cls, "3.0", instantiationToken=token))
    common = dict(modelIdentifier=cls.fmi_model_name(), needsExecutionTool="false",
                  canGetAndSetFMUState="true", canSerializeFMUState=_bool(cls.can_serialize_state),
                  providesDirectionalDerivatives="true", providesAdjointDerivatives="true")
    if cls.co_simulation_only:
        common.update(providesDirectionalDerivatives="false", providesAdjointDerivatives="false")
    else:
        ET.SubElement(root, "ModelExchange", xml_attributes(
            **common, needsCompletedIntegratorStep=_bool(cls.watches_drift())))
    event_mode = cs_event_mode(cls)
    ET.SubElement(root, "CoSimulation", xml_attributes(
        **common, canHandleVariableCommunicationStepSize="true", maxOutputDerivativeOrder="0",
        mightReturnEarlyFromDoStep=_bool(event_mode and not clock_driven(cls)), hasEventMode=_bool(event_mode)))
    if clock_driven(cls):
        ET.SubElement(root, "ScheduledExecution", xml_attributes(
            modelIdentifier=common["modelIdentifier"], needsExecutionTool="false", canGetAndSetFMUState="true",
            canSerializeFMUState="true", providesDirectionalDerivatives="true", providesAdjointDerivatives="true"))
    add_unit_definitions(root, cls)
    enumerations = enumeration_types(cls)
    if enumerations:
        types = ET.SubElement(root, "TypeDefinitions")
        for name, members in enumerations.items():
            add_enumeration_items(ET.SubElement(types, "EnumerationType", name=name), members)
    add_log_categories_and_experiment(root, cls, fmi_version=3)

    variables = ET.SubElement(root, "ModelVariables")
    ET.SubElement(variables, "Float64", name="time", valueReference=str(layout.time_vr),
                  causality="independent", variability="continuous", description="Simulation time")
    for i, clock in enumerate(layout.clocks):  # priority: mandatory in Scheduled Execution, ignored otherwise
        _clock(variables, layout.time_vr + 1 + i, clock, priority=i if clock_driven(cls) else None)
    reinit = _states_reinitialized(cls)
    for group in layout.variables3():
        _variable(variables, layout, group, reinit)
    for i in range(cls.n_event_indicators):
        ET.SubElement(variables, "Float64", name=EVENT_INDICATOR_NAME.format(i + 1),
                      valueReference=str(layout.first_indicator_vr + i), causality="local",
                      variability="continuous", initial="calculated",
                      description=f"Event indicator {i + 1} (a state event where it changes sign)")
    _model_structure(root, cls)
    tool = ET.SubElement(ET.SubElement(root, "Annotations"), "Annotation", type="deltafmi")
    add_derivatives_annotation(tool, cls)
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def cs_event_mode(cls: type[Component]) -> bool:
    """Whether the FMI 3.0 Co-Simulation interface has Event Mode (``hasEventMode``). A component
    that steps itself handles its events inside its own do_step, except a clock-driven one: an
    importer can activate a Clock only in Event Mode (see :func:`.clocks.clock_driven`)."""
    if not has_events(cls):
        return False
    return not cls.overrides_do_step() or clock_driven(cls)


def _clock(parent: ET.Element, vr: int, clock: Clock, priority: int | None) -> None:
    # a Parameter's period: a fixed Clock whose interval the importer asks for in Initialization
    # Mode (fmi3GetIntervalDecimal; no intervalDecimal, which would let the importer set it)
    if clock.constant:
        kind = dict(intervalVariability="constant", intervalDecimal=xml_value(clock.period))
        text = f"sampled every {xml_value(clock.period)} s from the start time"
    else:
        kind = dict(intervalVariability="fixed")
        text = f"sampled every {clock.period} s from the start time"
    ET.SubElement(parent, "Clock", xml_attributes(
        name=clock.fmi_name, valueReference=str(vr), description=clock.description or f"The component is {text}",
        causality="input", variability="discrete", **kind, priority=None if priority is None else str(priority)))


def variable_of(layout: Layout) -> dict[int, int]:
    """The value reference of the FMI 3.0 variable holding each scalar, by scalar value reference."""
    return {s.value_reference: group[0].value_reference for group in layout.variables3() for s in group}


def _states_reinitialized(cls: type[Component]) -> bool:
    # which states an update() or a projection changes is not declared: all of them may
    return cls.update is not Component.update or cls.watches_drift()


def _variable(parent: ET.Element, layout: Layout, group: list[ScalarVariable], reinit: bool) -> None:
    s = group[0]
    fmi_type = _TYPES3[s.fmi_type]
    array = len(group) > 1 or (s.declaration is not None and s.declaration.shape is not None)
    name = s.declaration.fmi_name if s.declaration is not None else _derivative_name(layout, s)
    starts = [g.start for g in group]
    has_start = s.initial != "calculated" and s.start is not None
    attributes = xml_attributes(name=name, valueReference=str(s.value_reference), description=_description(s, array),
                        causality=s.causality, variability=s.variability, initial=s.initial)
    if fmi_type == "Enumeration":
        attributes["declaredType"] = enumeration_name(s.declaration.type)
    if fmi_type != "String" and has_start:
        attributes["start"] = " ".join(xml_value(v) for v in starts)
    if fmi_type == "Float64":
        attributes.update(real_attributes(s))
        if s.derivative_of is not None:
            attributes["derivative"] = str(layout.scalars[s.derivative_of - 1].value_reference)
        elif reinit and s.value_reference < layout.nx:
            attributes["reinit"] = "true"
    elif fmi_type in ("Int32", "Enumeration"):
        attributes.update(integer_attributes(s))
    element = ET.SubElement(parent, fmi_type, attributes)
    if array:
        ET.SubElement(element, "Dimension", start=str(len(group)))
    if fmi_type == "String" and has_start:
        for v in starts:
            ET.SubElement(element, "Start", value=str(v))


def _derivative_name(layout: Layout, s: ScalarVariable) -> str:
    return f"der({layout.scalars[s.derivative_of - 1].declaration.fmi_name})"


def _description(s: ScalarVariable, array: bool) -> str | None:
    if s.derivative_of is not None and array:  # "Time derivative of q[1]" names one element
        return s.description.rsplit("[", 1)[0]
    return s.description or None


def _model_structure(root: ET.Element, cls: type[Component]) -> None:
    layout = cls._layout
    owner = variable_of(layout)
    time = layout.time_vr
    structure = ET.SubElement(root, "ModelStructure")
    outputs: dict[int, set[int]] = {}
    for vr, deps in output_dependencies(cls).items():
        outputs.setdefault(owner[vr], set()).update(owner[d] for d in deps)
    for vr, deps in outputs.items():
        ET.SubElement(structure, "Output", _deps(vr, deps | {time}))
    derivative_deps = {owner[d] for d in derivative_dependencies(cls)} | {time}
    for group in layout.variables3():
        if group[0].derivative_of is not None:
            ET.SubElement(structure, "ContinuousStateDerivative", _deps(group[0].value_reference, derivative_deps))
    for vr in dict.fromkeys(owner[s.value_reference] for s in initial_unknowns(cls)):
        ET.SubElement(structure, "InitialUnknown", valueReference=str(vr))
    for i in range(cls.n_event_indicators):
        ET.SubElement(structure, "EventIndicator", _deps(layout.first_indicator_vr + i, derivative_deps))


def _deps(vr: int, deps: Iterable[int]) -> dict:
    return dependency_attributes({"valueReference": str(vr)}, deps)


def _check_names(cls: type[Component]) -> None:
    """The names FMI 3.0 builds add must not be taken by the component's own variables."""
    reserved = {"time"} | {EVENT_INDICATOR_NAME.format(i + 1) for i in range(cls.n_event_indicators)}
    taken = reserved | {d.fmi_name for d in cls._layout.declarations}
    for clock in cls._layout.clocks:
        if clock.fmi_name in taken:
            raise ValueError(f"{cls.__qualname__}: the Clock '{clock.fmi_name}' has the name of another variable; "
                             "rename it (name=...)")
        taken.add(clock.fmi_name)
    for decl in cls._layout.declarations:
        if decl.fmi_name in reserved:
            raise ValueError(f"{cls.__qualname__}: a variable named '{decl.fmi_name}' clashes with the "
                             "variable of that name FMI 3.0 builds add; rename it (name=...)")


def _bool(flag: bool) -> str:
    return "true" if flag else "false"
