"""Linearization of one Model Exchange FMU at an operating point: continuous A, B, C, D.

The FMU is instantiated at (states, inputs, time), optionally brought to an equilibrium first
(:mod:`.equilibrium`), and differentiated with its directional derivatives (central differences
when it provides none; :mod:`deltafmi.master.stepping.jacobians`).
"""
from __future__ import annotations

import math
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence

import fmpy
import numpy as np
from fmpy.fmi2 import FMU2Model
from fmpy.fmi3 import FMU3Model

from deltafmi.errors import BadInput, did_you_mean

from ..scenario.fmu_checks import binary_problem
from ..scenario.modelinfo import ModelInfo, UnknownVariable, model_info
from ..stepping.jacobians import REAL_TYPES, FmuJacobian, Key, scalar_key
from ..stepping.unit_base import instantiation_reason, logger_callbacks
from .equilibrium import find_equilibrium
from .linear_model import LinearModel

__all__ = ["linearize_fmu"]


def linearize_fmu(fmu: Path, *, start_values: Optional[Mapping[str, Any]] = None,
                  states: Optional[Mapping[str, Any]] = None, time: float = 0.0, rest: bool = False,
                  free: Sequence[str] = (), hold: Optional[Mapping[str, Any]] = None,
                  inputs: Sequence[str] = (), outputs: Sequence[str] = (), label: Optional[str] = None) -> LinearModel:
    """Continuous A, B, C, D of the Model Exchange FMU at ``fmu`` at an operating point.

    Args:
        fmu: the .fmu file.
        start_values: parameters and start values (name -> value; arrays take a list), set
            before initialization.
        states: continuous states to set after initialization (name -> value or list).
        time: the time of the operating point.
        rest: move to an equilibrium first: der(x) = 0, solving for the ``free`` inputs (default:
            every continuous Real input) and, with ``hold``, the states as well.
        hold: outputs held at given values at the equilibrium (implies ``rest``).
        inputs, outputs: the model's inputs and outputs (names or array names); default: every
            continuous Real input and output.
        label: how messages name the FMU (default: its path), e.g. the source it was built from.

    Raises:
        BadInput: unknown names, wrong values, no Model Exchange interface, no equilibrium.
    """
    if not math.isfinite(time):
        raise BadInput(f"--at {time:g}: the operating point's time must be a finite number")
    info = _info(fmu)
    where = label or str(fmu)
    if info.md.modelExchange is None:
        raise BadInput(f"'{where}' offers no Model Exchange interface: linearizing an FMU needs its equations")
    missing = binary_problem(fmu, [info.model_identifier("ME")], info.fmi3)
    if missing:
        raise BadInput(f"'{where}' cannot run here: {missing}")
    directory = tempfile.mkdtemp(prefix="deltafmi-linearize-")
    model = None
    errors: List[str] = []
    said = lambda status, category, text: _said(where, status, text, errors)  # noqa: E731
    try:
        model = (FMU3Model if info.fmi3 else FMU2Model)(
            guid=info.md.guid, unzipDirectory=fmpy.extract(str(fmu), directory),
            modelIdentifier=info.model_identifier("ME"), instanceName="linearize")
        try:
            if info.fmi3:
                model.instantiate(logMessage=lambda env, status, category, text: said(status, category, _text(text)))
            else:
                model.instantiate(callbacks=logger_callbacks(said), loggingOn=False)
        except Exception:  # noqa: BLE001 - fmpy raises a plain Exception when instantiation returns NULL
            model = None  # nothing to free
            call = "fmi3InstantiateModelExchange" if info.fmi3 else "fmi2Instantiate"
            raise BadInput(f"'{where}': {call} failed: "
                           f"{instantiation_reason([(3, '', text) for text in errors])}") from None
        if info.fmi3:
            _set_all(model, info, start_values or {}, where)
            model.enterInitializationMode(startTime=time)
            model.exitInitializationMode()
            while model.updateDiscreteStates()[0]:
                pass
        else:
            model.setupExperiment(startTime=time)
            _set_all(model, info, start_values or {}, where)
            model.enterInitializationMode()
            model.exitInitializationMode()
            while model.newDiscreteStates()[0]:
                pass
        model.enterContinuousTimeMode()
        jac = FmuJacobian(model, info)
        state_names = jac.state_names
        if states:
            x = jac.get_states()
            for name, value in states.items():
                names = _expand(info, name, where)
                values = _values(name, value, len(names))
                for n, v in zip(names, values):
                    if n not in state_names:
                        raise BadInput(f"'{n}' is not a continuous state of '{where}'"
                                       f"{did_you_mean(n, state_names)}")
                    x[state_names.index(n)] = float(v)
            jac.set_states(x)
        real_inputs = [n for n, v in info.variables.items()
                       if v.causality == "input" and v.type in REAL_TYPES and v.variability == "continuous"]
        real_outputs = [n for n, v in info.variables.items()
                        if v.causality == "output" and v.type in REAL_TYPES and v.variability == "continuous"]
        notes = []
        if rest or hold:
            free_names = _expand_all(info, free, where) if free else real_inputs
            targets = {}
            for name, value in (hold or {}).items():
                names = _expand(info, name, where)
                targets.update({scalar_key(info, n): float(v)
                                for n, v in zip(names, _values(name, value, len(names)))})
            try:
                found = find_equilibrium(jac, [scalar_key(info, n) for n in free_names], targets)
            except ValueError as exc:
                raise BadInput(f"'{where}': {exc}") from None
            notes.append(f"equilibrium: largest |der(x)| {found.residual:.3g}; "
                         + ", ".join(f"{n} = {v:.9g}" for n, v in zip(free_names, found.inputs)))
        input_names = _expand_all(info, inputs, where) if inputs else real_inputs
        output_names = _expand_all(info, outputs, where) if outputs else real_outputs
        u_keys = [_real_key(info, n, "input", where) for n in input_names]
        y_keys = [_real_key(info, n, "output", where) for n in output_names]
        nx = jac.nx
        J = jac.block(jac.derivatives + y_keys, jac.states + u_keys)
        return LinearModel(J[:nx, :nx], J[:nx, nx:], J[nx:, :nx], J[nx:, nx:], state_names, input_names,
                           output_names, None, time, jac.get_states(), jac.values.get(u_keys),
                           jac.values.get(y_keys), str(fmu), notes)
    except fmpy.fmi1.FMICallException as exc:
        last = errors[-1].strip().splitlines()[-1] if errors and errors[-1].strip() else ""
        raise BadInput(f"'{where}': {exc}" + (f": {last}" if last else "")) from None
    finally:
        if model is not None:
            for call in (model.terminate, model.freeInstance):
                try:
                    call()
                except Exception:  # noqa: BLE001 - cleaning up after a failure must not hide it
                    pass
        shutil.rmtree(directory, ignore_errors=True)


def _said(where: str, status: int, text: str, errors: List[str]) -> None:
    """The FMU's logger: warnings to stderr, errors kept for the failure message."""
    if status >= 2:
        errors.append(text)
    elif status == 1:
        sys.stderr.write(f"warning: {where}: {text}\n")


def _describe(variable: Any) -> str:
    return f"a {variable.type} {variable.causality}"


def _info(fmu: Path) -> ModelInfo:
    if not Path(fmu).is_file():
        raise BadInput(f"FMU '{fmu}' not found")
    try:
        return model_info(str(fmu))
    except Exception as exc:  # noqa: BLE001 - any unreadable FMU is a user error here
        raise BadInput(f"cannot read FMU '{fmu}': {exc}") from None


def _expand(info: ModelInfo, name: str, where: str) -> List[str]:
    try:
        return info.expand(name)
    except UnknownVariable as exc:
        raise BadInput(f"'{where}' has no variable '{exc.reference}'{did_you_mean(exc.reference, exc.names)}") from None


def _expand_all(info: ModelInfo, names: Sequence[str], where: str) -> List[str]:
    return [n for name in names for n in _expand(info, name, where)]


def _values(name: str, value: Any, count: int) -> list:
    values = list(value) if isinstance(value, (list, tuple, np.ndarray)) else [value]
    if len(values) != count:
        raise BadInput(f"'{name}' has {count} element(s) but {len(values)} value(s) were given")
    return values


def _real_key(info: ModelInfo, name: str, causality: str, where: str) -> Key:
    variable = info.variables[name]
    if variable.type not in REAL_TYPES or variable.causality != causality:
        raise BadInput(f"'{name}' of '{where}' is {_describe(variable)}; linearize takes Real {causality}s")
    return scalar_key(info, name)


def _set_all(model: Any, info: ModelInfo, start_values: Mapping[str, Any], where: str) -> None:
    """Set parameters and start values before initialization. FMI 3.0 sets an array whole: its
    elements not given keep their start values from the modelDescription."""
    given: Dict[str, Any] = {}
    for name, value in start_values.items():
        names = _expand(info, name, where)
        given.update(zip(names, _values(name, value, len(names))))
    by_variable: Dict[int, List[str]] = {}
    for name in given:
        by_variable.setdefault(info.variables[name].valueReference, []).append(name)
    for vr, names in by_variable.items():
        if info.fmi3 and info.sizes[vr] > 1:
            elements = [n for n, v in info.variables.items() if v.valueReference == vr]
            values = [given.get(n, info.variables[n].start) for n in elements]
            _set(model, info, elements[0], [vr], values, where)
        else:
            for name in names:
                _set(model, info, name, [info.variables[name].valueReference], [given[name]], where)


def _set(model: Any, info: ModelInfo, name: str, vrs: List[int], values: List[Any], where: str) -> None:
    variable = info.variables[name]
    kind = variable.type
    try:
        if kind in REAL_TYPES or kind == "Float32":
            converted, setter = [float(v) for v in values], kind if info.fmi3 else "Real"
        elif kind == "Boolean":
            converted, setter = [_boolean(v) for v in values], "Boolean"
        elif kind == "String":
            converted, setter = [str(v) for v in values], "String"
        else:  # Integer, Enumeration, the FMI 3.0 integers
            converted = [int(v) for v in values]
            setter = ("Int64" if kind == "Enumeration" else kind) if info.fmi3 else "Integer"
        getattr(model, f"set{setter}")(vrs, converted)
    except (TypeError, ValueError):
        raise BadInput(f"'{name}' of '{where}' is {kind}: cannot take {values[0] if len(values) == 1 else values!r}") \
            from None
    except fmpy.fmi1.FMICallException:
        raise BadInput(f"'{name}' of '{where}' ({variable.causality}, {variable.variability}) cannot be set "
                       "before initialization") from None


def _boolean(value: Any) -> bool:
    if isinstance(value, str):
        if value.strip().lower() not in ("true", "false", "1", "0"):
            raise ValueError(value)
        return value.strip().lower() in ("true", "1")
    return bool(value)


def _text(message: Any) -> str:
    return message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message or "")
