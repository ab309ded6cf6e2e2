"""What the master needs to know about one FMU, read from its modelDescription through fmpy.

Variable lookup with Modelica-style array references (``r`` = all of ``r[1]..r[n]``,
``r[1:3]``, ``r[*]``), units, and direct feedthrough from ``<ModelStructure><Outputs>``.

FMI 2.0 and FMI 3.0 look the same from here: an FMI 3.0 array variable ``q`` (``<Dimension>``)
is listed as its elements ``q[1]``, ``q[2]``, ... (2-D: ``A[1,1]``, ``A[1,2]``, ... row-major),
as an FMI 2.0 FMU lists its scalarized arrays; each element shares the array's value reference
and has its place in it (:attr:`ModelInfo.positions`). The independent variable (``time``) and
the array variables themselves are not in :attr:`ModelInfo.variables`.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cached_property
from itertools import product
from pathlib import Path
from typing import Dict, FrozenSet, List, Optional, Set, Tuple

from attrs import evolve
from fmpy import read_model_description
from fmpy.model_description import ModelDescription, ModelVariable

from deltafmi.errors import BadInput, DeltaFmiError

__all__ = ["ModelInfo", "UnknownVariable", "element_names", "model_info", "split_element"]

_RANGE = re.compile(r"^(?P<base>.+)\[(?P<lo>\d+):(?P<hi>\d+)\]$")
_ALL = re.compile(r"^(?P<base>.+)\[\*\]$")
_ELEMENT = re.compile(r"(?P<base>.+)\[(?P<i>\d+)\]")
_DERIVATIVE = re.compile(r"der\((.+)\)")


def split_element(name: str) -> Optional[Tuple[str, int]]:
    """``plant.z[3]`` -> ``("plant.z", 3)``: an element of a scalarized 1-D array; None for a
    name that is none (``plant.fn``, ``plant.z[1:3]``)."""
    m = _ELEMENT.fullmatch(name)
    return (m["base"], int(m["i"])) if m else None


class UnknownVariable(DeltaFmiError, LookupError):
    """A variable reference names nothing in the FMU; ``names`` are candidates for suggestions."""

    exit_code = 2  # bad input

    def __init__(self, reference: str, names: List[str]) -> None:
        super().__init__(reference)
        self.reference = reference
        self.names = names


@dataclass(frozen=True)
class ModelInfo:
    """A parsed modelDescription plus lookups; build with :func:`model_info`."""

    path: str
    md: ModelDescription

    @property
    def fmi3(self) -> bool:
        """Whether the FMU is an FMI 3.0 FMU."""
        return self.md.fmiVersion.startswith("3")

    @cached_property
    def variables(self) -> Dict[str, ModelVariable]:
        """Scalar variables by name (an FMI 3.0 array as its elements, see the module's note)."""
        if not self.fmi3:
            return {v.name: v for v in self.md.modelVariables}
        found: Dict[str, ModelVariable] = {}
        for v in self.md.modelVariables:
            if v.causality == "independent":
                continue
            if not v.dimensions:
                found[v.name] = v
                continue
            starts = _start_items(v)
            for i, name in enumerate(element_names(v.name, v.shape)):
                found[name] = evolve(v, name=name, start=starts[i] if i < len(starts) else None)
        return found

    @cached_property
    def discrete_real_inputs(self) -> FrozenSet[int]:
        """Value references of the Real (Float32/64) inputs of variability discrete."""
        return frozenset(v.valueReference for v in self.md.modelVariables
                         if v.type in ("Real", "Float64", "Float32") and v.causality == "input"
                         and v.variability == "discrete")

    @cached_property
    def positions(self) -> Dict[str, int]:
        """Element name -> its place (row-major) in its FMI 3.0 array variable; 0 for a scalar."""
        found: Dict[str, int] = {}
        for v in self.md.modelVariables:
            if v.dimensions and v.causality != "independent":
                found.update({name: i for i, name in enumerate(element_names(v.name, v.shape))})
        return found

    @cached_property
    def sizes(self) -> Dict[int, int]:
        """Value reference -> number of elements of its variable (1 for a scalar)."""
        return {v.valueReference: _count(v.shape) if v.dimensions else 1 for v in self.md.modelVariables}

    @cached_property
    def fmi3_arrays(self) -> Dict[str, Tuple[int, ...]]:
        """FMI 3.0 array variables: name -> shape."""
        return {v.name: tuple(v.shape) for v in self.md.modelVariables
                if v.dimensions and v.causality != "independent"}

    @cached_property
    def arrays(self) -> Dict[str, List[str]]:
        """Arrays: base name -> element names in order (scalarized FMI 2.0 arrays by index, FMI 3.0
        arrays row-major)."""
        if self.fmi3:
            return {v.name: element_names(v.name, v.shape) for v in self.md.modelVariables
                    if v.dimensions and v.causality != "independent"}
        found: Dict[str, Dict[int, str]] = {}
        for name in self.variables:
            element = split_element(name)
            if element:
                found.setdefault(element[0], {})[element[1]] = name
        return {base: [els[i] for i in sorted(els)] for base, els in found.items()}

    def shape(self, reference: str) -> Optional[Tuple[int, ...]]:
        """The shape of a whole array named by ``reference`` (FMI 3.0: as declared; a scalarized
        FMI 2.0 array: its length); None for anything else."""
        if reference in self.fmi3_arrays:
            return self.fmi3_arrays[reference]
        if reference in self.arrays and reference not in self.variables:
            return (len(self.arrays[reference]),)
        return None

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
        inputs = {name for name, v in self.variables.items() if v.causality == "input"}
        result: Dict[str, Set[str]] = {}
        for unknown in self.md.outputs:
            depends = set(inputs) if unknown.dependencies is None else \
                {n for d in unknown.dependencies for n in self._elements(d.name) if n in inputs}
            for name in self._elements(unknown.variable.name):
                result[name] = depends
        for name, v in self.variables.items():
            if v.causality == "output" and name not in result:
                result[name] = set(inputs)
        return result

    def _elements(self, name: str) -> List[str]:
        """A variable's scalar names: an FMI 3.0 array's elements, else the name itself."""
        return self.arrays[name] if self.fmi3 and name in self.arrays else [name]

    @cached_property
    def initial_feedthrough(self) -> Dict[str, Set[str]]:
        """Output name -> inputs it depends on during initialization: the ``dependencies`` of its
        ``<InitialUnknowns>`` entry where the FMU gives them (a sample-and-hold's initial output
        is its input), else those of :attr:`feedthrough` (read literally, an entry without
        ``dependencies`` would depend on every input and close every feedback loop at
        initialization)."""
        inputs = {name for name, v in self.variables.items() if v.causality == "input"}
        result = {name: set(inputs_of) for name, inputs_of in self.feedthrough.items()}
        for unknown in self.md.initialUnknowns:
            if unknown.dependencies is None:
                continue
            depends = {n for d in unknown.dependencies for n in self._elements(d.name) if n in inputs}
            for name in self._elements(unknown.variable.name):
                if name in result:
                    result[name] = set(depends)
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



def element_names(name: str, shape: Tuple[int, ...]) -> List[str]:
    """Names of the elements of an array ``name`` of ``shape``, row-major, 1-based:
    ``q[1], q[2]`` (1-D), ``A[1,1], A[1,2], A[2,1], ...`` (2-D); a derivative array ``der(q)`` has
    ``der(q[1])``, ... as FMI 2.0 names them."""
    indices = [",".join(str(i + 1) for i in index) for index in product(*(range(n) for n in shape))]
    derivative = _DERIVATIVE.fullmatch(name)
    if derivative:
        return [f"der({derivative[1]}[{index}])" for index in indices]
    return [f"{name}[{index}]" for index in indices]


def _count(shape: Tuple[int, ...]) -> int:
    count = 1
    for n in shape:
        count *= n
    return count


def _start_items(v: ModelVariable) -> List[str]:
    """The start values of an FMI 3.0 array's elements (its start attribute lists them, separated by
    white space; one value sets every element)."""
    if v.start is None:
        return []
    items = [v.start] if v.type in ("String", "Binary") else v.start.split()
    return items * _count(v.shape) if len(items) == 1 else items


def model_info(path: str) -> ModelInfo:
    """Read the modelDescription of the FMU at ``path`` (fmpy.read_model_description); raises
    :class:`~deltafmi.errors.BadInput` saying why a file is not an FMU deltafmi can read
    (:func:`~.fmu_checks.archive_problem`)."""
    kept = _kept_description(Path(path))
    md = kept.read() if kept is not None else None
    if md is None:
        from .fmu_checks import archive_problem

        problem = archive_problem(Path(path))
        if problem is not None:
            raise BadInput(problem)
        md = read_model_description(str(path), validate=False)
        if kept is not None:
            kept.write(md)
    return ModelInfo(str(path), md)


class _KeptDescription:
    """An FMU's model description as read before, kept in the cache under the FMU's stamp (path,
    size, modification time, inode) and fmpy's version: reading it again costs a millisecond,
    parsing the XML (and the checks of the archive, which passed) many."""

    def __init__(self, file: Path) -> None:
        self.file = file

    def read(self) -> Optional[ModelDescription]:
        import pickle

        try:
            md = pickle.loads(self.file.read_bytes())
        except Exception:  # noqa: BLE001 - none kept, or kept by another fmpy: read the FMU
            return None
        return md if isinstance(md, ModelDescription) else None

    def write(self, md: ModelDescription) -> None:
        import os
        import pickle

        temporary = self.file.with_name(f"{self.file.name}.{os.getpid()}.tmp")
        try:
            self.file.parent.mkdir(parents=True, exist_ok=True)
            temporary.write_bytes(pickle.dumps(md, protocol=pickle.HIGHEST_PROTOCOL))
            os.replace(temporary, self.file)
        except Exception:  # noqa: BLE001 - a read-only cache, a description pickle cannot hold: read it each time
            temporary.unlink(missing_ok=True)


def _kept_description(fmu: Path) -> Optional[_KeptDescription]:
    from deltafmi.toolchain import cache_dir

    from .fmu_checks import fmu_stamp

    stamp = fmu_stamp(fmu)
    return None if stamp is None else _KeptDescription(cache_dir() / "model-descriptions" / stamp)
