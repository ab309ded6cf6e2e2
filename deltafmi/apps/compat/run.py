"""Run one FMU through deltafmi's master the way the compatibility layout asks: the settings of
``X_ref.opt``, the interface of the tree (cs or me), the inputs of ``X_in.csv``, the variables of
``X_ref.csv`` recorded.

The master runs FMUs only, so the input signals come from a small component of our own: its
outputs replay the table (linear interpolation of real signals, as the rules ask; integers and
Booleans hold their last value; at a time written twice the later row applies from that time on),
built into an FMU like any other component and connected to the FMU's inputs. Co-Simulation runs
Jacobi (the FMU steps from t with the inputs at t); Model Exchange runs Gauss-Seidel with short
steps, each real input held at its value in the middle of the step.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from tempfile import TemporaryDirectory
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from deltafmi.errors import BadInput

from .files import RefOptions, Table

__all__ = ["run_fmu"]

#: the component names in the generated scenario
MODEL, INPUTS = "model", "inputs"
#: communication steps of a run whose ``X_ref.opt`` says StepSize 0 (a variable-step solver)
VARIABLE_STEP_POINTS = 500
#: communication steps per output interval of a Model Exchange run with inputs
ME_INPUT_SUBSTEPS = 10

_SOURCE = '''"""Input signals of a compatibility run, replayed from a table (written by deltafmi.apps.compat)."""
import enum

import numpy as np

from deltafmi.runtime import Component, Experiment, Output, Parameter
{enumerations}


class CompatInputs(Component):
    """Outputs y1, y2, ... replay the columns of ``table`` (time first, whitespace-separated):
    real ones interpolated linearly, integer and Boolean ones held; at a time listed twice the
    later row applies from that time on."""

    default_experiment = Experiment(stop=1.0, step=1e-3)
    table = Parameter("", type=str, description="Table file: time, then one column per output")
    lag = Parameter(0.0, unit="s", description="Real outputs replay the table this much later")
{declarations}
    _REAL = {real}

    def initialize(self, t):
        self._data = np.loadtxt(self.table, ndmin=2)

    def outputs(self, t):
        real = self._row(t - self.lag)
        held = self._row(t)
        for k, is_real in enumerate(self._REAL):
            name = f"y{{k + 1}}"
            setattr(self, name, float(real[k]) if is_real else type(getattr(self, name))(round(held[k])))

    def _row(self, t):
        data = self._data
        times = data[:, 0]
        i = int(np.searchsorted(times, t, side="right")) - 1
        i = min(max(i, 0), len(times) - 1)
        j = min(i + 1, len(times) - 1)
        w = (t - times[i]) / (times[j] - times[i]) if times[j] > times[i] and t > times[i] else 0.0
        real = data[i, 1:] + w * (data[j, 1:] - data[i, 1:])
        return np.where(self._REAL, real, data[i, 1:])

    def do_step(self, t, h):
        pass  # no state: the runtime evaluates the outputs at t + h
'''

_DECLARATION = {"real": "    y{k} = Output(0.0)", "int": "    y{k} = Output(0, type=int)",
                "bool": "    y{k} = Output(False, type=bool)"}
#: an Enumeration output: an IntEnum with the items, and the type name, of the FMU's input
_ENUMERATION = "_E{k} = enum.IntEnum('_E{k}', {items!r})\n_E{k}.__qualname__ = {name!r}\n"


def input_kind(variable: Any) -> Optional[str]:
    """``real``, ``int``, ``bool`` or ``enum`` for an input the table can drive; None for String,
    Binary and Clock inputs (no CSV value can stand for them) and for the FMI 3.0 types that a
    component's outputs do not have (Float32, the 8-, 16- and 64-bit integers): the master connects
    only equal types."""
    kind = variable.type
    if kind in ("Real", "Float64"):
        return "real"
    if kind == "Boolean":
        return "bool"
    if kind == "Enumeration" and variable.declaredType is not None:
        return "enum"
    if kind in ("Integer", "Int32"):
        return "int"
    return None


def inputs_component(kinds: Sequence[str], enumerations: Sequence[Any] = ()) -> Path:
    """The source of the input component with outputs of these kinds (``enumerations``: the
    FMU's declared type of each ``enum`` output, in order), kept in the build cache, one file per
    text, so that its FMU is built once."""
    from deltafmi.toolchain import cache_dir

    declarations, classes = [], []
    types = iter(enumerations)
    for k, kind in enumerate(kinds, start=1):
        if kind == "enum":
            declared = next(types)
            items = {item.name: int(item.value) for item in declared.items}
            classes.append(_ENUMERATION.format(k=k, items=items, name=declared.name))
            first = min(items.values())
            declarations.append(f"    y{k} = Output(_E{k}({first}), type=_E{k})")
        else:
            declarations.append(_DECLARATION[kind].format(k=k))
    text = _SOURCE.format(declarations="\n".join(declarations), real=tuple(kind == "real" for kind in kinds),
                          enumerations="\n" + "".join(classes) if classes else "")
    path = cache_dir() / "compat" / f"inputs_{hashlib.sha1(text.encode()).hexdigest()[:16]}" / "compat_inputs.py"
    if not path.is_file() or path.read_text() != text:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return path


def run_fmu(fmu: Path, interface: str, options: RefOptions, names: Sequence[str],
            inputs: Optional[Table] = None) -> Table:
    """Run ``fmu`` (``interface`` ``cs`` or ``me``) through the master with ``options`` and
    ``inputs`` (recording every StepSize; with inputs, Model Exchange communicates every tenth of
    it so that held inputs come close to the linear interpolation the rules ask); the result holds
    the variables ``names`` (FMI names; an FMI 3.0 array as one 2-D column). Raises
    :class:`~deltafmi.errors.SimulationError` when the run fails, and :class:`BadInput` when the
    input table names what is not an input of the FMU, or an input a table cannot drive."""
    from fmpy import read_model_description

    from deltafmi.master.simulate import simulate

    md = read_model_description(str(fmu), validate=False)
    variables = {v.name: v for v in md.modelVariables}
    step = options.step or (options.stop - options.start) / VARIABLE_STEP_POINTS
    # the master holds an ME FMU's inputs over a communication step; the rules interpolate them
    # linearly: ME steps a tenth of the output interval, recording every tenth step
    substeps = ME_INPUT_SUBSTEPS if interface == "me" and inputs is not None and inputs.columns else 1
    scenario: Dict[str, Any] = {
        "experiment": {"start": options.start, "stop": options.stop, "step": step / substeps,
                       "tolerance": options.rel_tol},
        "result": {"every": substeps},
        # Co-Simulation, Jacobi: the FMU steps from t with the inputs at t, as an importer sets
        # them before doStep. Model Exchange, Gauss-Seidel: the table goes first, so the FMU's
        # outputs recorded at t see the inputs at t (a held input leads by one short step)
        "master": {"algorithm": "jacobi" if interface == "cs" else "gauss-seidel"},
        "components": {MODEL: {"fmu": str(Path(fmu).resolve()), "interface": interface.upper()}},
        "connections": [],
        "outputs": [_pattern(variables, name) for name in names],
    }
    with TemporaryDirectory(prefix="deltafmi-compat-") as work:
        if inputs is not None and inputs.columns:
            source, table, connections = _input_source(inputs, variables, Path(work))
            # Model Exchange holds each input over a short step: the value at its midpoint makes
            # that hold second-order accurate for smooth signals (integer and Boolean ones jump on time)
            lag = step / substeps / 2 if interface == "me" else 0.0
            scenario["components"][INPUTS] = {"source": str(source), "interface": "CS",
                                              "parameters": {"table": str(table), "lag": lag}}
            scenario["connections"] = connections
        path = Path(work) / "compat_run.yaml"
        path.write_text(json.dumps(scenario, indent=1))
        result = simulate(path)
    # the master may stamp a time event a round-off after the grid point that follows it
    # (0.010000000000000002, then 0.01): the rules want a time that never decreases
    time = np.maximum.accumulate(np.asarray(result.time, dtype=float))
    columns = {}
    for name in names:
        elements = result.elements(f"{MODEL}.{name}") if _is_array(variables.get(name)) else [f"{MODEL}.{name}"]
        stacked = np.column_stack([np.asarray(result[e], dtype=float) for e in elements])
        columns[name] = stacked[:, 0] if not _is_array(variables.get(name)) else stacked
    return Table(time, columns)


def _input_source(inputs: Table, variables: Dict[str, Any], work: Path) -> Tuple[Path, Path, List[Dict[str, str]]]:
    """The input component, its table file and the connections to the model."""
    kinds: List[str] = []
    enumerations: List[Any] = []
    targets: List[str] = []
    values: List[np.ndarray] = []
    for name, column in inputs.columns.items():
        variable = variables.get(name)
        if variable is None or variable.causality != "input":
            raise BadInput(f"input file: {name!r} is not an input of the FMU")
        kind = input_kind(variable)
        if kind is None:
            raise BadInput(f"input file: {name!r} is a {variable.type} input, which deltafmi cannot drive "
                           "from a table (it drives Real/Float64, Integer/Int32, Boolean and Enumeration inputs)")
        block = column.reshape(len(inputs.time), -1)
        for i in range(block.shape[1]):
            kinds.append(kind)
            if kind == "enum":
                enumerations.append(variable.declaredType)
            targets.append(f"{name}[{i + 1}]" if _is_array(variable) else name)
            values.append(block[:, i])
    table = work / "inputs.txt"
    np.savetxt(table, np.column_stack([inputs.time, *values]), fmt="%.17g")
    connections = [{"from": f"{INPUTS}.y{k}", "to": f"{MODEL}.{target}"} for k, target in enumerate(targets, start=1)]
    return inputs_component(kinds, enumerations), table, connections


def _is_array(variable: Any) -> bool:
    return bool(getattr(variable, "dimensions", None))


def _pattern(variables: Dict[str, Any], name: str) -> str:
    return f"{MODEL}.{name}[*]" if _is_array(variables.get(name)) else f"{MODEL}.{name}"
