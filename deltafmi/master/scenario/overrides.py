"""Run options laid over a scenario: start values, stop time, communication step, tolerance, NaN.

One function, :func:`with_overrides`, serves ``deltafmi run --set/--stop/--step/--tolerance/
--allow-nan`` and the Python API (``deltafmi.simulate``). It returns a new :class:`Scenario`;
the values go into the components' ``parameters`` as if written in the YAML, so
:func:`~.resolve.resolve_system` checks them as it checks the file's (unknown variable with a
suggestion, output or calculated variable, type, element count), naming ``--set plant.z0``
instead of a file line.

Values are Python numbers, bools, strings or lists of them (a numpy array is a list), or
:class:`Text` typed on a command line (:func:`parse_assignment`): the resolver converts a
:class:`Text` by the FMU variable's type, a comma list for an array variable
(``plant.z0=0.1,0,-1.0``); one element is ``plant.z0[3]=-1.05``.

The tolerance rule: a component's relative tolerance is its ``solver: {rtol: ...}``, else the
scenario's ``experiment: {tolerance: ...}``, else the FMU's default experiment tolerance (ME: else
1e-6; CS: the FMU's own choice). ``tolerance=`` (``--tolerance``) replaces it for every component: an ME component's CVODE ``rtol`` and the
tolerance a CS component gets in ``fmi2SetupExperiment``. ``atol`` given in the YAML stays;
otherwise it follows rtol (rtol x the states' nominals). The adaptive master's
``master.adaptive.tolerance`` and ``master.loops.tolerance`` are other tolerances and stay.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import replace
from typing import Any, List, Mapping, Optional, Sequence, Tuple

from deltafmi.errors import BadInput, did_you_mean

from .spec import ComponentSpec, OutputSpec, Parameter, Scenario

__all__ = ["ALGORITHMS", "MAX_THREADS", "Text", "parse_assignment", "with_overrides", "split_name", "value_items",
           "from_text"]

#: the master's algorithms (``master.algorithm``, ``--algorithm``)
ALGORITHMS = ("gauss-seidel", "jacobi")
#: the most threads ``master.threads`` takes (the schema's maximum)
MAX_THREADS = 256

_NO_VALUES: Mapping[str, Any] = {}


class Text(str):
    """A value as typed on a command line; the resolver converts it by the variable's FMI type."""


def parse_assignment(text: str) -> Tuple[str, Text]:
    """``"plant.z0=0.1,0,-1"`` -> ``("plant.z0", Text("0.1,0,-1"))``; :class:`BadInput` when
    there is no ``=`` or no name before it."""
    name, sep, value = text.partition("=")
    name = name.strip()
    if not sep or not name:
        raise BadInput(f"--set {text!r}: expected NAME=VALUE, e.g. --set plant.z0=0.1,0,-1.0 or "
                       "--set controller.pole=10")
    return name, Text(value.strip())


def with_overrides(scenario: Scenario, values: Mapping[str, Any] = _NO_VALUES, *,
                   stop: Optional[float] = None, step: Optional[float] = None,
                   tolerance: Optional[float] = None, allow_nan: Optional[bool] = None,
                   algorithm: Optional[str] = None, record: Optional[Sequence[str]] = None,
                   fmi_version: Optional[int] = None, realtime: Optional[bool] = None,
                   speed: Optional[float] = None, behind: Optional[str] = None,
                   threads: Optional[int] = None, origin: str = "--set", cli: bool = False) -> Scenario:
    """``scenario`` with start values (``{"plant.z0": [0.1, 0, -1.0], "controller.pole": 10}``), the
    stop time, the communication step, every component's relative tolerance, the NaN check
    (``allow_nan``), the master's ``algorithm``, the recorded variables and the scenario's
    ``fmi_version`` (what its ``source:`` components are built as) replaced; None leaves a
    setting as it is.

    A value replaces the scenario's value of the same name, or is set after it (``plant.z0[3]``
    after the YAML's ``z0``). In a one-component scenario a name may leave out the component.
    ``record``: patterns of the variables to record (``"plant.z[*]"``, ``"Oscillator.*"``),
    replacing the scenario's ``outputs:``. ``realtime`` paces the run to the wall clock (or not),
    ``speed`` (simulated seconds per wall second; given alone, it paces the run) and ``behind``
    ("warn" or "error") replace ``master.realtime``'s; ``threads`` ``master.threads``. ``origin``
    names the values in diagnostics (``"--set plant.z0"``); ``cli``: messages name the command-line
    options (``--stop``, ``--record``).
    Raises :class:`BadInput` (exit code 2) for a stop, step or tolerance that is not a finite
    positive number, an unknown algorithm, or a name of no component; variables, types and
    patterns are checked when the scenario is resolved.
    """
    experiment = scenario.experiment
    if stop is not None:
        stop = _finite(stop, "stop time", "--stop" if cli else "")
        if stop <= experiment.start:
            raise BadInput(f"stop time {stop:g} s is not after the start time {experiment.start:g} s")
        experiment = replace(experiment, stop=stop)
    if step is not None:
        step = _finite(step, "communication step", "--step" if cli else "")
        if step <= 0:
            raise BadInput(f"communication step {step:g} s: must be greater than 0")
        experiment = replace(experiment, step=step)
    if tolerance is not None:
        tolerance = _finite(tolerance, "tolerance", "--tolerance" if cli else "")
        if tolerance <= 0:
            raise BadInput(f"tolerance {tolerance:g}: a relative tolerance must be greater than 0")
        experiment = replace(experiment, tolerance=tolerance)
    master = scenario.master if allow_nan is None else replace(scenario.master, allow_nan=bool(allow_nan))
    if algorithm is not None:
        if algorithm not in ALGORITHMS:
            raise BadInput(f"algorithm {algorithm!r}: use {' or '.join(map(repr, ALGORITHMS))}"
                           f"{did_you_mean(str(algorithm), ALGORITHMS)}")
        master = replace(master, algorithm=algorithm)
    master = _paced(master, realtime, speed, behind, cli)
    if threads is not None:
        if isinstance(threads, bool) or not isinstance(threads, int) or not 1 <= threads <= MAX_THREADS:
            raise BadInput(f"{'--threads ' if cli else 'threads '}{threads!r}: a whole number of threads from 1 to "
                           f"{MAX_THREADS}")
        master = replace(master, threads=threads)
    outputs = scenario.outputs
    if record is not None:
        if isinstance(record, str):
            record = [record]  # one pattern, not its letters
        outputs = tuple(OutputSpec(str(pattern), None, f"--record {pattern}" if cli else f"record {pattern!r}")
                        for pattern in record)
    added: dict = {spec.name: [] for spec in scenario.components}
    for name, value in values.items():
        component, variable = split_name(scenario, str(name), origin)
        added[component].append(Parameter(variable, _plain(value), None, f"{origin} {name}"))
    components = tuple(_component(spec, added[spec.name], tolerance) for spec in scenario.components)
    if fmi_version is not None:
        if fmi_version not in (2, 3):
            raise BadInput(f"FMI version {fmi_version!r}: use 2 or 3")
        scenario = replace(scenario, fmi_version=int(fmi_version))
    return replace(scenario, experiment=experiment, master=master, components=components, outputs=outputs)


def _paced(master: Any, realtime: Optional[bool], speed: Optional[float], behind: Optional[str], cli: bool) -> Any:
    """``master`` with its real-time settings replaced (see :func:`with_overrides`)."""
    paced = master.realtime
    if speed is not None:
        speed = _finite(speed, "real-time speed", "--speed" if cli else "")
        if speed <= 0:
            raise BadInput(f"real-time speed {speed:g}: must be greater than 0 (1: real time, 2: twice as fast)")
        paced = replace(paced, speed=speed, enabled=True if realtime is None else bool(realtime))
    if realtime is not None:
        paced = replace(paced, enabled=bool(realtime))
    if behind is not None:
        if behind not in ("warn", "error"):
            raise BadInput(f"behind {behind!r}: use 'warn' or 'error'")
        paced = replace(paced, behind=behind)
    return master if paced == master.realtime else replace(master, realtime=paced)


def value_items(value: Any, count: int) -> List[Any]:
    """The elements of a start value for a variable of ``count`` scalars: a list as is, a
    :class:`Text` of a vector split at commas (``"0.1,0,-1"`` or ``"[0.1, 0, -1]"``)."""
    if isinstance(value, list):
        return value
    if isinstance(value, Text) and count > 1:
        inner = value[1:-1] if value.startswith("[") and value.endswith("]") else value
        return [Text(item.strip()) for item in inner.split(",")]
    return [value]


def from_text(text: str, kind: str) -> Any:
    """``text`` as a value of FMI type ``kind`` (Real, Integer, Boolean, String; ``Enumeration``:
    an item name or its number); ValueError with a short reason when it is not one."""
    if kind == "String":
        return str(text)
    if kind == "Boolean":
        lowered = text.lower()
        if lowered in ("true", "1", "yes", "on"):
            return True
        if lowered in ("false", "0", "no", "off"):
            return False
        raise ValueError(f"{text!r} is not a Boolean (true or false)")
    if kind in ("Integer", "Enumeration"):
        try:
            return int(text)
        except ValueError:
            if kind == "Enumeration":
                return str(text)
            raise ValueError(f"{text!r} is not an integer") from None
    try:
        number = float(text)
    except ValueError:
        raise ValueError(f"{text!r} is not a number") from None
    if math.isnan(number):
        raise ValueError(f"{text!r} is not a number")
    return number


def _finite(value: Any, what: str, option: str) -> float:
    """``value`` as a finite float; ``option``: the command-line option to name, if any."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise BadInput(f"{what} {value!r}: not a number") from None
    value = float(value)
    if not math.isfinite(value):
        raise BadInput(f"{what} {value!r}: must be a finite number" + (f" ({option})" if option else ""))
    return value


def split_name(scenario: Scenario, name: str, origin: str) -> Tuple[str, str]:
    """``comp.var`` -> (comp, var); in a one-component scenario also a bare ``var``;
    :class:`BadInput` naming ``origin`` for a name of no component."""
    names = [spec.name for spec in scenario.components]
    component, dot, variable = name.partition(".")
    if dot and component in names and variable:
        return component, variable
    if len(names) == 1 and not (dot and did_you_mean(component, names)):  # else a misspelt component
        return names[0], name
    if not dot or not variable:
        raise BadInput(f"{origin} {name}: expected component.variable (components: {', '.join(names)})")
    raise BadInput(f"{origin} {name}: the scenario has no component '{component}'"
                   f"{did_you_mean(component, names)} (components: {', '.join(names)})")


def _plain(value: Any) -> Any:
    """API values as the YAML gives them: numpy scalars and arrays, tuples -> Python values, lists."""
    if isinstance(value, str):
        return value
    if hasattr(value, "tolist"):  # numpy array or scalar
        value = value.tolist()
    if isinstance(value, tuple):
        value = list(value)
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _component(spec: ComponentSpec, values: List[Parameter], tolerance: Optional[float]) -> ComponentSpec:
    if not values and tolerance is None:
        return spec
    replaced = {p.name for p in values}
    parameters = tuple(p for p in spec.parameters if p.name not in replaced) + tuple(values)
    solver = spec.solver if tolerance is None else {**spec.solver, "rtol": tolerance}
    return replace(spec, parameters=parameters, solver=solver)
