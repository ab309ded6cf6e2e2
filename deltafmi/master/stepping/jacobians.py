"""Partial derivatives of a Model Exchange FMU, through fmpy: the FMU's directional derivatives
(``fmi2GetDirectionalDerivative`` / ``fmi3GetDirectionalDerivative``) when it provides them, else
central differences of its state derivatives and Real outputs.

Used by the master's CVODE (the Newton matrix d der(x) / dx) and by ``deltafmi linearize`` (A, B,
C, D). The FMU must be in continuous-time or event mode with its time, states and inputs set;
every value it changes to take differences is restored.

A scalar is named by a key ``(value reference, element)``: the element is 0 for a scalar and for
every FMI 2.0 variable, the row-major place in an FMI 3.0 array variable otherwise
(:attr:`.Port.index`).
"""
from __future__ import annotations

from ctypes import POINTER, c_double, c_uint32 as _VR  # fmi2ValueReference = fmi3ValueReference
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..scenario.modelinfo import ModelInfo, element_names
from .unit_base import bare_function

if TYPE_CHECKING:
    import xml.etree.ElementTree as ET

__all__ = ["FD_STEP", "FmuJacobian", "Key", "REAL_TYPES", "RealValues", "computes_exact_derivatives", "real_nominals",
           "scalar_key"]

#: relative step of the central differences (eps^(1/3): truncation and rounding balanced)
FD_STEP = float(np.finfo(float).eps) ** (1.0 / 3.0)

Key = Tuple[int, int]
#: the variable types whose scalars are differentiated (FMI 2.0 Real, FMI 3.0 Float64)
REAL_TYPES = ("Real", "Float64")


def scalar_key(info: ModelInfo, name: str) -> Key:
    """The key of the scalar variable (or array element) ``name``."""
    return info.variables[name].valueReference, info.positions.get(name, 0)


def real_nominals(info: ModelInfo) -> Dict[Key, float]:
    """|nominal| of every Real scalar that declares one (elements of an FMI 3.0 array each)."""
    return {(v.valueReference, i): nominal for v in info.md.modelVariables
            if v.type in REAL_TYPES and getattr(v, "nominal", None)
            for i, nominal in enumerate(_nominals(v, info.sizes[v.valueReference]))}


def computes_exact_derivatives(unzip_dir: str) -> bool:
    """Whether a solver should take d der(x)/dx from the FMU: False only for a deltafmi FMU whose
    directional derivatives are its own central differences (its vendor annotation says so), as
    good as a solver's difference quotients at twice the calls; True for every other FMU."""
    root = _model_description(unzip_dir)
    note = None if root is None else root.find("VendorAnnotations/Tool[@name='deltafmi']/DirectionalDerivatives")
    return note is None or note.get("derivatives") == "exact"


def provides_directional_derivatives(unzip_dir: str) -> bool:
    """The Model Exchange interface's providesDirectionalDerivative (FMI 2.0) or
    providesDirectionalDerivatives (FMI 3.0; fmpy 0.3.32 does not read it)."""
    root = _model_description(unzip_dir)
    me = None if root is None else root.find("ModelExchange")
    if me is None:
        return False
    value = me.get("providesDirectionalDerivatives", me.get("providesDirectionalDerivative", "false"))
    return value.strip() in ("true", "1")


def _model_description(unzip_dir: str) -> Optional[ET.Element]:
    import xml.etree.ElementTree as ET  # here: a run whose solvers need no Jacobian never parses it

    try:
        return ET.parse(Path(unzip_dir) / "modelDescription.xml").getroot()
    except (OSError, ET.ParseError):
        return None


class RealValues:
    """Get and set Real scalars by key: ``fmi2GetReal``/``fmi2SetReal``, or in FMI 3.0
    ``fmi3GetFloat64``/``fmi3SetFloat64`` of whole variables (an array is set whole, its other
    elements keeping their values)."""

    def __init__(self, fmu: Any, info: ModelInfo) -> None:
        self.fmu, self.info = fmu, info

    def get(self, keys: Sequence[Key]) -> np.ndarray:
        """The values of ``keys``."""
        if not len(keys):
            return np.zeros(0)
        if not self.info.fmi3:
            return np.array(self.fmu.getReal([vr for vr, _ in keys]), dtype=float)
        variables, offsets = self._whole(keys)
        values = self.fmu.getFloat64(variables, sum(self.info.sizes[vr] for vr in variables))
        return np.array([values[offsets[vr] + i] for vr, i in keys], dtype=float)

    def set(self, keys: Sequence[Key], values: Sequence[float]) -> None:
        """Set ``keys`` to ``values``."""
        if not len(keys):
            return
        if not self.info.fmi3:
            self.fmu.setReal([vr for vr, _ in keys], [float(v) for v in values])
            return
        variables, offsets = self._whole(keys)
        whole = list(self.fmu.getFloat64(variables, sum(self.info.sizes[vr] for vr in variables)))
        for (vr, i), value in zip(keys, values):
            whole[offsets[vr] + i] = float(value)
        self.fmu.setFloat64(variables, whole)

    def _whole(self, keys: Sequence[Key]) -> Tuple[List[int], Dict[int, int]]:
        variables = list(dict.fromkeys(vr for vr, _ in keys))
        offsets, n = {}, 0
        for vr in variables:
            offsets[vr] = n
            n += self.info.sizes[vr]
        return variables, offsets


class FmuJacobian:
    """Jacobian blocks of one instantiated ME FMU (fmpy ``FMU2Model`` or ``FMU3Model``)."""

    def __init__(self, fmu: Any, info: ModelInfo, exact: Optional[bool] = None) -> None:
        """``exact``: use the FMU's directional derivatives (default: when it provides them)."""
        self.fmu, self.info = fmu, info
        self.values = RealValues(fmu, info)
        derivatives = [d.variable for d in info.md.derivatives]
        #: keys of the state derivatives and of the states, in the FMU's state order
        self.derivatives: List[Key] = [(v.valueReference, i) for v in derivatives
                                       for i in range(info.sizes[v.valueReference])]
        self.states: List[Key] = [(v.derivative.valueReference, i) for v in derivatives
                                  for i in range(info.sizes[v.derivative.valueReference])]
        self.nx = len(self.states)
        self._derivative_variables = [v.valueReference for v in derivatives]
        provided = provides_directional_derivatives(fmu.unzipDirectory)
        self.exact = provided if exact is None else bool(exact and provided)
        self.nominals = real_nominals(info)
        #: the states' names (an FMI 3.0 array state by its elements)
        self.state_names = [name for v in derivatives for name in _element_names(v.derivative)]
        if self.exact:
            self._dd = bare_function(fmu, "fmi2GetDirectionalDerivative")
        self._columns: dict = {}

    # --- the solver's Newton matrix -----------------------------------------------------------
    def fill_state_jacobian(self, J: np.ndarray) -> None:
        """d der(x) / dx into the Fortran-ordered (nx, nx) array ``J``, one directional derivative
        per column written straight into it (time and states already set)."""
        calls = self._columns.get(J.ctypes.data)
        if calls is None:
            calls = self._columns[J.ctypes.data] = [
                self._column_call(self._derivative_variables, known, J[:, j])
                for j, known in enumerate(self.states)]
        handle = self.fmu.component
        for args in calls:
            self._dd(handle, *args)

    def _column_call(self, unknowns: Sequence[int], known: Key, out: np.ndarray) -> tuple:
        """The arguments after the instance of the directional derivative call that writes
        d unknowns / d known (whole variables, every element) into ``out``."""
        vr, element = known
        size = self.info.sizes[vr] if self.info.fmi3 else 1
        seed = (c_double * size)()
        seed[element] = 1.0
        unknown_refs = (_VR * len(unknowns))(*unknowns)
        target = out.ctypes.data_as(POINTER(c_double))
        if self.info.fmi3:
            return unknown_refs, len(unknowns), (_VR * 1)(vr), 1, seed, size, target, len(out)
        return unknown_refs, len(unknowns), (_VR * 1)(vr), 1, seed, target

    # --- dense blocks -------------------------------------------------------------------------
    def block(self, unknowns: Sequence[Key], knowns: Sequence[Key]) -> np.ndarray:
        """d unknowns / d knowns (keys; unknowns: state derivatives and Real outputs, knowns:
        states and Real inputs) as a dense (len(unknowns), len(knowns)) matrix."""
        matrix = np.zeros((len(unknowns), len(knowns)))
        if not len(unknowns) or not len(knowns):
            return matrix
        if self.exact:
            variables = list(dict.fromkeys(vr for vr, _ in unknowns))
            sizes = [self.info.sizes[vr] if self.info.fmi3 else 1 for vr in variables]
            offsets = dict(zip(variables, np.cumsum([0] + sizes[:-1])))
            rows = [offsets[vr] + i for vr, i in unknowns]
            column = np.zeros(sum(sizes))
            for j, known in enumerate(knowns):
                self._dd(self.fmu.component, *self._column_call(variables, known, column))
                matrix[:, j] = column[rows]
            return matrix
        return self._differences(list(unknowns), list(knowns))

    def _differences(self, unknowns: List[Key], knowns: List[Key]) -> np.ndarray:
        """Central differences: states through SetContinuousStates, inputs as values."""
        x0 = self.get_states()
        state_index = {key: i for i, key in enumerate(self.states)}
        inputs = [key for key in knowns if key not in state_index]
        u0 = self.values.get(inputs)
        input_index = {key: i for i, key in enumerate(inputs)}
        columns = []
        try:
            for key in knowns:
                value = x0[state_index[key]] if key in state_index else u0[input_index[key]]
                h = FD_STEP * max(abs(value), self.nominals.get(key, 1.0))
                sides = []
                for sign in (1.0, -1.0):
                    if key in state_index:
                        x = x0.copy()
                        x[state_index[key]] += sign * h
                        self.set_states(x)
                    else:
                        self.values.set([key], [value + sign * h])
                    sides.append(self._unknowns(unknowns))
                    self.set_states(x0)
                    self.values.set(inputs, u0)
                columns.append((sides[0] - sides[1]) / (2.0 * h))
        finally:
            self.set_states(x0)
            self.values.set(inputs, u0)
        return np.column_stack(columns)

    def _unknowns(self, unknowns: List[Key]) -> np.ndarray:
        derivative_index = {key: i for i, key in enumerate(self.derivatives)}
        values = np.zeros(len(unknowns))
        if self.nx and any(key in derivative_index for key in unknowns):
            dx = self.state_derivatives()
            for i, key in enumerate(unknowns):
                if key in derivative_index:
                    values[i] = dx[derivative_index[key]]
        others = [(i, key) for i, key in enumerate(unknowns) if key not in derivative_index]
        if others:
            values[[i for i, _ in others]] = self.values.get([key for _, key in others])
        return values

    def state_derivatives(self) -> np.ndarray:
        """The FMU's state derivatives now."""
        dx = np.zeros(self.nx)
        if self.nx:
            get = self.fmu.getContinuousStateDerivatives if self.info.fmi3 else self.fmu.getDerivatives
            get(dx.ctypes.data_as(POINTER(c_double)), self.nx)
        return dx

    def get_states(self) -> np.ndarray:
        """The FMU's continuous states."""
        x = np.zeros(self.nx)
        if self.nx:
            self.fmu.getContinuousStates(x.ctypes.data_as(POINTER(c_double)), self.nx)
        return x

    def set_states(self, x: np.ndarray) -> None:
        """Set the FMU's continuous states."""
        if self.nx:
            x = np.ascontiguousarray(x, dtype=float)
            self.fmu.setContinuousStates(x.ctypes.data_as(POINTER(c_double)), self.nx)


def _element_names(variable: Any) -> List[str]:
    return element_names(variable.name, variable.shape) if variable.dimensions else [variable.name]


def _nominals(variable: Any, size: int) -> List[float]:
    """The nominal value of each element (1.0 where it is not a number)."""
    text = variable.nominal
    try:
        values = [abs(float(v)) for v in str(text).split()]
    except ValueError:
        return [1.0] * size
    return values * size if len(values) == 1 else (values + [1.0] * size)[:size]
