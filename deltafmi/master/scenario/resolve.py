"""Check a :class:`Scenario` against its FMUs and resolve it into a runnable :class:`System`.

Every finding is a :class:`Diagnostic` at ``file:line``: unknown components and variables (with
suggestions), connections that do not go output -> input, type and unit mismatches, inputs driven
twice, unconnected inputs (warning), algebraic loops the master cannot solve (from each FMU's
direct feedthrough), parameters that cannot be set, record patterns that match nothing.
FMI 2.0 and FMI 3.0 FMUs resolve alike: an FMI 3.0 array is its elements (:mod:`.modelinfo`),
connected whole (shapes must agree) or by element; Binary and Clock variables are not connected.
"""
from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

from deltafmi.errors import Diagnostic, FmuSourceError, ScenarioError, did_you_mean, file_hint

from .fmu_source import provided_fmu
from .system import AlgebraicLoop, Link, Port, ResolvedComponent, System, SystemInterface, bus_type
from .graph import block_stepping_order, initialization_order, loop_groups, tear
from .modelinfo import UnknownVariable, model_info, split_element
from .overrides import Text, from_text, value_items
from .spec import ComponentSpec, ConnectionSpec, OutputSpec, Scenario

__all__ = ["AlgebraicLoop", "System", "describe", "pattern_regex", "resolve_system"]


_SETTABLE_CAUSALITIES = ("parameter", "input")
#: how a start value of each FMI 3.0 type is checked: as a Real or Integer value
_VALUE_KINDS = {"Int64": "Integer", "UInt64": "Integer", "UInt32": "Integer"}
_INTEGER_RANGES = {f"{sign}Int{bits}": ((0, 2 ** bits - 1) if sign else (-2 ** (bits - 1), 2 ** (bits - 1) - 1))
                   for sign in ("", "U") for bits in (8, 16, 32, 64)}
#: the buses whose variables a scenario exported as one FMU offers
_EXPORTED_TYPES = ("Real", "Integer", "Boolean")
#: FMI 3.0 types whose values the master does not exchange
_NOT_CONNECTABLE = ("Binary", "Clock")


def resolve_system(scenario: Scenario, check_fmus: bool = False) -> System:
    """Locate/build the FMUs and check everything; raises :class:`ScenarioError` on any error.

    ``check_fmus`` also runs fmpy's validation of each FMU (used by ``deltafmi validate``).
    """
    checker = _Checker(scenario)
    system = checker.run(check_fmus)
    errors = [d for d in checker.found if d.severity == "error"]
    if errors:
        raise ScenarioError(errors)
    return system


class _Checker:
    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.file = str(scenario.path)
        self.found: List[Diagnostic] = []
        self.components: Dict[str, ResolvedComponent] = {}

    def error(self, line: Optional[int], message: str, at: Optional[str] = None) -> None:
        """An error at ``line`` of the scenario file, or at ``at`` (a run option such as ``--set x``)."""
        self.found.append(Diagnostic(at or self.file, line, message))

    def warn(self, line: Optional[int], message: str) -> None:
        self.found.append(Diagnostic(self.file, line, message, "warning"))

    def run(self, check_fmus: bool) -> Optional[System]:
        """Check everything; the resolved system, or None when an error was found."""
        for spec in self.scenario.components:
            component = self._component(spec, check_fmus)
            if component is not None:
                self.components[spec.name] = component
        live = self._live_components()
        links = self._links()
        if not self.scenario.single_fmu:
            self._unconnected(links)
        feedthrough = {name: c.info.feedthrough for name, c in self.components.items()}
        pairs = [(l.source.ref, l.target.ref) for l in links]
        initial_feedthrough = {name: c.info.initial_feedthrough for name, c in self.components.items()}
        loops = self._loops(links, feedthrough, initial=False)
        init_loops = self._loops(links, initial_feedthrough, initial=True)
        recorded = self._recorded()
        streamed = [self._matches(stream.signals, stream.line, "stream") for stream in self.scenario.streams]
        recorded = _with(recorded, [port for c in live for port in _outputs(c)] + [p for s in streamed for p in s])
        self._settings()
        interface = self._interface(recorded, links)
        if any(d.severity == "error" for d in self.found):
            return None
        names = [c.name for c in self.scenario.components]
        by_pair = dict(zip(pairs, links))
        return System(self.scenario, [self.components[n] for n in names], links, recorded,
                      block_stepping_order(names + [c.name for c in live], pairs, feedthrough,
                                           [loop.members for loop in loops]),
                      [by_pair[p] for p in initialization_order(pairs, initial_feedthrough)],
                      [d for d in self.found if d.severity == "warning"], loops, init_loops, live, streamed,
                      interface)

    def _live_components(self) -> List[ResolvedComponent]:
        """The live sources' components (and the pacing measurements' of a paced run), added to
        :attr:`components` for connections and patterns to find."""
        from .live_components import REALTIME, live_component, realtime_component

        live = [live_component(spec) for spec in self.scenario.live]
        if self.scenario.master.realtime.enabled:
            if REALTIME in self.components or any(c.name == REALTIME for c in live):
                self.error(None, f"a paced run records its lateness as '{REALTIME}.*': rename the component "
                                 f"'{REALTIME}'")
            live.append(realtime_component())
        for component in live:
            self.components.setdefault(component.name, component)
        return live

    def _loops(self, links: List[Link], feedthrough: Dict[str, Any], initial: bool) -> List[AlgebraicLoop]:
        """The algebraic loops of ``links`` under ``feedthrough``, torn; errors for those the
        master cannot solve."""
        by_pair = {(l.source.ref, l.target.ref): l for l in links}
        position = {spec.name: i for i, spec in enumerate(self.scenario.components)}
        loops = []
        for pairs in loop_groups(by_pair, feedthrough):
            inside = [by_pair[p] for p in pairs]
            line = min((l.line for l in inside if l.line is not None), default=None)
            members = sorted({p.component for l in inside for p in (l.source, l.target)}, key=position.__getitem__)
            sources = {l.source.ref: l.source for l in inside}
            loop = AlgebraicLoop(tuple(members), tuple(inside), (), line, initial)
            try:
                order, torn = tear(members, pairs, lambda ref: sources[ref].type == "Real")
            except ValueError:
                self.error(line, f"{loop}{' at initialization' * initial}: every way to cut it passes through "
                                 "a connection that is not Real; the master iterates on Real values only")
                continue
            loop = AlgebraicLoop(tuple(order), tuple(inside), tuple(sources[ref] for ref in torn), line, initial)
            if not initial:
                self._check_loop(loop)
            loops.append(loop)
        return loops

    def _check_loop(self, loop: AlgebraicLoop) -> None:
        """Solving a loop at every step redoes its members' steps: each must restore its state, and
        all must step together (same step_multiple)."""
        members = [self.components[name] for name in loop.members]
        for c in members:
            if not c.info.can_get_set_state(c.interface):
                self.error(loop.line, f"{loop}: component '{c.name}' ({c.interface}) cannot save and restore its "
                                      "state (canGetAndSetFMUstate is not true), which solving the loop at every "
                                      "step needs: each iteration redoes the loop's step from the saved state")
        multiples = {c.spec.step_multiple for c in members}
        if len(multiples) > 1:
            self.error(loop.line, f"{loop}: its components step together, so they need the same step_multiple "
                                  f"(they have {', '.join(f'{c.name}: {c.spec.step_multiple}' for c in members)})")
        if self.scenario.master.loops.jacobian == "directional-derivative":
            for c in members:
                element = c.info.md.modelExchange if c.interface == "ME" else c.info.md.coSimulation
                if not element.providesDirectionalDerivative:
                    self.error(loop.line, f"{loop}: master.loops.jacobian is directional-derivative but component "
                                          f"'{c.name}' ({c.interface}) does not provide fmi2GetDirectionalDerivative")

    # --- components ---------------------------------------------------------------------------
    def _component(self, spec: ComponentSpec, check_fmus: bool) -> Optional[ResolvedComponent]:
        path = self._fmu_path(spec)
        if path is None:
            return None
        try:
            info = model_info(str(path))
        except Exception as exc:  # noqa: BLE001 - any unreadable FMU is a user error here
            self.error(spec.line, f"component '{spec.name}': cannot read FMU '{path}': {exc}")
            return None
        if spec.fmi_version is not None and spec.fmu is not None and info.fmi3 != (spec.fmi_version == 3):
            self.error(spec.line, f"component '{spec.name}': FMU '{path.name}' is an FMI {info.md.fmiVersion} FMU, "
                                  f"not FMI {spec.fmi_version}.0 as its fmi_version says")
            return None
        offered = info.interfaces()
        interface = spec.interface or ("CS" if "CS" in offered else "ME")
        if interface not in offered:
            self.error(spec.line, f"component '{spec.name}': the FMU offers no "
                                  f"{'ModelExchange' if interface == 'ME' else 'CoSimulation'} interface "
                                  f"(it has {', '.join(offered) or 'none'})")
            return None
        from .fmu_checks import binary_problem
        missing = binary_problem(path, [info.model_identifier(interface)], info.fmi3)
        if missing:
            self.error(spec.line, f"component '{spec.name}': FMU '{path.name}' cannot run here: {missing}")
            return None
        if info.fmi3:
            from .fmu_checks import clock_problem
            refused = clock_problem(path, interface)
            if refused:
                self.error(spec.line, f"component '{spec.name}': FMU '{path.name}': {refused}")
        if check_fmus:
            from .fmu_checks import validation_problems
            for problem in validation_problems(path):
                self.error(spec.line, f"component '{spec.name}': FMU validation: {problem.strip()}")
            from .fmu_checks import guid_problem
            mismatch = guid_problem(path, info.md.guid)
            if mismatch:
                self.error(spec.line, f"component '{spec.name}': FMU '{path.name}': {mismatch}")
        if interface == "CS":
            ignored = sorted(set(spec.solver) - {"rtol"})
            if ignored:
                self.warn(spec.line, f"component '{spec.name}': solver options {', '.join(ignored)} "
                                     "only apply to ME components (ignored)")
        component = ResolvedComponent(spec, path, info, interface)
        component.start_values = self._start_values(component)
        return component

    def _fmu_path(self, spec: ComponentSpec) -> Optional[Path]:
        base = self.scenario.directory
        if spec.fmu is not None:
            path = Path(spec.fmu) if Path(spec.fmu).is_absolute() else base / spec.fmu
            if not path.is_file():
                self.error(spec.line, f"component '{spec.name}': FMU '{spec.fmu}' not found"
                                      f"{file_hint(path, '*.fmu')}")
                return None
            return path
        version = spec.fmi_version or self.scenario.fmi_version or 2
        try:
            return provided_fmu(spec.source, base, version, self.scenario.resource_paths(spec))
        except FmuSourceError as exc:
            self.error(spec.line, f"component '{spec.name}': {exc}")
            return None

    def _start_values(self, component: ResolvedComponent) -> List[Tuple[Port, Any]]:
        values = []
        info = component.info
        for param in component.spec.parameters:
            where = f"component '{component.name}': parameter '{param.name}'"
            at = param.origin  # a run option (--set) rather than a line of the file
            try:
                names = info.expand(param.name)
            except UnknownVariable as exc:
                prefix = param.name.partition(".")[0]
                other = (f" (nor is '{prefix}' a component: the scenario's one component is '{component.name}')"
                         if at and "." in param.name and prefix != component.name
                         and not any(n.startswith(prefix + ".") for n in exc.names) else "")
                if at and param.name == component.name:
                    other = f" ('{param.name}' is the component: set one of its variables, {param.name}.NAME=VALUE)"
                self.error(param.line, f"{where}: no such variable in the FMU"
                                       f"{did_you_mean(param.name, exc.names) or other}", at)
                continue
            items = value_items(param.value, len(names))
            if len(items) != len(names):
                self.error(param.line, f"{where}: has {len(names)} element(s) but {len(items)} value(s) were given",
                           at)
                continue
            for name, value in zip(names, items):
                var = info.variables[name]
                if var.causality == "structuralParameter":
                    self.error(param.line, f"{where}: '{name}' is a structural parameter, which the master keeps "
                                           "at its start value (it sizes the FMU's arrays)", at)
                    break
                if not _settable(var):
                    self.error(param.line, f"{where}: '{name}' is {_article(var.causality)} "
                                           f"({var.initial or 'calculated'}) and cannot be set", at)
                    break
                kind = _VALUE_KINDS.get(var.type, bus_type(var.type))
                if kind in _NOT_CONNECTABLE:
                    self.error(param.line, f"{where}: '{name}' is a {kind} variable, which the master does not "
                                           "set", at)
                    break
                enumeration = info.enumeration(name)
                if isinstance(value, Text):
                    try:
                        value = from_text(value, "Enumeration" if enumeration is not None else kind)
                    except ValueError as exc:
                        self.error(param.line, f"{where}: '{name}' is {kind}: {exc}", at)
                        break
                if enumeration is not None:
                    value = self._enumeration_value(param.line, f"{where}: '{name}'", enumeration, value, at)
                    if value is None:
                        break
                elif not _value_fits(kind, value):
                    self.error(param.line, f"{where}: type mismatch: '{name}' is {kind} but the value "
                                           f"{value!r} is {type(value).__name__}", at)
                    break
                outside = _outside_range(var, kind, value, _INTEGER_RANGES.get(var.type))
                if outside:
                    self.error(param.line, f"{where}: '{name}' = {value!r} {outside}", at)
                    break
                values.append((_port(component, name), value))
        return values

    def _enumeration_value(self, line: Optional[int], where: str, enumeration: Tuple[str, Dict[str, int]],
                           value: Any, at: Optional[str] = None) -> Optional[int]:
        """An Enumeration start value given by item name or by value; None (reported) if neither."""
        type_name, items = enumeration
        listed = ", ".join(f"{name} = {number}" for name, number in items.items())
        if isinstance(value, str):
            if value in items:
                return items[value]
            self.error(line, f"{where} is Enumeration '{type_name}', which has no item '{value}' "
                             f"(its items: {listed}){did_you_mean(value, items)}", at)
        elif isinstance(value, int) and not isinstance(value, bool) and value in items.values():
            return value
        else:
            self.error(line, f"{where} is Enumeration '{type_name}': give an item name or its value "
                             f"({listed}), not {value!r}", at)
        return None

    # --- connections --------------------------------------------------------------------------
    def _links(self) -> List[Link]:
        links: List[Link] = []
        driver: Dict[str, Tuple[str, Optional[int]]] = {}
        for conn in self.scenario.connections:
            sources = self._endpoint(conn.source, conn.source_line, "from")
            targets = self._endpoint(conn.target, conn.target_line, "to")
            if sources is None or targets is None:
                continue
            if not self._causalities(conn, sources, targets):
                continue
            shapes = self._shape(conn.source), self._shape(conn.target)
            if len(sources) != len(targets) or (None not in shapes and shapes[0] != shapes[1]):
                if None not in shapes:
                    self.error(conn.line, f"connection {conn.source} -> {conn.target}: the arrays differ in "
                                          f"shape: '{conn.source}' is {_shape_text(shapes[0])} but "
                                          f"'{conn.target}' is {_shape_text(shapes[1])}")
                else:
                    self.error(conn.line, f"connection {conn.source} -> {conn.target}: {len(sources)} source "
                                          f"variable(s) but {len(targets)} target variable(s)")
                continue
            for source, target in zip(sources, targets):
                if not self._compatible(conn, source, target):
                    break
                if target.ref in driver:
                    other, other_line = driver[target.ref]
                    self.error(conn.target_line, f"input '{target.ref}' is driven twice: by '{other}' "
                                                 f"(line {other_line}) and by '{source.ref}'")
                    continue
                driver[target.ref] = (source.ref, conn.line)
                links.append(Link(source, target, conn.factor, conn.offset, conn.line))
        return links

    def _endpoint(self, reference: str, line: Optional[int], role: str) -> Optional[List[Port]]:
        comp_name, var = reference.split(".", 1)
        component = self.components.get(comp_name)
        if component is None:
            if comp_name not in {c.name for c in self.scenario.components}:
                self.error(line, f"'{role}: {reference}': unknown component '{comp_name}'"
                                 f"{did_you_mean(comp_name, [c.name for c in self.scenario.components])}")
            return None
        try:
            names = component.info.expand(var)
        except UnknownVariable as exc:
            self.error(line, f"'{role}: {reference}': component '{comp_name}' has no variable "
                             f"'{exc.reference}'{did_you_mean(exc.reference, exc.names)}")
            return None
        return [_port(component, n) for n in names]

    def _shape(self, reference: str) -> Optional[Tuple[int, ...]]:
        """The shape of the whole array ``component.variable`` names, else None."""
        comp_name, var = reference.split(".", 1)
        return self.components[comp_name].info.shape(var)

    def _causalities(self, conn: ConnectionSpec, sources: List[Port], targets: List[Port]) -> bool:
        ok = True
        src = self._causality(sources[0])
        if src != "output":
            self.error(conn.source_line, f"'from: {conn.source}' is {_article(src)}; a connection must "
                                         "start at an output")
            ok = False
        dst = self._causality(targets[0])
        if dst == "output":
            self.error(conn.target_line, f"'to: {conn.target}' is an output (output -> output); a connection "
                                         "must end at an input")
            ok = False
        elif dst != "input":
            self.error(conn.target_line, f"'to: {conn.target}' is {_article(dst)}; a connection must end at an input")
            ok = False
        return ok

    def _causality(self, port: Port) -> str:
        return self.components[port.component].info.variables[port.name].causality

    def _compatible(self, conn: ConnectionSpec, source: Port, target: Port) -> bool:
        for port in (source, target):
            if port.type in _NOT_CONNECTABLE:
                self.error(conn.line, f"'{port.ref}' is a {port.type} variable, which the master does not "
                                      "exchange: only Float, Integer, Boolean, String and Enumeration variables "
                                      "can be connected")
                return False
        if source.same_type_as != target.same_type_as:
            self.error(conn.line, f"type mismatch: '{source.ref}' is {source.type_name} but '{target.ref}' "
                                  f"is {target.type_name}")
            return False
        if source.enumeration:
            items = [self.components[p.component].info.enumeration(p.name)[1] for p in (source, target)]
            if items[0] != items[1]:
                described = [", ".join(f"{n} = {v}" for n, v in i.items()) for i in items]
                self.error(conn.line, f"type mismatch: Enumeration '{source.enumeration}' of '{source.ref}' "
                                      f"({described[0]}) is not the one of '{target.ref}' ({described[1]})")
                return False
        if conn.has_transform and source.type != "Real":
            self.error(conn.line, f"factor/offset need Real variables; '{source.ref}' is {source.type}")
            return False
        if source.unit and target.unit and source.unit != target.unit and not (conn.has_transform or conn.converts):
            self.error(conn.line, f"unit mismatch: '{source.ref}' is in '{source.unit}' but '{target.ref}' "
                                  f"expects '{target.unit}' (convert with factor/offset)")
            return False
        return True

    def _unconnected(self, links: List[Link]) -> None:
        """One warning for the whole scenario listing the inputs neither connected nor given a value
        in the scenario (an input given one under ``parameters:`` is deliberately set)."""
        driven = {l.target.ref for l in links}
        loose = []
        for component in self.components.values():
            given = {port.ref for port, _ in component.start_values}
            names = [name for name, v in component.info.variables.items() if v.causality == "input"
                     and v.type not in _NOT_CONNECTABLE and f"{component.name}.{name}" not in driven | given]
            loose += [f"{component.name}.{name}" for name in _ranges(names)]
        if loose:
            self.warn(None, f"input(s) not connected, kept at their start values: {', '.join(loose)} "
                            "(connect them, or give them a value under the component's parameters:)")

    # --- recording and settings ---------------------------------------------------------------
    def _recorded(self) -> List[Port]:
        patterns = self.scenario.outputs
        recorded: Dict[str, Port] = {}
        if not patterns:
            for component in self.components.values():
                for name, v in component.info.variables.items():
                    if v.causality == "output" and v.type not in _NOT_CONNECTABLE:
                        recorded.setdefault(f"{component.name}.{name}", _port(component, name))
            return list(recorded.values())
        for spec in patterns:
            for port in self._matches([spec.pattern], spec.line, "output", spec.origin):
                recorded.setdefault(port.ref, port)
        return list(recorded.values())

    def _matches(self, patterns: Sequence[str], line: Optional[int], what: str,
                 origin: Optional[str] = None) -> List[Port]:
        """The variables ``patterns`` name (``plant.z[*]``, ``*.u``), in order, each once; an
        error at ``line`` (or ``origin``) for a pattern that names none."""
        every = [(c, name) for c in self.components.values() for name, v in c.info.variables.items()
                 if v.type not in _NOT_CONNECTABLE]
        unresolved = {c.name for c in self.scenario.components} - set(self.components)
        found: Dict[str, Port] = {}
        for pattern in patterns:
            regex = pattern_regex(pattern)
            hits = [(c, n) for c, n in every if regex.match(f"{c.name}.{n}")] or self._array_named(pattern)
            if not hits:
                head = pattern_regex(pattern.split(".", 1)[0])
                if any(head.match(name) for name in unresolved):
                    continue  # it may name a variable of a component whose error is reported already
                candidates = [f"{c.name}.{n}" for c, n in every]
                hint = did_you_mean(pattern, candidates)
                names = list(self.components)
                if not hint and "." in pattern and not any(head.match(name) for name in names):
                    hint = f" (no component '{pattern.split('.', 1)[0]}': the components are {', '.join(names)})"
                self.error(line, f"{what} pattern '{pattern}' matches no variable{hint}", origin)
                continue
            for component, name in hits:
                port = _port(component, name)
                found.setdefault(port.ref, port)
        return list(found.values())

    def _interface(self, recorded: List[Port], links: Sequence[Link]) -> SystemInterface:
        """What the scenario exported as one FMU offers: ``exports:``, else the recorded variables,
        every unconnected input and the parameters this file sets; an error for an exported
        variable of the wrong kind (a connected input, an output given as a parameter, ...)."""
        exports = self.scenario.exports
        driven = {link.target.ref for link in links}
        components = [c for c in self.components.values() if c.name in {s.name for s in self.scenario.components}]

        def kind(port: Port) -> Tuple[str, str]:
            var = self.components[port.component].info.variables[port.name]
            return var.causality, var.variability

        def chosen(specs: Optional[Sequence[OutputSpec]], default: List[Port], what: str,
                   fits: Callable[[Port], Optional[str]]) -> Tuple[Port, ...]:
            if specs is None:
                ports = [p for p in default if fits(p) is None]
            else:
                ports = []
                for spec in specs:
                    for port in self._matches([spec.pattern], spec.line, f"exported {what}"):
                        why = fits(port)
                        if why is None:
                            ports.append(port)
                        elif "*" not in spec.pattern and "?" not in spec.pattern:
                            self.error(spec.line, f"exports: {what} '{port.ref}' {why}")
            unique: Dict[str, Port] = {}
            for port in ports:
                unique.setdefault(port.ref, port)
            return tuple(unique.values())

        def output(port: Port) -> Optional[str]:
            if port.type not in _EXPORTED_TYPES:
                return f"is a {port.type_name}: an exported variable is a Real, Integer or Boolean"
            return None if port.component in self.components else "is not a component's variable"

        def free_input(port: Port) -> Optional[str]:
            if kind(port)[0] != "input":
                return f"is {_article(kind(port)[0])}, not an input"
            if port.ref in driven:
                return "is connected: only an unconnected input can be the exported FMU's input"
            return output(port)

        def parameter(port: Port) -> Optional[str]:
            causality, variability = kind(port)
            if causality != "parameter" or variability == "constant":
                return f"is {_article(variability if variability == 'constant' else causality)}, not a parameter"
            return output(port)

        every_input = [_port(c, n) for c in components for n, v in c.info.variables.items() if v.causality == "input"]
        set_here = [_port(c, name) for c in components for p in c.spec.parameters if p.origin is None
                    for name in self._expanded(c, p.name)]
        return SystemInterface(chosen(exports.outputs, recorded, "output", output),
                               chosen(exports.inputs, every_input, "input", free_input),
                               chosen(exports.parameters, set_here, "parameter", parameter))

    def _expanded(self, component: ResolvedComponent, name: str) -> List[str]:
        try:
            return component.info.expand(name)
        except UnknownVariable:
            return []  # reported with the start values

    def _array_named(self, pattern: str) -> List[Tuple[ResolvedComponent, str]]:
        """The elements of the array ``component.array`` that ``pattern`` names (``plant.z`` records
        ``plant.z[1]``, ... as in a connection), else none."""
        comp_name, _, var = pattern.partition(".")
        component = self.components.get(comp_name)
        if component is None or var not in component.info.arrays:
            return []
        return [(component, name) for name in component.info.arrays[var]]

    def _settings(self) -> None:
        master = self.scenario.master
        if master.adaptive.enabled:
            multiples = [c.name for c in self.scenario.components if c.step_multiple != 1]
            if multiples:
                self.warn(None, f"step_multiple of {', '.join(multiples)} is ignored with an adaptive step")


def _outputs(component: ResolvedComponent) -> List[Port]:
    """Every output of ``component``, as ports."""
    return [_port(component, name) for name, v in component.info.variables.items() if v.causality == "output"]


def _with(recorded: List[Port], more: Sequence[Port]) -> List[Port]:
    """``recorded`` and then those of ``more`` not in it yet."""
    refs = {port.ref for port in recorded}
    added = []
    for port in more:
        if port.ref not in refs:
            refs.add(port.ref)
            added.append(port)
    return recorded + added


def _port(component: ResolvedComponent, name: str) -> Port:
    info = component.info
    var = info.variables[name]
    enumeration = info.enumeration(name)
    return Port(component.name, name, var.valueReference, bus_type(var.type),
                info.unit(name), enumeration[0] if enumeration else "",
                var.type if info.fmi3 and var.type != "Enumeration" else "", info.positions.get(name, 0))


def _shape_text(shape: Tuple[int, ...]) -> str:
    """``(3,)`` -> ``[3]``, ``(2, 3)`` -> ``[2, 3]``."""
    return f"[{', '.join(map(str, shape))}]"


def _ranges(names: Sequence[str]) -> List[str]:
    """Variable names with runs of consecutive array elements shortened: ``f[1], f[2], f[3]`` -> ``f[1:3]``."""
    out: List[str] = []
    run: Optional[Tuple[str, int, int]] = None  # (array name, first index, last index)
    for name in [*names, ""]:
        element = split_element(name)
        if element and run and run[0] == element[0] and element[1] == run[2] + 1:
            run = (run[0], run[1], run[2] + 1)
            continue
        if run:
            out.append(f"{run[0]}[{run[1]}]" if run[1] == run[2] else f"{run[0]}[{run[1]}:{run[2]}]")
            run = None
        if element:
            run = (element[0], element[1], element[1])
        elif name:
            out.append(name)
    return out


def _settable(var: Any) -> bool:
    if var.variability == "constant":
        return False
    if var.causality in _SETTABLE_CAUSALITIES:
        return True
    if var.initial in ("exact", "approx"):
        return True
    return var.initial is None and var.start is not None and var.causality == "local"


def start_value_problem(var: Any, value: Any) -> str:
    """Why ``value`` is not a start value the FMU variable ``var`` takes, the checks a scenario's
    ``parameters:`` pass (its type, finite, within its declared min and max, within its FMI 3.0
    integer type), else ``""``. For a value given as a number or a boolean (a study's cases)."""
    kind = _VALUE_KINDS.get(var.type, bus_type(var.type))
    if kind in _NOT_CONNECTABLE or var.type == "Enumeration":
        return ""
    if not _value_fits(kind, value):
        return f"type mismatch: it is {kind} but the value is {type(value).__name__}"
    return _outside_range(var, kind, value, _INTEGER_RANGES.get(var.type))


def _value_fits(kind: str, value: Any) -> bool:
    if kind == "Real":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind == "Integer":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "Boolean":
        return isinstance(value, bool)
    return isinstance(value, str)


def _outside_range(var: Any, kind: str, value: Any, limits: Optional[Tuple[int, int]] = None) -> str:
    """Why a Real or Integer start value is not one the FMU takes (not finite, or outside the
    min/max its modelDescription declares, declared type included, or outside the range of its
    FMI 3.0 integer type, ``limits``), else ``""``."""
    if kind not in ("Real", "Integer"):
        return ""
    if kind == "Real" and not math.isfinite(value):
        return "is not a finite number"
    declared = getattr(var, "declaredType", None)
    low, high = (_bound(var, declared, "min", -math.inf), _bound(var, declared, "max", math.inf))
    if limits is not None and not limits[0] <= value <= limits[1]:
        return f"is outside the range of {var.type} [{limits[0]}, {limits[1]}]"
    if low <= value <= high:
        return ""
    return f"is outside its declared range [{low:g}, {high:g}]"


def _bound(var: Any, declared: Any, which: str, default: float) -> float:
    for source in (var, declared):
        bound = getattr(source, which, None)
        if bound is not None:
            return float(bound)
    return default


def _article(causality: str) -> str:
    return f"an {causality}" if causality[0] in "aeiou" else f"a {causality}"


def pattern_regex(pattern: str) -> "re.Pattern[str]":
    """Glob of ``comp.var`` to a regex: ``*`` and ``?`` wildcards, ``[i:j]`` ranges, all else literal."""
    out = ""
    for token in re.split(r"(\*|\?|\[\d+:\d+\])", pattern):
        if token == "*":
            out += ".*"
        elif token == "?":
            out += "."
        elif re.fullmatch(r"\[\d+:\d+\]", token):
            lo, hi = map(int, token[1:-1].split(":"))
            out += r"\[(?:" + "|".join(str(i) for i in range(lo, hi + 1)) + r")\]"
        else:
            out += re.escape(token)
    return re.compile(out + r"\Z")


def describe(system: System) -> Sequence[str]:
    """Short human summary of a resolved system (printed by ``deltafmi validate``)."""
    lines = [f"{len(system.components)} components, {len(system.links)} scalar connections, "
             f"{len(system.recorded)} recorded variables",
             f"stepping order ({system.scenario.master.algorithm}): {' -> '.join(system.order)}"]
    for c in system.components:
        lines.append(f"  {c.name}: {c.interface} {c.info.md.modelName}, FMI {c.info.md.fmiVersion} ({c.fmu})")
    for c in system.live:
        lines.append(f"  {c.name}: {c.info.md.modelName[1:-1]}: {', '.join(c.info.variables)}")
    realtime = system.scenario.master.realtime
    if realtime.enabled:
        priority = "" if realtime.priority is None else f"; real-time priority {realtime.priority}"
        lines.append(f"paced to the wall clock at {realtime.speed:g}x (falling behind: {realtime.behind}{priority})")
    for stream, ports in zip(system.scenario.streams, system.streamed):
        where = stream.target if stream.kind == "udp" else "a plot window"
        lines.append(f"  stream to {where}: {', '.join(p.ref for p in ports)}")
    initial = {frozenset(loop.links): loop for loop in system.init_loops}
    solved = [(loop, "at initialization and at every step" if initial.pop(frozenset(loop.links), None)
               else "at every step") for loop in system.loops]
    for loop, when in solved + [(loop, "at initialization") for loop in initial.values()]:
        lines.append(f"{loop}: solved {when}, iterating on {', '.join(p.ref for p in loop.tears)}")
    return lines
