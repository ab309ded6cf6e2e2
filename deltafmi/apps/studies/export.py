"""One case of a study as a plain scenario file (``deltafmi study-case``), to run it alone."""
from __future__ import annotations

import yaml

from deltafmi.master.scenario.yaml_lines import load_yaml

from .cases import Case
from .plan import PlannedStudy

__all__ = ["case_scenario"]


def case_scenario(planned: PlannedStudy, case: Case) -> str:
    """The study's scenario as YAML with ``case``'s values set: start values are added after the
    scenario's own (so they win), FMUs are named by absolute path (the files the study used),
    the recorded variables are the study's (the scenario's plus what the metrics need)."""
    data, _ = load_yaml(planned.study.scenario.read_text())
    fmus = {c.name: str(c.fmu.resolve()) for c in planned.system.components}
    for name, spec in data["components"].items():
        spec.pop("source", None)
        spec["fmu"] = fmus[name]
    for target, value in case.values.items():
        component, variable = target.split(".", 1)
        if component == "experiment":
            data["experiment"][variable] = value
        else:
            parameters = data["components"][component].setdefault("parameters", {}) or {}
            parameters.pop(variable, None)  # re-added last
            parameters[variable] = value
            data["components"][component]["parameters"] = parameters
    data["outputs"] = [spec.pattern for spec in planned.plan.scenario.outputs]
    result = data.get("result") or {}
    result.pop("file", None)
    if result:
        data["result"] = result
    else:
        data.pop("result", None)
    data["description"] = (f"Case {case.id} of the study {planned.study.path}: {case.describe()}. "
                           + str(data.get("description", "")))
    return yaml.safe_dump(data, sort_keys=False, width=100)
