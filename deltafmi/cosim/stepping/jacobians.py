"""Partial derivatives of a Model Exchange FMU, through fmpy: ``fmi2GetDirectionalDerivative`` when
the FMU provides it, else central differences of ``fmi2GetDerivatives``/``fmi2GetReal``.

Used by the master's CVODE (the Newton matrix d der(x) / dx) and by ``deltafmi linearize`` (A, B,
C, D). The FMU must be in continuous-time or event mode with its time, states and inputs set;
every value it changes to take differences is restored.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from ctypes import POINTER, c_double
from pathlib import Path
from typing import Any, Optional, Sequence

import numpy as np
from fmpy.fmi2 import fmi2Real, fmi2ValueReference
from fmpy.model_description import ModelDescription

from .unit_base import bare_function

#: relative step of the central differences (eps^(1/3): truncation and rounding balanced)
FD_STEP = float(np.finfo(float).eps) ** (1.0 / 3.0)


def computes_exact_derivatives(unzip_dir: str) -> bool:
    """Whether a solver should take d der(x)/dx from the FMU: False only for a deltafmi FMU whose
    directional derivatives are its own central differences (its vendor annotation says so), as
    good as a solver's difference quotients at twice the calls; True for every other FMU."""
    try:
        root = ET.parse(Path(unzip_dir) / "modelDescription.xml").getroot()
    except (OSError, ET.ParseError):
        return True
    note = root.find("VendorAnnotations/Tool[@name='deltafmi']/DirectionalDerivatives")
    return note is None or note.get("derivatives") == "exact"


class FmuJacobian:
    """Jacobian blocks of one instantiated ME FMU (fmpy ``FMU2Model``)."""

    def __init__(self, fmu: Any, md: ModelDescription, exact: Optional[bool] = None) -> None:
        """``exact``: use fmi2GetDirectionalDerivative (default: when the FMU provides it)."""
        self.fmu, self.md = fmu, md
        self.nx = md.numberOfContinuousStates
        self.states = [d.variable.derivative.valueReference for d in md.derivatives]
        self.derivatives = [d.variable.valueReference for d in md.derivatives]
        provided = bool(md.modelExchange is not None and md.modelExchange.providesDirectionalDerivative)
        self.exact = provided if exact is None else bool(exact and provided)
        self.nominals = {v.valueReference: abs(float(v.nominal)) for v in md.modelVariables
                         if v.type == "Real" and getattr(v, "nominal", None)}
        if self.exact:
            self._dd = bare_function(fmu, "fmi2GetDirectionalDerivative")
        self._columns: dict = {}

    # --- the solver's Newton matrix -----------------------------------------------------------
    def fill_state_jacobian(self, J: np.ndarray) -> None:
        """d der(x) / dx into the Fortran-ordered (nx, nx) array ``J``, one directional derivative
        per column written straight into it (time and states already set)."""
        calls = self._columns.get(J.ctypes.data)
        if calls is None:
            n = self.nx
            unknowns = (fmi2ValueReference * n)(*self.derivatives)
            seed = (fmi2Real * 1)(1.0)
            calls = [((fmi2ValueReference * 1)(vr), J[:, j].ctypes.data_as(POINTER(c_double)))
                     for j, vr in enumerate(self.states)]
            calls = self._columns[J.ctypes.data] = (unknowns, seed, calls)
        unknowns, seed, columns = calls
        handle, n = self.fmu.component, self.nx
        for known, out in columns:
            self._dd(handle, unknowns, n, known, 1, seed, out)

    # --- dense blocks -------------------------------------------------------------------------
    def block(self, unknowns: Sequence[int], knowns: Sequence[int]) -> np.ndarray:
        """d unknowns / d knowns (value references; unknowns: derivatives and Real outputs, knowns:
        states and Real inputs) as a dense (len(unknowns), len(knowns)) matrix."""
        matrix = np.zeros((len(unknowns), len(knowns)))
        if not len(unknowns) or not len(knowns):
            return matrix
        if self.exact:
            for j, known in enumerate(knowns):
                matrix[:, j] = self.fmu.getDirectionalDerivative(list(unknowns), [known], [1.0])
            return matrix
        return self._differences(list(unknowns), list(knowns))

    def _differences(self, unknowns: list, knowns: list) -> np.ndarray:
        """Central differences: states through fmi2SetContinuousStates, inputs through fmi2SetReal."""
        fmu = self.fmu
        x0 = self.get_states()
        state_index = {vr: i for i, vr in enumerate(self.states)}
        inputs = [vr for vr in knowns if vr not in state_index]
        u0 = dict(zip(inputs, fmu.getReal(inputs))) if inputs else {}
        columns = []
        try:
            for vr in knowns:
                value = x0[state_index[vr]] if vr in state_index else u0[vr]
                h = FD_STEP * max(abs(value), self.nominals.get(vr, 1.0))
                sides = []
                for sign in (1.0, -1.0):
                    if vr in state_index:
                        x = x0.copy()
                        x[state_index[vr]] += sign * h
                        self.set_states(x)
                    else:
                        fmu.setReal([vr], [value + sign * h])
                    sides.append(self._unknowns(unknowns))
                    self.set_states(x0)
                    if inputs:
                        fmu.setReal(inputs, [u0[k] for k in inputs])
                columns.append((sides[0] - sides[1]) / (2.0 * h))
        finally:
            self.set_states(x0)
            if inputs:
                fmu.setReal(inputs, [u0[k] for k in inputs])
        return np.column_stack(columns)

    def _unknowns(self, unknowns: list) -> np.ndarray:
        derivative_index = {vr: i for i, vr in enumerate(self.derivatives)}
        values = np.zeros(len(unknowns))
        if self.nx and any(vr in derivative_index for vr in unknowns):
            dx = np.zeros(self.nx)
            self.fmu.getDerivatives(dx.ctypes.data_as(POINTER(c_double)), self.nx)
            for i, vr in enumerate(unknowns):
                if vr in derivative_index:
                    values[i] = dx[derivative_index[vr]]
        others = [(i, vr) for i, vr in enumerate(unknowns) if vr not in derivative_index]
        if others:
            values[[i for i, _ in others]] = self.fmu.getReal([vr for _, vr in others])
        return values

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
