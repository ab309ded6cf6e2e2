"""Check a study against its scenario and FMUs, and plan its runs (client side).

Every name in the study is checked where it is written (``study.yaml:12: error: ...``): varied
targets (component, variable, settable, type of every value, via the scenario checker itself),
metric signals (recorded variables, numeric, same size and unit on both sides of a difference).
The result is a :class:`StudyPlan`, the small picklable description a worker needs (the parsed
scenario, which FMU by content hash each component uses, what to record and measure), plus the
list of cases.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

from deltafmi.errors import Diagnostic, ScenarioError, did_you_mean
from deltafmi.master.scenario.live_components import refuse_live
from deltafmi.master.scenario.modelinfo import UnknownVariable
from deltafmi.master.scenario.resolve import resolve_system, start_value_problem
from deltafmi.master.scenario.system import System, bus_type
from deltafmi.master.scenario.spec import ComponentSpec, OutputSpec, Parameter, Scenario, load_scenario

from .cases import Case, generate_cases
from .metrics import Metric
from .spec import Study, Target

__all__ = ["PlannedStudy", "StudyPlan", "plan_study", "with_parameters"]

_NUMERIC = ("Real", "Integer", "Int64", "UInt64", "Boolean")


@dataclass(frozen=True)
class StudyPlan:
    """What a worker needs to run any case of a study (small; FMUs travel separately by hash)."""

    #: the scenario, recording ``outputs``
    scenario: Scenario
    #: component name -> sha256 of its FMU file
    fmus: Tuple[Tuple[str, str], ...]
    #: varied component targets with a representative value each: appended to the scenario's
    #: start values, they give every case its slots (see deltafmi.apps.studies.runner.CaseTemplate)
    probe: Tuple[Tuple[str, Any], ...]
    metrics: Tuple[Metric, ...]
    #: identifies the study's runs: scenario, FMU contents, recording, metrics
    fingerprint: str


@dataclass
class PlannedStudy:
    """A checked study: its plan, cases, FMU files and column metadata."""

    study: Study
    plan: StudyPlan
    cases: List[Case]
    #: sha256 -> FMU file on this machine
    fmu_files: Dict[str, Path]
    #: sha256 -> the FMU's bytes, as read when planning (what the workers get)
    fmu_bytes: Dict[str, bytes]
    #: unit of every varied target and metric ("" when none)
    units: Dict[str, str]
    #: the resolved scenario (client side)
    system: System

    @property
    def targets(self) -> List[str]:
        """Varied targets, in column order."""
        return [t.name for t in self.study.vary.targets]


def plan_study(study: Study) -> PlannedStudy:
    """Check ``study`` against its scenario and FMUs (building them if needed) and plan it.

    Raises :class:`ScenarioError` with every problem found, located in the study file (or in the
    scenario, for problems of the scenario itself).
    """
    file = str(study.path)
    if not study.scenario.is_file():
        folder = study.scenario.parent
        hint = did_you_mean(study.scenario.name, [p.name for p in folder.glob("*.yaml")]) if folder.is_dir() else ""
        raise ScenarioError([Diagnostic(file, study.scenario_line, f"scenario '{study.scenario}' not found{hint}")])
    scenario = load_scenario(study.scenario)
    system = resolve_system(scenario)
    refuse_live(system, "a study")
    checker = _Checker(study, system)
    units = checker.targets()
    metrics = checker.metrics()
    if checker.found:
        raise ScenarioError(checker.found)
    recorded = [p.ref for p in system.recorded]
    outputs = recorded + [c for m in metrics for c in m.left + m.right if c not in recorded]
    outputs = list(dict.fromkeys(outputs))
    scenario = dataclasses.replace(scenario, outputs=tuple(OutputSpec(ref, None) for ref in outputs))
    # read once: what is hashed is what the workers get, even if the file is rebuilt meanwhile
    blobs = {str(c.fmu): Path(c.fmu).read_bytes() for c in system.components}
    digests = {path: hashlib.sha256(data).hexdigest() for path, data in blobs.items()}
    fmu_files = {digests[str(c.fmu)]: c.fmu for c in system.components}
    fmu_bytes = {digests[path]: data for path, data in blobs.items()}
    fmus = tuple((c.name, digests[str(c.fmu)]) for c in system.components)
    probe = checker.probe_values()
    fingerprint = _fingerprint(scenario, fmus, metrics)
    plan = StudyPlan(scenario, fmus, probe, tuple(metrics), fingerprint)
    cases = generate_cases(study.vary, checker.nominals)
    checker.case_values(cases)  # every case passes the checks the scenario's values pass, before any runs
    if checker.found:
        raise ScenarioError(checker.found)
    units.update({m.name: m.unit for m in metrics})
    return PlannedStudy(study, plan, cases, fmu_files, fmu_bytes, units, system)


class _Checker:
    """Checks names and values of a study against the resolved scenario; collects diagnostics."""

    def __init__(self, study: Study, system: System) -> None:
        self.study = study
        self.system = system
        self.file = str(study.path)
        self.found: List[Diagnostic] = []
        self.components = {c.name: c for c in system.components}
        self.nominals: Dict[str, float] = {}
        self._representatives: Dict[str, List[Any]] = {}

    def error(self, line: Optional[int], message: str) -> None:
        self.found.append(Diagnostic(self.file, line, message))

    # --- varied targets -----------------------------------------------------------------------
    def targets(self) -> Dict[str, str]:
        """Check every varied target; returns target -> unit."""
        units: Dict[str, str] = {}
        vary = self.study.vary
        values = {t.name: list(v) for t, v in vary.grid + vary.zipped}
        distributions = {t.name: d for t, d in vary.monte_carlo.parameters} if vary.monte_carlo else {}
        for target in vary.targets:
            if target.is_experiment:
                if "experiment" in self.components:
                    self.error(target.line, f"'{target.name}' is ambiguous: the scenario has a component "
                                            "called 'experiment'")
                units[target.name] = "s"
                self._check_experiment_values(target, values.get(target.name, []))
                continue
            name = self._scalar(target)
            if name is None:
                continue
            component = self.components[target.component]
            units[target.name] = component.info.unit(name)
            if target.name in distributions:
                self._check_sampled(target, name, distributions[target.name].relative)
                self._representatives[target.name] = [1.0]
            else:
                self._representatives[target.name] = _one_of_each_type(values[target.name])
        if not self.found:
            self._probe()
        return units

    def _scalar(self, target: Target) -> Optional[str]:
        """The FMU variable a component target names (component and variable must exist)."""
        component = self.components.get(target.component)
        if component is None:
            self.error(target.line, f"'{target.name}': the scenario has no component '{target.component}'"
                                    f"{did_you_mean(target.component, list(self.components) + ['experiment'])}")
            return None
        try:
            names = component.info.expand(target.variable)
        except UnknownVariable as exc:
            self.error(target.line, f"'{target.name}': component '{target.component}' has no variable "
                                    f"'{exc.reference}'{did_you_mean(exc.reference, exc.names)}")
            return None
        if len(names) != 1:
            self.error(target.line, f"'{target.name}' has {len(names)} elements: vary one element at a time "
                                    f"('{names[0]}')")
            return None
        return names[0]

    def case_values(self, cases: Sequence[Case]) -> None:
        """Every case's value of every varied component target against its FMU variable: type,
        finite, declared min and max (as a scenario's ``parameters:`` and ``--set`` are checked);
        one error per target, naming its first case that fails and how many more do."""
        for target in self.study.vary.targets:
            if target.is_experiment:
                continue
            component = self.components[target.component]
            name = component.info.expand(target.variable)[0]
            var = component.info.variables[name]
            bad = [(case, problem) for case in cases
                   for problem in [start_value_problem(var, case.values[target.name])] if problem]
            if bad:
                case, problem = bad[0]
                more = f" (and {len(bad) - 1} more case{'s' * (len(bad) > 2)})" if len(bad) > 1 else ""
                joint = " " if problem.startswith("is ") else ": "
                self.error(target.line, f"'{target.name}' = {case.values[target.name]!r} in case {case.id}{joint}"
                                        f"{problem}{more}")

    def _check_experiment_values(self, target: Target, values: Sequence[Any]) -> None:
        for value in values:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or value <= 0:
                self.error(target.line, f"'{target.name}': {value!r} is not a positive number of seconds")
                return
        start = self.system.scenario.experiment.start
        if target.name == "experiment.stop" and any(v <= start for v in values):
            self.error(target.line, f"'{target.name}': every stop time must be after the start time {start}")

    def _check_sampled(self, target: Target, name: str, relative: bool) -> None:
        component = self.components[target.component]
        kind = component.info.variables[name].type
        if kind != "Real":
            self.error(target.line, f"'{target.name}' is {kind}: Monte Carlo samples are real numbers")
            return
        if relative:
            nominal = self._nominal(target.component, name)
            if nominal is None:
                self.error(target.line, f"'{target.name}': no nominal value to scale (the FMU gives no start "
                                        "value and the scenario sets none)")
            else:
                self.nominals[target.name] = nominal

    def _nominal(self, component_name: str, name: str) -> Optional[float]:
        """The value the scenario gives ``name`` (the last one set), else the FMU's start value."""
        component = self.components[component_name]
        given = [value for port, value in component.start_values if port.name == name]
        if given:
            return float(given[-1])
        start = component.info.variables[name].start
        return float(start) if start is not None else None

    def _probe(self) -> None:
        """Let the scenario checker judge every kind of value given to each target, reporting its
        findings at the target's line in the study."""
        targets = [t for t in self.study.vary.targets if not t.is_experiment]
        rounds = max((len(self._representatives[t.name]) for t in targets), default=0)
        seen = set()
        for k in range(rounds):
            chosen = [(t, self._representatives[t.name][k % len(self._representatives[t.name])]) for t in targets]
            try:
                resolve_system(with_parameters(self.system.scenario, chosen))
            except ScenarioError as exc:
                for d in exc.diagnostics:
                    if (d.line, d.message) not in seen:
                        seen.add((d.line, d.message))
                        self.found.append(Diagnostic(self.file, d.line, d.message))

    def probe_values(self) -> Tuple[Tuple[str, Any], ...]:
        """A valid value of every varied component target (column order)."""
        return tuple((t.name, self._representatives[t.name][0]) for t in self.study.vary.targets
                     if not t.is_experiment)

    # --- metrics ------------------------------------------------------------------------------
    def metrics(self) -> List[Metric]:
        """Check every metric's signal; returns the metrics with their columns resolved."""
        metrics = []
        for spec in self.study.metrics:
            left = self._signal_columns(spec.name, spec.left, spec.line)
            right = self._signal_columns(spec.name, spec.right, spec.line) if spec.right else ()
            if left is None or right is None:
                continue
            if right and len(left[0]) != len(right[0]):
                self.error(spec.line, f"metric '{spec.name}': '{spec.left}' has {len(left[0])} element(s) but "
                                      f"'{spec.right}' has {len(right[0])}")
                continue
            unit = left[1]
            if right and left[1] and right[1] and left[1] != right[1]:
                self.error(spec.line, f"metric '{spec.name}': '{spec.left}' is in '{left[1]}' but '{spec.right}' "
                                      f"in '{right[1]}'")
                continue
            if spec.statistic in ("settling_time", "first_crossing"):
                unit = "s"
            metrics.append(Metric(spec, left[0], right[0] if right else (), unit))
        return metrics

    def _signal_columns(self, metric: str, reference: str, line: Optional[int]) -> Optional[Tuple[Tuple[str, ...], str]]:
        component_name, variable = reference.split(".", 1)
        component = self.components.get(component_name)
        if component is None:
            self.error(line, f"metric '{metric}': the scenario has no component '{component_name}'"
                             f"{did_you_mean(component_name, list(self.components))}")
            return None
        try:
            names = component.info.expand(variable)
        except UnknownVariable as exc:
            self.error(line, f"metric '{metric}': component '{component_name}' has no variable "
                             f"'{exc.reference}'{did_you_mean(exc.reference, exc.names)}")
            return None
        kinds = {bus_type(component.info.variables[n].type) for n in names}
        if not kinds <= set(_NUMERIC):
            self.error(line, f"metric '{metric}': '{reference}' is {', '.join(sorted(kinds))}, not a number")
            return None
        return tuple(f"{component_name}.{n}" for n in names), component.info.unit(names[0])


def with_parameters(scenario: Scenario, values: Sequence[Tuple[Target, Any]]) -> Scenario:
    """``scenario`` with start values appended to its components' parameters (the last one set wins)."""
    extra: Dict[str, List[Parameter]] = {}
    for target, value in values:
        extra.setdefault(target.component, []).append(Parameter(target.variable, value, target.line))
    components = tuple(dataclasses.replace(c, parameters=c.parameters + tuple(extra.get(c.name, ())))
                       for c in scenario.components)
    return dataclasses.replace(scenario, components=components)


def _one_of_each_type(values: Sequence[Any]) -> List[Any]:
    """The first value of each Python type, and every distinct string (Enumeration item names)."""
    chosen: List[Any] = []
    types = set()
    for value in values:
        if isinstance(value, str):
            if value not in chosen:
                chosen.append(value)
        elif type(value) not in types:
            types.add(type(value))
            chosen.append(value)
    return chosen


def _fingerprint(scenario: Scenario, fmus: Tuple[Tuple[str, str], ...], metrics: Sequence[Metric]) -> str:
    """sha256 of what decides a case's results besides its varied values (line numbers, paths and
    the result file excluded, so editing comments or moving the project keeps it)."""
    text = json.dumps({"scenario": _plain(scenario), "fmus": fmus,
                       "metrics": [m.spec.as_dict() for m in metrics]}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _plain(value: Any) -> Any:
    """Dataclasses as dicts without their lines, paths, description and result settings (and a
    component's FMU path: its content hash stands in for it)."""
    if dataclasses.is_dataclass(value):
        # threads: how many step the units, never what they compute
        skipped = ("path", "result", "description", "threads") + (("fmu", "source") if isinstance(value, ComponentSpec)
                                                                   else ())
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)
                if not f.name.endswith("line") and f.name not in skipped}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    return value
