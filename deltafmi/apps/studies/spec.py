"""Study files: YAML -> checked against ``study.schema.json`` -> a :class:`Study`.

A study names a scenario, what to vary in it (a grid, zipped lists, Monte Carlo samples from
named distributions) and the metrics to compute from every run. Errors are located at
``file:line`` like scenario errors, with suggestions for misspellings. This module knows no FMU:
:mod:`deltafmi.apps.studies.check` checks the names against the scenario and its FMUs.
"""
from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, List, Optional, Tuple

from deltafmi.errors import Diagnostic, ScenarioError, did_you_mean
from deltafmi.shipped import is_shipped
from deltafmi.master.scenario.schema_check import load_mapping, read_document, schema_diagnostics
from deltafmi.master.scenario.line_map import LineMap

if TYPE_CHECKING:
    import jsonschema

__all__ = ["Distribution", "MetricSpec", "MonteCarlo", "Study", "Target", "Vary", "Window", "load_study", "parse_study"]

#: experiment settings a study may vary
EXPERIMENT_TARGETS = ("experiment.stop", "experiment.step")
STATISTICS = ("max", "min", "mean", "rms", "final", "at", "settling_time", "first_crossing", "alternation")
#: keys a statistic takes besides signal, statistic, norm and window: (required, optional)
STATISTIC_KEYS: Dict[str, Tuple[Tuple[str, ...], Tuple[str, ...]]] = {
    "at": (("time",), ()),
    "settling_time": (("band",), ("target",)),
    "first_crossing": (("level",), ("direction",)),
}
#: distribution -> its two parameters
DISTRIBUTIONS: Dict[str, Tuple[str, str]] = {
    "uniform": ("low", "high"), "normal": ("mean", "std"), "lognormal": ("mu", "sigma")}

#: columns of the results table besides the varied values and the metrics
RESERVED_COLUMNS = ("case", "status", "error", "wall_time", "setup_time", "sim_time", "worker")

_SIGNAL = re.compile(r"^\s*(?P<left>\S+?)(?:\s+-\s+(?P<right>\S+))?\s*$")
_REFERENCE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*\.\S+$")


@dataclass(frozen=True)
class Target:
    """Something a study varies: ``component.variable`` (``plant.z0[3]`` for one element) or
    ``experiment.stop`` / ``experiment.step``."""

    name: str
    line: Optional[int]

    @property
    def component(self) -> str:
        """The component name (``experiment`` for the experiment settings)."""
        return self.name.split(".", 1)[0]

    @property
    def variable(self) -> str:
        """The variable (or experiment setting) name."""
        return self.name.split(".", 1)[1]

    @property
    def is_experiment(self) -> bool:
        """True for ``experiment.stop`` and ``experiment.step``."""
        return self.component == "experiment"


@dataclass(frozen=True)
class Distribution:
    """A named distribution: uniform(low, high), normal(mean, std) or lognormal(mu, sigma)
    (the mean and standard deviation of the logarithm). ``relative``: samples multiply the
    nominal value."""

    kind: str
    a: float
    b: float
    relative: bool = False

    def describe(self) -> str:
        """``uniform(0.9, 1.1) x nominal`` and the like."""
        first, second = DISTRIBUTIONS[self.kind]
        return (f"{self.kind}({first} {self.a:g}, {second} {self.b:g})"
                + (" x nominal" if self.relative else ""))


@dataclass(frozen=True)
class MonteCarlo:
    """``samples`` draws of every parameter, reproducible from ``seed``."""

    samples: int
    seed: int
    parameters: Tuple[Tuple[Target, Distribution], ...]


@dataclass(frozen=True)
class Vary:
    """What changes from case to case; the cases are the product of the blocks given."""

    grid: Tuple[Tuple[Target, Tuple[Any, ...]], ...] = ()
    zipped: Tuple[Tuple[Target, Tuple[Any, ...]], ...] = ()
    monte_carlo: Optional[MonteCarlo] = None

    @property
    def targets(self) -> List[Target]:
        """Every varied target, in column order: grid, zip, Monte Carlo."""
        found = [t for t, _ in self.grid] + [t for t, _ in self.zipped]
        if self.monte_carlo is not None:
            found += [t for t, _ in self.monte_carlo.parameters]
        return found

    def kind_of(self, name: str) -> str:
        """``grid``, ``zip`` or ``monte_carlo``: the block that varies ``name``."""
        if any(t.name == name for t, _ in self.grid):
            return "grid"
        if any(t.name == name for t, _ in self.zipped):
            return "zip"
        return "monte_carlo"


@dataclass(frozen=True)
class Window:
    """A time window; None: from the start / to the end of the run."""

    start: Optional[float] = None
    stop: Optional[float] = None


@dataclass(frozen=True)
class MetricSpec:
    """One number per run, computed from recorded signals (see :mod:`deltafmi.apps.studies.metrics`).

    The signal is ``left`` or ``left - right``. A one-element signal stays signed unless a
    ``norm`` is given (then its absolute value); a vector signal is reduced to its norm
    (Euclidean by default) at every sample.
    """

    name: str
    signal: str
    left: str
    right: Optional[str]
    statistic: str
    norm: Optional[str] = None
    window: Window = Window()
    time: Optional[float] = None
    band: Optional[float] = None
    target: Optional[float] = None
    level: Optional[float] = None
    direction: str = "either"
    line: Optional[int] = None

    def as_dict(self) -> Dict[str, Any]:
        """The definition as plain data (for fingerprints and result metadata)."""
        return {"name": self.name, "signal": self.signal, "statistic": self.statistic, "norm": self.norm,
                "window": [self.window.start, self.window.stop], "time": self.time, "band": self.band,
                "target": self.target, "level": self.level, "direction": self.direction}


@dataclass(frozen=True)
class Study:
    """A parsed study file; ``path`` as named by the user (used in diagnostics)."""

    path: Path
    scenario: Path
    vary: Vary
    metrics: Tuple[MetricSpec, ...]
    result_file: Path
    timeseries: bool = False
    description: str = ""
    scenario_line: Optional[int] = None


@lru_cache(maxsize=1)
def schema() -> Dict[str, Any]:
    """The JSON Schema of study files (shipped as ``deltafmi/apps/studies/study.schema.json``)."""
    return json.loads(resources.files("deltafmi.apps.studies").joinpath("study.schema.json").read_text())


def load_study(path: str | Path) -> Study:
    """Read, schema-check and parse a study file, or the shipped example study of that name
    (``"gain_payload"``). Raises :class:`ScenarioError` (exit code 2)."""
    from deltafmi.shipped import find_input
    path = find_input(path, "study")
    return parse_study(read_document(path, "study"), path)


def parse_study(text: str, path: Path) -> Study:
    """Parse study ``text``; ``path`` names it in diagnostics and anchors relative paths."""
    file = str(path)
    data, lines = load_mapping(text, file, "study")
    problems = _schema_errors(data, lines, file)
    if not problems:
        problems = _semantic_errors(data, lines, file)
    if problems:
        raise ScenarioError(problems)
    return _build(data, lines, path)


# --- schema --------------------------------------------------------------------------------------
def _schema_errors(data: Any, lines: LineMap, file: str) -> List[Diagnostic]:
    return schema_diagnostics(data, lines, file, schema(), "study", _study_wording)


def _study_wording(error: jsonschema.ValidationError, lines: LineMap, file: str) -> Optional[List[Diagnostic]]:
    if "propertyNames" not in error.absolute_schema_path:
        return None
    path, key = tuple(error.absolute_path), error.instance
    if path and path[-1] == "metrics":
        message = f"metric name '{key}' must be an identifier (letters, digits, _)"
    else:
        message = (f"'{key}' is not something a study can vary: write 'component.variable' "
                   f"(or experiment.stop / experiment.step)")
    return [Diagnostic(file, lines.key_line(path + (key,)), message)]


# --- checks the schema cannot express ------------------------------------------------------------
#: cases a study may have unless its ``max_cases`` allows more
MAX_CASES = 1_000_000


def _semantic_errors(data: Dict[str, Any], lines: LineMap, file: str) -> List[Diagnostic]:
    found: List[Diagnostic] = []

    def error(path: Tuple[Any, ...], message: str, key: bool = False) -> None:
        found.append(Diagnostic(file, lines.key_line(path) if key else lines.line(path), message))

    vary = data["vary"]
    seen: Dict[str, str] = {}
    for block in ("grid", "zip", "monte_carlo"):
        names = vary.get(block, {})
        if block == "monte_carlo":
            names = names.get("parameters", {})
        for name in names:
            if name in seen:
                error(("vary", block, name), f"'{name}' is varied twice (in {seen[name]} and in {block})", key=True)
            seen[name] = block
            if name.split(".", 1)[0] == "experiment" and name not in EXPERIMENT_TARGETS:
                error(("vary", block, name), f"'{name}': a study varies only {' and '.join(EXPERIMENT_TARGETS)} "
                                             f"of the experiment{did_you_mean(name, EXPERIMENT_TARGETS)}", key=True)
    sizes: List[int] = []  # of every block, to count the cases before any list is made
    for name, values in vary.get("grid", {}).items():
        if isinstance(values, dict):
            where: Tuple[Any, ...] = ("vary", "grid", name)
            infinite = [k for k in ("from", "to", "step") if isinstance(values.get(k), float)
                        and not math.isfinite(values[k])]
            if infinite:
                error(where + (infinite[0],), f"grid '{name}': '{infinite[0]}' ({values[infinite[0]]}) must be a "
                                              "finite number")
            elif ("step" in values) == ("num" in values):
                error(where, f"grid '{name}': give either 'step' or 'num' with 'from' and 'to'")
            elif values["to"] < values["from"]:
                error(where, f"grid '{name}': 'to' ({values['to']}) is below 'from' ({values['from']})")
            else:
                sizes.append(values["num"] if "num" in values else
                             int(math.floor((values["to"] - values["from"]) / values["step"] * (1 + 1e-12) + 1e-9)) + 1)
        elif isinstance(values, list):
            sizes.append(len(values))
    lengths = {name: len(values) for name, values in vary.get("zip", {}).items()}
    if len(set(lengths.values())) > 1:
        listed = ", ".join(f"{name}: {n}" for name, n in lengths.items())
        error(("vary", "zip"), f"zipped lists must have the same length ({listed})", key=True)
    sizes += list(lengths.values())[:1]
    if isinstance(vary.get("monte_carlo", {}).get("samples"), int):
        sizes.append(vary["monte_carlo"]["samples"])
    cases, limit = math.prod(sizes), data.get("max_cases", MAX_CASES)
    if sizes and cases > limit:
        error(("vary",), f"the study has {cases:,} cases ({' x '.join(f'{n:,}' for n in sizes)}), more than the "
                         f"{limit:,} a study may have; to plan them all, raise the limit (max_cases: {cases})",
              key=True)
    for name, spec in vary.get("monte_carlo", {}).get("parameters", {}).items():
        where = ("vary", "monte_carlo", "parameters", name)
        kind = spec["distribution"]
        wanted = DISTRIBUTIONS[kind]
        for key in spec:
            if key not in wanted + ("distribution", "relative"):
                error(where + (key,), f"'{name}': '{key}' is not a parameter of the {kind} distribution "
                                      f"(it takes {' and '.join(wanted)})", key=True)
        missing = [k for k in wanted if k not in spec]
        if missing:
            error(where, f"'{name}': the {kind} distribution needs {' and '.join(missing)}")
        elif kind == "uniform" and spec["high"] <= spec["low"]:
            error(where, f"'{name}': uniform needs low < high (got {spec['low']}, {spec['high']})")
    for name, spec in data["metrics"].items():
        if name in RESERVED_COLUMNS or name in seen:
            error(("metrics", name), f"metric name '{name}' is taken by a column of the results "
                                     f"({', '.join(RESERVED_COLUMNS)} and the varied values)", key=True)
        found.extend(_metric_errors(name, spec, lines, file))
    return found


def _metric_errors(name: str, spec: Dict[str, Any], lines: LineMap, file: str) -> List[Diagnostic]:
    where = ("metrics", name)
    found: List[Diagnostic] = []
    statistic = spec["statistic"]
    required, optional = STATISTIC_KEYS.get(statistic, ((), ()))
    specific = {k for keys in STATISTIC_KEYS.values() for pair in keys for k in pair}
    for key in spec:
        if key in specific and key not in required + optional:
            users = [s for s, (r, o) in STATISTIC_KEYS.items() if key in r + o]
            found.append(Diagnostic(file, lines.key_line(where + (key,)),
                                    f"metric '{name}': '{key}' applies to {' and '.join(users)}, "
                                    f"not to '{statistic}'"))
    for key in required:
        if key not in spec:
            found.append(Diagnostic(file, lines.line(where), f"metric '{name}': '{statistic}' needs '{key}'"))
    if statistic == "at" and "window" in spec:
        found.append(Diagnostic(file, lines.key_line(where + ("window",)),
                                f"metric '{name}': 'at' takes a time, not a window"))
    window = spec.get("window", {})
    if "from" in window and "to" in window and window["to"] <= window["from"]:
        found.append(Diagnostic(file, lines.line(where + ("window",)),
                                f"metric '{name}': window 'to' ({window['to']}) must be after 'from' ({window['from']})"))
    signal = spec["signal"]
    match = _SIGNAL.match(signal)
    unspaced = match is not None and match["right"] is None and re.search(r"-\s*[A-Za-z_]\w*\.", match["left"])
    if match is None or unspaced or not all(_REFERENCE.match(r) for r in match.groups() if r is not None):
        hint = (" (write a difference with spaces around the minus: 'plant.z - trajectory.r')"
                if "-" in signal else "")
        found.append(Diagnostic(file, lines.line(where + ("signal",)),
                                f"metric '{name}': signal '{signal}' is not 'component.variable' or "
                                f"'component.variable - component.variable'{hint}"))
    return found


# --- build ---------------------------------------------------------------------------------------
def grid_values(spec: Any) -> Tuple[Any, ...]:
    """The values of one grid axis: a list as given, or ``{from, to, step}`` (``to`` included when
    on the grid) / ``{from, to, num}`` (evenly spaced, both ends included)."""
    if isinstance(spec, list):
        return tuple(spec)
    start, stop = spec["from"], spec["to"]
    if "step" in spec:
        step = spec["step"]
        count = int(math.floor((stop - start) / step * (1 + 1e-12) + 1e-9)) + 1
        values = [start + k * step for k in range(count)]
        integers = all(isinstance(v, int) for v in (start, stop, step))
    else:
        count = spec["num"]
        values = [start + (stop - start) * k / (count - 1) for k in range(count)] if count > 1 else [start]
        integers = False
    if integers:
        return tuple(int(v) for v in values)
    # 12 significant digits: 0.1 steps give 0.3, not 0.30000000000000004
    return tuple(float(f"{v:.12g}") for v in values)


def _build(data: Dict[str, Any], lines: LineMap, path: Path) -> Study:
    vary_data = data["vary"]
    grid = tuple((Target(name, lines.key_line(("vary", "grid", name))), grid_values(values))
                 for name, values in vary_data.get("grid", {}).items())
    zipped = tuple((Target(name, lines.key_line(("vary", "zip", name))), tuple(values))
                   for name, values in vary_data.get("zip", {}).items())
    monte_carlo = None
    if "monte_carlo" in vary_data:
        mc = vary_data["monte_carlo"]
        parameters = []
        for name, spec in mc["parameters"].items():
            first, second = DISTRIBUTIONS[spec["distribution"]]
            parameters.append((Target(name, lines.key_line(("vary", "monte_carlo", "parameters", name))),
                               Distribution(spec["distribution"], float(spec[first]), float(spec[second]),
                                            bool(spec.get("relative", False)))))
        monte_carlo = MonteCarlo(int(mc["samples"]), int(mc["seed"]), tuple(parameters))
    metrics = []
    for name, spec in data["metrics"].items():
        match = _SIGNAL.match(spec["signal"])
        assert match is not None  # checked by _metric_errors
        window = spec.get("window", {})
        metrics.append(MetricSpec(
            name=name, signal=spec["signal"].strip(), left=match["left"], right=match["right"],
            statistic=spec["statistic"], norm=None if "norm" not in spec else str(spec["norm"]),
            window=Window(_float(window.get("from")), _float(window.get("to"))),
            time=_float(spec.get("time")), band=_float(spec.get("band")), target=_float(spec.get("target")),
            level=_float(spec.get("level")), direction=spec.get("direction", "either"),
            line=lines.key_line(("metrics", name))))
    result = data.get("result", {})
    result_file = Path(result["file"]) if "file" in result else Path(path.stem + ".parquet")
    if "file" in result and not result_file.is_absolute() and not is_shipped(path):
        result_file = path.parent / result_file  # a shipped study's results go here, not into the package
    scenario = Path(data["scenario"])
    if not scenario.is_absolute():
        scenario = path.parent / scenario
    return Study(path, scenario, Vary(grid, zipped, monte_carlo), tuple(metrics), result_file,
                 bool(result.get("timeseries", False)), data.get("description", ""),
                 lines.line(("scenario",)))


def _float(value: Any) -> Optional[float]:
    return None if value is None else float(value)
