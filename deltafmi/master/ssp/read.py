"""Read an SSP 1.0 archive (or a bare ``.ssd`` file) into a :class:`Scenario`.

The SSD is checked against the SSP 1.0 schema, then turned into the data of a YAML scenario
(components with their FMU files, start values from the parameter bindings, scalar connections
with their ``ssc:LinearTransformation``, the ``com.deltafmi`` annotations of :mod:`.write`)
that goes through the same schema check and, in :func:`~deltafmi.master.scenario.resolve.resolve_system`,
the same validation as a YAML file. Diagnostics name ``<archive>/SystemStructure.ssd`` and the
SSD's line numbers.

Supported: a flat system of FMU components with inline or ``.ssv`` parameter sets (component or
system level, with ``prefix``), Real/Integer/Boolean/String/Enumeration parameters and
connectors, linear transformations. Not supported (reported, never ignored): nested systems,
signal dictionaries, connections to the system's own connectors, parameter mappings, mapping
transformations, components that are not FMUs. Without a ``com.deltafmi`` step the
communication step is libcosim's ``osp:FixedStepAlgorithm baseStepSize``, else the smallest
``stepSize`` of the FMUs' default experiments.
"""
from __future__ import annotations

import posixpath
import re
import zipfile
from dataclasses import replace
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple
from urllib.parse import unquote, urlsplit

from lxml import etree

from deltafmi.errors import Diagnostic, ScenarioError, did_you_mean

from . import is_ssp
from ..scenario.spec import ResultSettings, Scenario, scenario_from_data
from ..scenario.line_map import LineMap
from .format import (ANNOTATION_TYPE, FMU_MIME_TYPE, NAMESPACES, OSP_ANNOTATION_TYPE,
                         PARAMETER_SET_MIME_TYPE, SSD_NAME, schema_problems, tag)

__all__ = ["is_ssp", "load_ssp"]

#: annotation attributes that stay text (every other one is read as a number or boolean)
_TEXT_KEYS = {"algorithm", "error_estimate", "method", "format", "file", "pattern"}
_INTEGER = re.compile(r"[-+]?\d+\Z")


def load_ssp(path: str | Path, workdir: Path, stop: Optional[float] = None) -> Scenario:
    """The scenario of the SSP archive (or ``.ssd``) at ``path``; FMUs of an archive are unpacked
    into ``workdir``. ``stop`` stands in for a missing ``DefaultExperiment stopTime``. Raises
    :class:`ScenarioError` (exit code 2) with every problem found."""
    return _Reader(Path(path), Path(workdir), stop).scenario()


class _Reader:
    def __init__(self, path: Path, workdir: Path, stop: Optional[float]) -> None:
        self.path = path
        self.archive = path.suffix.lower() == ".ssp"
        #: what diagnostics name: the SSD, inside the archive for an .ssp
        self.file = f"{path}/{SSD_NAME}" if self.archive else str(path)
        self.workdir = workdir
        self.stop = stop
        self.found: List[Diagnostic] = []
        self.data: Dict[str, Any] = {}
        self.lines = LineMap()
        self._zip: Optional[zipfile.ZipFile] = None
        self._result_file: Optional[str] = None

    # --- top level ----------------------------------------------------------------------------
    def scenario(self) -> Scenario:
        try:
            text = self._read(None, None)
            self._raise()
            root = self._parse(text or b"", None)
            self._system(root)
            self._experiment(root)
            self._results(root)
        finally:
            if self._zip is not None:
                self._zip.close()
        self._raise()
        scenario = scenario_from_data(self.data, self.lines, Path(self.file))
        return replace(scenario, path=Path(self.file), result=self._result_settings(scenario.result))

    def error(self, line: Optional[int], message: str) -> None:
        self.found.append(Diagnostic(self.file, line, message))

    def _raise(self) -> None:
        if self.found:
            raise ScenarioError(self.found)

    def _read(self, member: Optional[str], line: Optional[int], owner: str = "") -> Optional[bytes]:
        """Bytes of the SSD (``member`` None) or of a file it names (for ``owner``, which starts the
        message), from the archive or next to the .ssd; None (reported) when missing."""
        try:
            if not self.archive:
                return (self.path if member is None else self.path.parent / member).read_bytes()
            if self._zip is None:
                self._zip = zipfile.ZipFile(self.path)
            return self._zip.read(member or SSD_NAME)
        except KeyError:
            names = self._zip.namelist() if self._zip else []
            self.error(line, f"{owner}no '{member or SSD_NAME}' in the archive{did_you_mean(member or SSD_NAME, names)}"
                             + ("" if names else " (it is empty)"))
        except (OSError, zipfile.BadZipFile) as exc:
            reason = getattr(exc, "strerror", None) or str(exc)
            if member is None:  # the archive or the .ssd itself
                what = "SSP archive" if self.archive else "SSD"
                self.found.append(Diagnostic(str(self.path), None, f"cannot read {what}: {reason}"))
            else:
                self.error(line, f"{owner}cannot read '{member}' next to the SSD: {reason}")
        return None

    def _parse(self, text: bytes, line: Optional[int], kind: str = "ssd") -> Optional[etree._Element]:
        """Parse and schema-check the SSD (raises on any problem), or an .ssv file that a binding
        at ``line`` names (``kind="ssv"``: None, reported, on a problem)."""
        parser = etree.XMLParser(resolve_entities=False, no_network=True)
        before = len(self.found)
        try:
            root = etree.fromstring(text, parser)
        except etree.XMLSyntaxError as exc:
            self.error(exc.lineno if kind == "ssd" else line, f"XML syntax error: {exc.msg}")
            root = None
        if root is not None:
            for where, message in schema_problems(root, kind):
                self.error(where if kind == "ssd" else line, f"not valid SSP 1.0: {message}")
            if kind == "ssd":  # the SSD schema leaves inline parameter sets unchecked (xs:any)
                for parameter_set in root.iter(tag("ssv", "ParameterSet")):
                    for where, message in schema_problems(parameter_set, "ssv"):
                        self.error(where, f"not valid SSP 1.0: {message}")
        if kind == "ssd":
            self._raise()
        return root if len(self.found) == before else None

    # --- system -------------------------------------------------------------------------------
    def _system(self, root: etree._Element) -> None:
        system = root.find(tag("ssd", "System"))
        self.lines.value_lines[()] = root.sourceline
        if system.get("description"):
            self.data["description"] = system.get("description")
        dictionaries = system.find(tag("ssd", "SignalDictionaries"))
        if dictionaries is not None:
            self.error(dictionaries.sourceline, "signal dictionaries are not supported")
        components: Dict[str, Any] = {}
        self.data["components"] = components
        self._put(("components",), None, system.sourceline)
        elements = system.find(tag("ssd", "Elements"))
        connectors: Dict[str, set] = {}
        for element in elements if elements is not None else ():
            if not isinstance(element.tag, str):
                continue  # a comment
            if element.tag != tag("ssd", "Component"):
                kind = etree.QName(element).localname
                self.error(element.sourceline, f"'{element.get('name')}': {_UNSUPPORTED_ELEMENTS.get(kind, kind)} "
                                               "are not supported (a flat system of FMU components is)")
                continue
            name = element.get("name")
            if name in components:
                self.error(element.sourceline, f"component '{name}' is defined twice")
                continue
            connectors[name] = {c.get("name") for c in element.iterfind("ssd:Connectors/ssd:Connector", NAMESPACES)}
            components[name] = self._component(element)
        self._system_parameters(system, components)
        self._connections(system, connectors)

    def _component(self, element: etree._Element) -> Dict[str, Any]:
        name, line = element.get("name"), element.sourceline
        path = ("components", name)
        self.lines.key_lines[path] = line
        self.lines.value_lines[path] = line
        spec: Dict[str, Any] = {}
        if element.get("type", FMU_MIME_TYPE) != FMU_MIME_TYPE:
            self.error(line, f"component '{name}': type '{element.get('type')}' is not supported "
                             f"(only FMUs, {FMU_MIME_TYPE})")
            return spec
        fmu = self._component_file(name, element.get("source"), line)
        if fmu is not None:
            spec["fmu"] = str(fmu)
        implementation = element.get("implementation", "any")
        if implementation != "any":
            self._put(path + ("interface",), "ME" if implementation == "ModelExchange" else "CS", line, spec)
        parameters: Dict[str, Any] = {}
        for binding in element.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NAMESPACES):
            for parameter, value, where in self._binding(binding, f"component '{name}'"):
                self._put(path + ("parameters", parameter), value, where, parameters)
        if parameters:
            spec["parameters"] = parameters
        for annotation in self._annotations(element, "dfmi:Component"):
            for key, value in annotation.attrib.items():
                self._put(path + (key,), _typed(key, value), annotation.sourceline, spec)
            solver = annotation.find("dfmi:Solver", NAMESPACES)
            if solver is not None:
                spec["solver"] = {}
                self._put(path + ("solver",), None, solver.sourceline)
                for key, value in solver.attrib.items():
                    self._put(path + ("solver", key), _typed(key, value), solver.sourceline, spec["solver"])
        return spec

    def _component_file(self, name: str, source: str, line: int) -> Optional[Path]:
        """The FMU a component's ``source`` URI names: unpacked from the archive, or next to the .ssd."""
        uri = urlsplit(source)
        relative = unquote(uri.path)
        if uri.scheme or uri.netloc or uri.fragment or relative.startswith("/"):
            self.error(line, f"component '{name}': source '{source}' is not supported "
                             "(give a relative path, such as resources/Model.fmu)")
            return None
        relative = posixpath.normpath(relative)
        if relative.startswith("../"):
            self.error(line, f"component '{name}': source '{source}' points outside the "
                             f"{'archive' if self.archive else 'SSD folder'}")
            return None
        if not self.archive:
            path = self.path.parent / relative
            if not path.is_file():
                self.error(line, f"component '{name}': FMU '{source}' not found next to the SSD")
                return None
            return path
        target = self.workdir / relative
        if not target.is_file():
            data = self._read(relative, line, f"component '{name}': ")
            if data is None:
                return None
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
        return target

    def _binding(self, binding: etree._Element, owner: str) -> List[Tuple[str, Any, int]]:
        """(name, value, line) of each parameter of a ParameterBinding, its prefix prepended."""
        line = binding.sourceline
        if binding.get("type", PARAMETER_SET_MIME_TYPE) != PARAMETER_SET_MIME_TYPE:
            self.error(line, f"{owner}: parameter binding of type '{binding.get('type')}' is not supported")
            return []
        mapping = binding.find("ssd:ParameterMapping", NAMESPACES)
        if mapping is not None:
            self.error(mapping.sourceline, f"{owner}: parameter mappings are not supported")
            return []
        if binding.get("sourceBase", "SSD") != "SSD":
            self.error(line, f"{owner}: parameter binding sourceBase '{binding.get('sourceBase')}' is not supported")
            return []
        source = binding.get("source")
        if source:
            text = self._read(posixpath.normpath(unquote(source)), line, f"{owner}: parameter set ")
            parameter_set = self._parse(text, line, "ssv") if text is not None else None
            if parameter_set is None:
                return []
            located = False  # lines of another file: point at the binding
        else:
            parameter_set = binding.find("ssd:ParameterValues/ssv:ParameterSet", NAMESPACES)
            if parameter_set is None:
                return []
            located = True
        prefix = binding.get("prefix", "")
        values = []
        for parameter in parameter_set.iterfind("ssv:Parameters/ssv:Parameter", NAMESPACES):
            typed = next(iter(parameter.iterchildren(tag("ssv", "*"))))
            kind, text = etree.QName(typed).localname, typed.get("value")
            where = parameter.sourceline if located else line
            if kind == "Binary":
                self.error(where, f"{owner}: parameter '{parameter.get('name')}': Binary values are not supported")
                continue
            values.append((prefix + parameter.get("name"), _parameter_value(kind, text), where))
        return values

    def _system_parameters(self, system: etree._Element, components: Dict[str, Any]) -> None:
        """System-level bindings name ``component.variable``; they take precedence (SSP 1.0)."""
        for binding in system.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NAMESPACES):
            for name, value, line in self._binding(binding, "system"):
                component, _, variable = name.partition(".")
                if component not in components or not variable:
                    self.error(line, f"system parameter '{name}' names no component"
                                     f"{did_you_mean(component, list(components))}")
                    continue
                parameters = components[component].setdefault("parameters", {})
                parameters.pop(variable, None)  # re-inserted last: applied after the component's own
                self._put(("components", component, "parameters", variable), value, line, parameters)

    def _connections(self, system: etree._Element, connectors: Dict[str, set]) -> None:
        connections: List[Dict[str, Any]] = []
        for connection in system.iterfind("ssd:Connections/ssd:Connection", NAMESPACES):
            line = connection.sourceline
            ends = []
            for side in ("start", "end"):
                element, connector = connection.get(f"{side}Element"), connection.get(f"{side}Connector")
                if element is None:
                    self.error(line, f"connection {side}s at the system's own connector '{connector}': "
                                     "not supported (connect component to component)")
                elif element not in connectors:
                    self.error(line, f"connection {side}s at unknown component '{element}'"
                                     f"{did_you_mean(element, list(connectors))}")
                elif connector not in connectors[element]:
                    self.error(line, f"'{connector}' is not a connector of component '{element}' (declare it "
                                     f"in its ssd:Connectors){did_you_mean(connector, connectors[element])}")
                ends.append(f"{element}.{connector}")
            spec: Dict[str, Any] = {}
            for transformation in connection.iterchildren(tag("ssc", "*")):
                kind = etree.QName(transformation).localname
                if kind != "LinearTransformation":
                    self.error(transformation.sourceline, f"connection {ends[0]} -> {ends[1]}: {kind} is not "
                                                          "supported (LinearTransformation is)")
                    continue
                spec["factor"] = float(transformation.get("factor", "1.0"))
                spec["offset"] = float(transformation.get("offset", "0.0"))
            path = ("connections", len(connections))
            for key, value in (("from", ends[0]), ("to", ends[1])):
                self._put(path + (key,), value, line, spec)
            self.lines.value_lines[path] = line
            connections.append(spec)
        if connections:
            self.data["connections"] = connections

    # --- experiment and results ---------------------------------------------------------------
    def _experiment(self, root: etree._Element) -> None:
        experiment: Dict[str, Any] = {}
        self.data["experiment"] = experiment
        default = root.find(tag("ssd", "DefaultExperiment"))
        line = default.sourceline if default is not None else root.sourceline
        self.lines.value_lines[("experiment",)] = line
        if default is not None and default.get("startTime") is not None:
            self._put(("experiment", "start"), float(default.get("startTime")), line, experiment)
        stop = default.get("stopTime") if default is not None else None
        if stop is not None:
            self._put(("experiment", "stop"), float(stop), line, experiment)
        elif self.stop is not None:
            experiment["stop"] = float(self.stop)
        else:
            self.error(line, "no DefaultExperiment stopTime: give one, or the stop time with --stop")
        master: Dict[str, Any] = {}
        for annotation in self._annotations(default, "dfmi:Master"):
            self.lines.value_lines[("master",)] = annotation.sourceline
            for key, value in annotation.attrib.items():
                where = ("experiment",) if key == "step" else ("master",)
                self._put(where + (key,), _typed(key, value), annotation.sourceline,
                          experiment if key == "step" else master)
            adaptive = annotation.find("dfmi:Adaptive", NAMESPACES)
            if adaptive is not None:
                master["adaptive"] = {}
                self._put(("master", "adaptive"), None, adaptive.sourceline)
                for key, value in adaptive.attrib.items():
                    self._put(("master", "adaptive", key), _typed(key, value), adaptive.sourceline,
                              master["adaptive"])
        if master:
            self.data["master"] = master
        if "step" not in experiment:
            step = self._fallback_step(default)
            if step is None:
                self.error(line, "no communication step: SSP 1.0 has none; give it as a com.deltafmi "
                                 "annotation (<dfmi:Master step=\"0.001\"/>) or an osp:FixedStepAlgorithm "
                                 "baseStepSize, or in the FMUs' DefaultExperiment stepSize")
            else:
                experiment["step"] = step

    def _fallback_step(self, default: Optional[etree._Element]) -> Optional[float]:
        """libcosim's base step, else the smallest stepSize of the FMUs' default experiments."""
        for annotation in self._annotations(default, "osp:Algorithm", OSP_ANNOTATION_TYPE):
            fixed = annotation.find("osp:FixedStepAlgorithm", NAMESPACES)
            if fixed is not None and fixed.get("baseStepSize"):
                self.lines.value_lines[("experiment", "step")] = fixed.sourceline
                return _typed("step", fixed.get("baseStepSize"))
        from fmpy import read_model_description
        steps = []
        for spec in self.data["components"].values():
            if "fmu" in spec:
                experiment = read_model_description(spec["fmu"], validate=False).defaultExperiment
                if experiment is not None and experiment.stepSize:
                    steps.append(float(experiment.stepSize))
        return min(steps) if steps else None

    def _results(self, root: etree._Element) -> None:
        for annotation in self._annotations(root, "dfmi:Results"):
            line = annotation.sourceline
            result: Dict[str, Any] = {}
            self.lines.value_lines[("result",)] = line
            for key, value in annotation.attrib.items():
                if key != "file":  # resolved against the archive's folder in _result_settings
                    self._put(("result", key), _typed(key, value), line, result)
            self._result_file = annotation.get("file")
            self.data["result"] = result
            outputs: List[str] = []
            for record in annotation.iterfind("dfmi:Record", NAMESPACES):
                self._put(("outputs", len(outputs)), record.get("pattern"), record.sourceline)
                outputs.append(record.get("pattern"))
            if outputs:
                self.data["outputs"] = outputs

    def _result_settings(self, result: ResultSettings) -> ResultSettings:
        """The result file, relative to the folder of the archive (default ``<archive>.csv`` here)."""
        file = self._result_file
        if file is None:
            return replace(result, file=Path(self.path.stem + ".csv"))
        path = Path(file)
        return replace(result, file=path if path.is_absolute() else self.path.parent / path)

    # --- helpers ------------------------------------------------------------------------------
    def _annotations(self, parent: Optional[etree._Element], content: str,
                     kind: str = ANNOTATION_TYPE) -> List[etree._Element]:
        """The ``content`` elements (``prefix:Name``) of ``parent``'s annotations of type ``kind``."""
        if parent is None:
            return []
        found = []
        for annotation in parent.iterfind("ssd:Annotations/ssc:Annotation", NAMESPACES):
            if annotation.get("type") != kind:
                continue
            for child in annotation.iterfind(content, NAMESPACES):
                found.append(child)
        return found

    def _put(self, path: Tuple[Any, ...], value: Any, line: Optional[int],
             into: Optional[Dict[str, Any]] = None) -> None:
        """Record ``line`` for ``path`` (and store ``value`` under its last key in ``into``)."""
        if line is not None:
            self.lines.value_lines[path] = line
            self.lines.key_lines[path] = line
        if into is not None:
            into[path[-1]] = value


_UNSUPPORTED_ELEMENTS = {"System": "nested systems", "SignalDictionaryReference": "signal dictionary references"}


def _parameter_value(kind: str, text: str) -> Any:
    """An ssv value (schema-checked) as the Python value a YAML scenario would hold."""
    if kind == "Real":
        return float(text)
    if kind == "Integer":
        return int(text)
    if kind == "Boolean":
        return text.strip() in ("true", "1")
    return text  # String, and an Enumeration's item name


def _typed(key: str, text: str) -> Any:
    """An annotation attribute as the YAML value it stands for: number, boolean or text."""
    if key in _TEXT_KEYS:
        return text
    stripped = text.strip()
    if stripped in ("true", "false"):
        return stripped == "true"
    if _INTEGER.match(stripped):
        return int(stripped)
    try:
        return float(stripped)
    except ValueError:
        return text  # the schema check reports it
