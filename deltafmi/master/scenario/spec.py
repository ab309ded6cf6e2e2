"""Scenario files: YAML -> checked against ``scenario.schema.json`` -> :class:`Scenario` objects.

This module knows nothing of FMUs; :mod:`deltafmi.master.scenario.resolve` checks names, types and units
against each FMU's modelDescription.
"""
from __future__ import annotations

import json
import math
from dataclasses import field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, List, Optional, Tuple

from deltafmi.errors import Diagnostic, ScenarioError

from .records import record
from .schema_check import dotted, load_mapping, read_document, schema_diagnostics
from .line_map import LineMap

if TYPE_CHECKING:
    import jsonschema

__all__ = ["Adaptive", "ComponentSpec", "ExportSpec", "ConnectionSpec", "Experiment", "LiveSpec", "Loops",
           "MasterSettings",
           "OutputSpec", "Parameter", "ResultSettings", "Scenario", "StreamSpec", "grid_steps", "load_scenario",
           "parse_scenario", "scenario_from_data", "schema"]


@record
class Experiment:
    """Time span and communication step [s]; ``tolerance``: the relative tolerance of every
    component that gives no ``solver.rtol`` of its own (None: each FMU's default)."""

    start: float
    stop: float
    step: float
    tolerance: Optional[float] = None


#: communication steps a fixed-step run may take unless ``master.max_steps`` allows more: a step
#: given a thousand times too small (1e-12 s) asks for more steps than a run ends in a day
MAX_STEPS = 1_000_000_000


def too_many_steps(start: float, stop: float, step: float, limit: int) -> Optional[str]:
    """Why a fixed-step run from ``start`` to ``stop`` is refused (more than ``limit`` steps), or None."""
    steps = (stop - start) / step
    if steps <= limit:
        return None
    if not math.isfinite(steps) or steps > 2.0 ** 53:  # a span of 1e308 s: more steps than a float counts
        return (f"{stop - start:g} s in steps of {step:g} s: more communication steps than a run can count; "
                "shorten the span or lengthen the step")
    return (f"{steps:.3g} communication steps ({stop - start:g} s in steps of {step:g} s), more than the "
            f"{limit:.3g} a run may take; to run them all, raise the limit "
            f"(master: {{max_steps: {math.ceil(steps):d}}})")


def grid_steps(start: float, stop: float, step: float) -> int:
    """How many communication steps a fixed-step run from ``start`` to ``stop`` takes: point k is
    ``start + k * step`` for k < the count, the last one ``stop`` (a shorter last step when the
    span is not a whole number of steps)."""
    return max(1, math.ceil((stop - start) / step - 1e-9))


@record
class Adaptive:
    """Adaptive communication step with rollback (needs fmi2Get/SetFMUstate in every FMU)."""

    enabled: bool = False
    tolerance: float = 1e-4
    abs_tolerance: float = 1e-6
    min_step: Optional[float] = None
    max_step: Optional[float] = None
    error_estimate: str = "double-step"


@record
class Loops:
    """How the master solves algebraic loops (see :mod:`deltafmi.master.stepping.algebraic_loops`)."""

    method: str = "newton"
    tolerance: float = 1e-10
    fixed_point_iterations: int = 5
    max_iterations: int = 50
    jacobian: str = "auto"


@record
class Realtime:
    """Pacing to the wall clock (see :mod:`deltafmi.master.live.pacing`)."""

    enabled: bool = False
    #: simulated seconds per wall-clock second
    speed: float = 1.0
    #: "warn" or "error" when the run falls a whole communication step behind
    behind: str = "warn"
    #: lateness [s] counted as an overrun; None: a quarter of the paced step
    tolerance: Optional[float] = None
    #: wall seconds before a deadline spent polling the clock rather than sleeping; None: 0.05 ms
    #: without a lead, 0 with one (live/pacing.py)
    spin: Optional[float] = None
    #: a real-time priority (SCHED_FIFO, 1-99) for the thread that paces; None: its usual one
    priority: Optional[int] = None
    #: wall seconds a point may be released before its time (0: at its time); None: 0.5 ms for a
    #: paced step shorter than 0.1 ms of wall time, else 0 (live/pacing.py)
    lead: Optional[float] = None


@record
class MasterSettings:
    """How the master steps the components."""

    algorithm: str = "gauss-seidel"
    adaptive: Adaptive = field(default_factory=Adaptive)
    loops: Loops = field(default_factory=Loops)
    #: False: a recorded or connected Real that becomes NaN or infinite stops the run (exit 1)
    allow_nan: bool = False
    realtime: Realtime = field(default_factory=Realtime)
    #: the most communication steps a fixed-step run may take (:data:`MAX_STEPS`)
    max_steps: int = MAX_STEPS
    #: threads stepping the units that do not depend on each other within a step (1: the master's only)
    threads: int = 1


@record
class Parameter:
    """A start value given in the scenario; ``value`` may be a list for an array variable."""

    name: str
    value: Any
    line: Optional[int]
    #: where the value comes from when not the scenario file (``"--set plant.z0"``)
    origin: Optional[str] = None


@record
class ExportSpec:
    """``exports:``: patterns of the variables a scenario exported as one FMU offers, by kind;
    None keeps that kind's default (see :mod:`deltafmi.master.system_fmu`)."""

    outputs: Optional[Tuple[OutputSpec, ...]] = None
    inputs: Optional[Tuple[OutputSpec, ...]] = None
    parameters: Optional[Tuple[OutputSpec, ...]] = None
    line: Optional[int] = None


@record
class ComponentSpec:
    """One FMU instance of the scenario, as written (paths not yet resolved)."""

    name: str
    line: Optional[int]
    fmu: Optional[str] = None
    source: Optional[str] = None
    interface: Optional[str] = None
    #: the FMI version to build ``source`` as (2 or 3); None: the scenario's
    fmi_version: Optional[int] = None
    parameters: Tuple[Parameter, ...] = ()
    solver: Dict[str, Any] = field(default_factory=dict)
    step_multiple: int = 1
    #: files the FMU built from ``source`` carries in its resources/ (as written: relative to the
    #: scenario's folder, see :meth:`Scenario.resource_paths`)
    resources: Tuple[str, ...] = ()


@record
class ConnectionSpec:
    """``to = factor * from + offset``; ``from``/``to`` are ``comp.var`` references (ranges allowed)."""

    source: str
    target: str
    factor: float
    offset: float
    line: Optional[int]
    source_line: Optional[int]
    target_line: Optional[int]
    #: ``factor`` or ``offset`` written in the scenario (whatever its value): a deliberate unit conversion
    converts: bool = False

    @property
    def has_transform(self) -> bool:
        """True when the connection scales or shifts the value."""
        return self.factor != 1.0 or self.offset != 0.0


@record
class OutputSpec:
    """A pattern of variables to record."""

    pattern: str
    line: Optional[int]
    #: where the pattern comes from when not the scenario file (``"--record"``)
    origin: Optional[str] = None


@record
class LiveSignal:
    """One signal of a live source: a Real output of the scenario's ``live:`` component."""

    name: str
    line: Optional[int]
    start: float = 0.0
    unit: str = ""
    description: str = ""
    #: the source's own settings of the signal (a joystick's axis, scale, ...)
    options: Dict[str, Any] = field(default_factory=dict)


@record
class LiveSpec:
    """A live input source (``live:`` entry): ``kind`` "udp" or "joystick" and its settings."""

    name: str
    line: Optional[int]
    kind: str
    settings: Dict[str, Any]
    signals: Tuple[LiveSignal, ...]
    #: wall seconds without new data before the source is reported silent; None: never
    timeout: Optional[float] = None


@record
class StreamSpec:
    """A live output (``streams:`` entry): ``kind`` "udp" (to ``target``, host:port) or "plot"."""

    line: Optional[int]
    kind: str
    signals: Tuple[str, ...]
    target: str = ""
    #: datagrams per simulated second; None: the kind's default
    rate: Optional[float] = None
    format: str = "dfmi"
    byte_order: str = "little"
    window: float = 10.0


@record
class ResultSettings:
    """Where and how often results are written."""

    file: Path
    format: str = "csv"
    every: int = 1


@record
class Scenario:
    """A parsed scenario file. ``path`` is the file as named by the user (used in diagnostics)."""

    path: Path
    experiment: Experiment
    master: MasterSettings
    components: Tuple[ComponentSpec, ...]
    connections: Tuple[ConnectionSpec, ...]
    outputs: Tuple[OutputSpec, ...]
    result: ResultSettings
    description: str = ""
    #: one FMU run on its own (``deltafmi run Model.fmu``): its inputs have nothing to connect
    #: to, so they stay at their start values without a warning
    single_fmu: bool = False
    #: the FMI version (2 or 3) its components given by ``source:`` are built as, unless a
    #: component says otherwise; None: 2
    fmi_version: Optional[int] = None
    #: live input sources and live output streams (see :mod:`deltafmi.master.live`)
    live: Tuple[LiveSpec, ...] = ()
    streams: Tuple[StreamSpec, ...] = ()
    exports: ExportSpec = ExportSpec()

    @property
    def directory(self) -> Path:
        """Folder of the scenario file: relative paths in it are relative to this folder."""
        return self.path.parent

    def resource_paths(self, spec: ComponentSpec) -> List[Path]:
        """The files of ``spec.resources``, relative ones taken from the scenario's folder."""
        return [self.directory / name for name in spec.resources]

    def component(self, name: str) -> ComponentSpec:
        """The component called ``name`` (KeyError if none)."""
        for spec in self.components:
            if spec.name == name:
                return spec
        raise KeyError(name)


@lru_cache(maxsize=1)
def schema() -> Dict[str, Any]:
    """The JSON Schema of scenario files (shipped as ``deltafmi/master/scenario/scenario.schema.json``)."""
    text = Path(__file__).with_name("scenario.schema.json").read_text()  # not importlib.resources: slow to import
    return json.loads(text)


def load_scenario(path: str | Path) -> Scenario:
    """Read, schema-check and parse a scenario file, or the shipped example of that name
    (``"delta_tracking"``). Raises :class:`ScenarioError` (exit code 2)."""
    from deltafmi.shipped import find_input
    path = find_input(path, "scenario")
    return parse_scenario(read_document(path, "scenario"), path)


def parse_scenario(text: str, path: Path) -> Scenario:
    """Parse scenario ``text``; ``path`` names it in diagnostics and anchors relative paths."""
    data, lines = load_mapping(text, str(path), "scenario")
    return scenario_from_data(data, lines, path)


def scenario_from_data(data: Dict[str, Any], lines: LineMap, path: Path) -> Scenario:
    """Check scenario ``data`` (shaped as a YAML scenario, ``lines`` locating its values) and
    build the :class:`Scenario`; other formats (SSP) come in through here."""
    file = str(path)
    problems = schema_errors(data, lines, file)
    problems += _semantic_errors(data, lines, file)
    if problems:
        raise ScenarioError(problems)
    return _build(data, lines, path)


def schema_errors(data: Any, lines: LineMap, file: str) -> List[Diagnostic]:
    """Schema violations of ``data`` as located diagnostics, with suggestions for misspellings."""
    return schema_diagnostics(data, lines, file, schema(), "scenario", _scenario_wording)


def _scenario_wording(error: jsonschema.ValidationError, lines: LineMap, file: str) -> Optional[List[Diagnostic]]:
    path = tuple(error.absolute_path)
    if error.validator == "oneOf" and len(path) == 2 and path[0] == "components":
        return [Diagnostic(file, lines.line(path),
                           f"component '{path[1]}' needs exactly one of 'fmu' (a file) or 'source' (a .py to build)")]
    if "propertyNames" in error.absolute_schema_path:
        return [Diagnostic(file, lines.key_line(path + (error.instance,)),
                           f"component name '{error.instance}' must be an identifier (letters, digits, _)")]
    if error.validator == "pattern" and path and path[0] in ("connections", "outputs"):
        return [Diagnostic(file, lines.line(path),
                           f"{dotted(path)}: '{error.instance}' is not a 'component.variable' reference")]
    return None


def _semantic_errors(data: Dict[str, Any], lines: LineMap, file: str) -> List[Diagnostic]:
    """Checks the schema cannot express (relations between numbers)."""
    found = []
    exp = data.get("experiment")
    infinite = set()
    for key in ("start", "stop", "step", "tolerance") if isinstance(exp, dict) else ():
        if _number(exp.get(key)) and not math.isfinite(exp[key]):
            infinite.add(key)
            found.append(Diagnostic(file, lines.line(("experiment", key)),
                                    f"experiment.{key} ({exp[key]}) must be a finite number"))
    if infinite:
        return found
    if isinstance(exp, dict) and _number(exp.get("stop")) and _number(exp.get("start", 0.0)):
        if exp["stop"] <= exp.get("start", 0.0):
            found.append(Diagnostic(file, lines.line(("experiment", "stop")),
                                    f"experiment.stop ({exp['stop']}) must be greater than start ({exp.get('start', 0.0)})"))
    master = data.get("master") if isinstance(data.get("master"), dict) else {}
    adaptive = master.get("adaptive")
    adaptive_on = isinstance(adaptive, dict) and adaptive.get("enabled")
    if isinstance(exp, dict) and _number(exp.get("start", 0.0)) and _number(exp.get("stop")) \
            and _number(exp.get("step")) and exp["step"] > 0 and not adaptive_on:
        limit = master.get("max_steps", MAX_STEPS)
        why = too_many_steps(float(exp.get("start", 0.0)), float(exp["stop"]), float(exp["step"]),
                             limit if _number(limit) else MAX_STEPS)
        if why:
            found.append(Diagnostic(file, lines.line(("experiment", "step")), f"experiment.step: {why}"))
    if isinstance(adaptive, dict) and _number(adaptive.get("min_step")) and _number(adaptive.get("max_step")):
        if adaptive["min_step"] > adaptive["max_step"]:
            found.append(Diagnostic(file, lines.line(("master", "adaptive", "min_step")),
                                    "master.adaptive.min_step must not exceed max_step"))
    return found + _live_errors(data, lines, file) + _resource_errors(data, lines, Path(file))


def _resource_errors(data: Dict[str, Any], lines: LineMap, path: Path) -> List[Diagnostic]:
    """A component's ``resources``: files next to the scenario (or absolute) that exist, and only
    for a component built from ``source`` (an ``fmu`` carries its own resources)."""
    found = []
    components = data.get("components")
    for name, spec in components.items() if isinstance(components, dict) else ():
        if not isinstance(spec, dict) or not isinstance(spec.get("resources"), list):
            continue
        if "fmu" in spec:
            found.append(Diagnostic(str(path), lines.key_line(("components", name, "resources")),
                                    f"component '{name}': resources go into an FMU built from 'source'; "
                                    "an FMU given by 'fmu' carries its own"))
            continue
        for i, item in enumerate(spec["resources"]):
            if isinstance(item, str) and not (path.parent / item).is_file():
                found.append(Diagnostic(str(path), lines.line(("components", name, "resources", i)),
                                        f"component '{name}': resource '{item}' not found (looked in "
                                        f"{path.parent.resolve()})"))
    return found


def _live_errors(data: Dict[str, Any], lines: LineMap, file: str) -> List[Diagnostic]:
    """What live sources need that the schema cannot say: a joystick signal names its axis, a
    UDP signal has no joystick settings, the results keep every step (for ``--replay``), and
    a source's name is not a component's."""
    found = []
    live = data.get("live") or {}
    components = data.get("components") or {}
    for name, source in live.items() if isinstance(live, dict) else ():
        if not isinstance(source, dict) or not isinstance(source.get("signals"), dict):
            continue
        if name in components:
            found.append(Diagnostic(file, lines.key_line(("live", name)),
                                    f"live source '{name}': a component has that name; give the source another"))
        joystick = "joystick" in source
        for signal, options in source["signals"].items():
            options = options or {}
            where = ("live", name, "signals", signal)
            if joystick and "start" in options:
                found.append(Diagnostic(file, lines.line(where + ("start",)),
                                        f"live source '{name}': signal '{signal}': a joystick signal has no start "
                                        "value: it starts where the stick is when the device opens (centred, "
                                        "for a session that does not say)"))
            if joystick and "axis" not in options:
                found.append(Diagnostic(file, lines.key_line(where),
                                        f"live source '{name}': signal '{signal}' needs the joystick axis it "
                                        "reads (axis: ABS_X, ABS_Y, ...)"))
            extra = sorted(set(options) & set(_JOYSTICK_ONLY)) if not joystick else []
            if extra:
                found.append(Diagnostic(file, lines.key_line(where),
                                        f"live source '{name}': signal '{signal}': {', '.join(extra)}: settings of "
                                        "a joystick's axes, not of a UDP source"))
    result = data.get("result") or {}
    if live and isinstance(result, dict) and _number(result.get("every")) and result["every"] > 1:
        found.append(Diagnostic(file, lines.line(("result", "every")),
                                "result.every must be 1 with live sources: every communication step is "
                                "recorded so that --replay can repeat the run"))
    return found


_JOYSTICK_ONLY = ("axis", "scale", "offset", "dead_band", "rate_limit", "invert")


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _build(data: Dict[str, Any], lines: LineMap, path: Path) -> Scenario:
    exp = data["experiment"]
    tolerance = float(exp["tolerance"]) if "tolerance" in exp else None
    experiment = Experiment(float(exp.get("start", 0.0)), float(exp["stop"]), float(exp["step"]), tolerance)
    # the scenario's tolerance is each component's rtol unless it gives its own
    rtol = {} if tolerance is None else {"rtol": tolerance}
    master_data = data.get("master") or {}
    adaptive = Adaptive(**master_data.get("adaptive", {}))
    master = MasterSettings(master_data.get("algorithm", "gauss-seidel"), adaptive,
                            Loops(**master_data.get("loops", {})), bool(master_data.get("allow_nan", False)),
                            _realtime(master_data.get("realtime", False)),
                            int(master_data.get("max_steps", MAX_STEPS)), int(master_data.get("threads", 1)))
    components = tuple(
        ComponentSpec(
            name=name,
            line=lines.key_line(("components", name)),
            fmu=spec.get("fmu"),
            source=spec.get("source"),
            interface=spec.get("interface"),
            fmi_version=spec.get("fmi_version"),
            parameters=tuple(Parameter(k, v, lines.key_line(("components", name, "parameters", k)))
                             for k, v in (spec.get("parameters") or {}).items()),
            solver={**rtol, **(spec.get("solver") or {})},
            step_multiple=int(spec.get("step_multiple", 1)),
            resources=tuple(spec.get("resources") or ()),
        )
        for name, spec in data["components"].items())
    connections = tuple(
        ConnectionSpec(
            source=c["from"], target=c["to"],
            factor=float(c.get("factor", 1.0)), offset=float(c.get("offset", 0.0)),
            line=lines.line(("connections", i)),
            source_line=lines.line(("connections", i, "from")),
            target_line=lines.line(("connections", i, "to")),
            converts="factor" in c or "offset" in c)
        for i, c in enumerate(data.get("connections") or []))
    outputs = tuple(OutputSpec(p, lines.line(("outputs", i))) for i, p in enumerate(data.get("outputs") or []))
    result_data = data.get("result") or {}
    if "file" in result_data:
        result_file = Path(result_data["file"])
        if not result_file.is_absolute():
            result_file = path.parent / result_file
    else:
        result_file = Path(path.stem + ".csv")
    result = ResultSettings(result_file, result_data.get("format", "csv"), int(result_data.get("every", 1)))
    return Scenario(path, experiment, master, components, connections, outputs, result,
                    data.get("description", ""), fmi_version=data.get("fmi_version"),
                    live=tuple(_live(name, source, lines) for name, source in (data.get("live") or {}).items()),
                    streams=tuple(_stream(i, stream, lines) for i, stream in enumerate(data.get("streams") or [])),
                    exports=_exports(data.get("exports"), lines))


def _exports(data: Optional[Dict[str, Any]], lines: LineMap) -> ExportSpec:
    """``exports:`` as patterns with their lines."""
    if not data:
        return ExportSpec()
    kinds = {kind: tuple(OutputSpec(pattern, lines.line(("exports", kind, i)))
                         for i, pattern in enumerate(data[kind]))
             for kind in ("outputs", "inputs", "parameters") if kind in data}
    return ExportSpec(**kinds, line=lines.key_line(("exports",)))


def _realtime(value: Any) -> Realtime:
    """``master.realtime``: true/false or its settings."""
    if isinstance(value, bool):
        return Realtime(enabled=value)
    return Realtime(**{"enabled": True, **value})


def _live(name: str, source: Dict[str, Any], lines: LineMap) -> LiveSpec:
    kind = "udp" if "udp" in source else "joystick"
    signals = []
    for signal, options in source["signals"].items():
        options = dict(options or {})
        signals.append(LiveSignal(signal, lines.key_line(("live", name, "signals", signal)),
                                  float(options.pop("start", 0.0)), options.pop("unit", ""),
                                  options.pop("description", ""), options))
    timeout = source.get("timeout", 1.0 if kind == "udp" else None)
    return LiveSpec(name, lines.key_line(("live", name)), kind, dict(source[kind]), tuple(signals),
                    None if timeout is None else float(timeout))


def _stream(index: int, stream: Dict[str, Any], lines: LineMap) -> StreamSpec:
    kind = "udp" if "udp" in stream else "plot"
    signals = stream["signals"] if kind == "udp" else stream["plot"]
    rate = stream.get("rate")
    return StreamSpec(lines.line(("streams", index)), kind, tuple(signals), stream.get("udp", ""),
                      None if rate is None else float(rate), stream.get("format", "dfmi"),
                      stream.get("byte_order", "little"), float(stream.get("window", 10.0)))
