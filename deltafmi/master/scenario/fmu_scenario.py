"""The scenario of one FMU on its own (``deltafmi run Model.fmu``), as fmpy's ``simulate_fmu`` runs it.

One component named after the model, its inputs left at their start values, every output
recorded; the time span, step and tolerance of the FMU's default experiment. Like fmpy, the
component uses Co-Simulation when the FMU offers it, else Model Exchange (integrated by the
master's CVODE): the FMU author's own solver is the one the FMU was made for.
"""
from __future__ import annotations

import re
from pathlib import Path

from deltafmi.errors import Diagnostic, ScenarioError

from .modelinfo import model_info
from .spec import ComponentSpec, Experiment, MasterSettings, ResultSettings, Scenario

__all__ = ["fmu_scenario", "is_fmu"]


def is_fmu(path: str | Path) -> bool:
    """True when ``path`` names an FMU (by its extension)."""
    return str(path).lower().endswith(".fmu")


def fmu_scenario(path: str | Path) -> Scenario:
    """A one-component :class:`Scenario` that runs the FMU at ``path`` on its default experiment:
    start (else 0), stop (else start + 1 s), communication step (else fmpy's choice for the
    span, 500 to 1000 steps), tolerance as the solver's rtol (else the master's default).
    The result file is ``<file name>.csv`` in the current folder. Raises :class:`ScenarioError`
    (exit code 2) when the file is missing or is not an FMU."""
    path = Path(path)
    if path.is_dir():
        raise ScenarioError([Diagnostic(str(path), None, "a folder, not an FMU file (an FMU is one .fmu file, a "
                                        "zip archive)")])
    if not path.is_file():
        raise ScenarioError([Diagnostic(str(path), None, "no such FMU file")])
    try:
        info = model_info(str(path))
    except Exception as exc:  # noqa: BLE001 - any unreadable file is the user's input error
        raise ScenarioError([Diagnostic(str(path), None, f"cannot read it as an FMU: {exc}")]) from None
    md = info.md
    default = md.defaultExperiment
    start = float(default.startTime) if default is not None and default.startTime is not None else 0.0
    stop = float(default.stopTime) if default is not None and default.stopTime is not None else start + 1.0
    if default is not None and default.stepSize is not None and float(default.stepSize) > 0:
        step = float(default.stepSize)
    else:
        from fmpy.simulation import auto_interval
        step = float(auto_interval(stop - start))
    solver = {}
    if default is not None and default.tolerance is not None:
        solver["rtol"] = float(default.tolerance)
    name = re.sub(r"\W", "_", md.modelName or path.stem)
    name = name if re.match(r"[A-Za-z_]", name) else f"_{name}"
    component = ComponentSpec(name=name, line=None, fmu=str(path.resolve()), solver=solver)
    return Scenario(path, Experiment(start, stop, step), MasterSettings(), (component,), (), (),
                    ResultSettings(Path(path.stem + ".csv")), description=md.description or "", single_fmu=True)
