"""What the master needs to know about one FMU, read from its modelDescription through fmpy.

Variable lookup with Modelica-style array references (``r`` = all of ``r[1]..r[n]``,
``r[1:3]``, ``r[*]``), units, and direct feedthrough from ``<ModelStructure><Outputs>``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cached_property
from typing import Dict, List, Optional, Set, Tuple

from fmpy import read_model_description
from fmpy.model_description import ModelDescription, ModelVariable

_RANGE = re.compile(r"^(?P<base>.+)\[(?P<lo>\d+):(?P<hi>\d+)\]$")
_ALL = re.compile(r"^(?P<base>.+)\[\*\]$")
_ELEMENT = re.compile(r"(?P<base>.+)\[(?P<i>\d+)\]")


def split_element(name: str) -> Optional[Tuple[str, int]]:
    """``plant.z[3]`` -> ``("plant.z", 3)``: an element of a scalarized 1-D array; None for a
    name that is none (``plant.fn``, ``plant.z[1:3]``)."""
    m = _ELEMENT.fullmatch(name)
    return (m["base"], int(m["i"])) if m else None


class UnknownVariable(LookupError):
    """A variable reference names nothing in the FMU; ``names`` are candidates for suggestions."""

    def __init__(self, reference: str, names: List[str]) -> None:
        super().__init__(reference)
        self.reference = reference
        self.names = names


@dataclass(frozen=True)
class ModelInfo:
    """A parsed modelDescription plus lookups; build with :func:`model_info`."""

    path: str
    md: ModelDescription

    @cached_property
    def variables(self) -> Dict[str, ModelVariable]:
        """Variables by name."""
        return {v.name: v for v in self.md.modelVariables}

    @cached_property
    def arrays(self) -> Dict[str, List[str]]:
        """Scalarized 1-D arrays: base name -> element names ordered by index."""
        found: Dict[str, Dict[int, str]] = {}
        for name in self.variables:
            element = split_element(name)
            if element:
                found.setdefault(element[0], {})[element[1]] = name
        return {base: [els[i] for i in sorted(els)] for base, els in found.items()}

    def expand(self, reference: str) -> List[str]:
        """Scalar variable names of ``reference``; raises :class:`UnknownVariable`."""
        if reference in self.variables:
            return [reference]
        m = _RANGE.match(reference)
        if m and m["base"] in self.arrays:
            names = [f"{m['base']}[{i}]" for i in range(int(m["lo"]), int(m["hi"]) + 1)]
            missing = [n for n in names if n not in self.variables]
            if not missing and names:
                return names
            raise UnknownVariable(missing[0] if missing else reference, self.suggestion_names())
        m = _RANGE.match(reference) or _ALL.match(reference)
        if m:  # an unknown array: suggest array names
            raise UnknownVariable(m["base"], list(self.arrays))
        if reference in self.arrays:
            return list(self.arrays[reference])
        raise UnknownVariable(reference, self.suggestion_names())

    def suggestion_names(self) -> List[str]:
        """Names worth suggesting: every variable and every array base name."""
        return list(self.variables) + list(self.arrays)

    def unit(self, name: str) -> str:
        """Unit of a variable (its own or its declared type's), ``""`` when none."""
        var = self.variables[name]
        if var.unit:
            return var.unit
        declared = var.declaredType
        return (declared.unit or "") if declared is not None else ""

    def enumeration(self, name: str) -> Optional[Tuple[str, Dict[str, int]]]:
        """``(type name, {item name: value})`` of an Enumeration variable; None for other types."""
        var = self.variables[name]
        if var.type != "Enumeration" or var.declaredType is None:
            return None
        return var.declaredType.name, {item.name: int(item.value) for item in var.declaredType.items}

    @cached_property
    def feedthrough(self) -> Dict[str, Set[str]]:
        """Output name -> names of the inputs it depends on directly (ModelStructure Outputs).

        An output listed without a ``dependencies`` attribute depends on every input (FMI 2.0).
        """
        inputs = {v.name for v in self.md.modelVariables if v.causality == "input"}
        result: Dict[str, Set[str]] = {}
        listed = set()
        for unknown in self.md.outputs:
            name = unknown.variable.name
            listed.add(name)
            if unknown.dependencies is None:
                result[name] = set(inputs)
            else:
                result[name] = {d.name for d in unknown.dependencies if d.name in inputs}
        for v in self.md.modelVariables:
            if v.causality == "output" and v.name not in listed:
                result[v.name] = set(inputs)
        return result

    @cached_property
    def initial_feedthrough(self) -> Dict[str, Set[str]]:
        """Output name -> inputs it depends on during initialization: the ``dependencies`` of its
        ``<InitialUnknowns>`` entry where the FMU gives them (a sample-and-hold's initial output
        is its input), else those of :attr:`feedthrough` (read literally, an entry without
        ``dependencies`` would depend on every input and close every feedback loop at
        initialization)."""
        inputs = {v.name for v in self.md.modelVariables if v.causality == "input"}
        result = {name: set(inputs_of) for name, inputs_of in self.feedthrough.items()}
        for unknown in self.md.initialUnknowns:
            name = unknown.variable.name
            if name in result and unknown.dependencies is not None:
                result[name] = {d.name for d in unknown.dependencies if d.name in inputs}
        return result

    def interfaces(self) -> List[str]:
        """``"ME"`` and/or ``"CS"``, as offered by the FMU."""
        return [kind for kind, element in (("ME", self.md.modelExchange), ("CS", self.md.coSimulation))
                if element is not None]

    def can_get_set_state(self, interface: str) -> bool:
        """Whether fmi2GetFMUstate/fmi2SetFMUstate are supported for ``interface``."""
        element = self.md.modelExchange if interface == "ME" else self.md.coSimulation
        return bool(element is not None and element.canGetAndSetFMUstate)

    def model_identifier(self, interface: str) -> str:
        """modelIdentifier of ``interface``."""
        element = self.md.modelExchange if interface == "ME" else self.md.coSimulation
        return element.modelIdentifier

    def default_step(self) -> Optional[float]:
        """stepSize of the FMU's DefaultExperiment, if any."""
        de = self.md.defaultExperiment
        return float(de.stepSize) if de is not None and de.stepSize is not None else None


def model_info(path: str) -> ModelInfo:
    """Read the modelDescription of the FMU at ``path`` (fmpy.read_model_description)."""
    return ModelInfo(str(path), read_model_description(str(path), validate=False))
