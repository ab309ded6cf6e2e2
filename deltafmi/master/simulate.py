"""``deltafmi.simulate``: run a scenario from Python and get its results in memory.

The same run as ``deltafmi run``: the same scenario loading (a shipped example's name, a YAML
file, an SSP archive, one FMU on its default experiment), the same overrides
(:func:`~deltafmi.master.scenario.overrides.with_overrides`, which ``run --set/--stop/--step/
--tolerance`` use), the same master. Nothing is printed: no progress bar, no summary. What the
FMUs log goes to Python's :mod:`logging` (logger ``deltafmi.fmu.<component>``) or to the
``on_message`` callback; scenario warnings (an unconnected input, ...) to the logger
``deltafmi.scenario``.
"""
from __future__ import annotations

import logging
from contextlib import ExitStack
from pathlib import Path
from tempfile import TemporaryDirectory
from typing import Any, Callable, List, Mapping, Optional, Sequence, Tuple

from deltafmi.errors import BadInput, Interrupted, ResultWriteError, SimulationError

from .results.result import Result, ResultRecorder
from .scenario.spec import Scenario

__all__ = ["simulate", "load_any", "FMU_LOGGER", "SCENARIO_LOGGER"]

#: FMU messages go to ``deltafmi.fmu.<component name>``
FMU_LOGGER = "deltafmi.fmu"
#: scenario and master warnings
SCENARIO_LOGGER = "deltafmi.scenario"
#: fmi2Status of a message -> logging level (OK, Warning, Discard, Error, Fatal, Pending)
_LEVELS = (logging.INFO, logging.WARNING, logging.WARNING, logging.ERROR, logging.CRITICAL, logging.INFO)
#: where a run kept in memory says its results are
_IN_MEMORY = Path("<memory>")


def simulate(scenario: str | Path | Scenario, *, stop: Optional[float] = None,
             parameters: Optional[Mapping[str, Any]] = None, start_values: Optional[Mapping[str, Any]] = None,
             step: Optional[float] = None, tolerance: Optional[float] = None,
             output: Optional[str | Path] = None, algorithm: Optional[str] = None,
             record: Optional[Sequence[str]] = None, allow_nan: Optional[bool] = None,
             fmi_version: Optional[int] = None, verbose: bool = False,
             on_message: Optional[Callable[[str, int, str, str], None]] = None,
             realtime: Optional[bool] = None, speed: Optional[float] = None, behind: Optional[str] = None,
             replay: Optional[str | Path] = None, threads: Optional[int] = None) -> Result:
    """Run ``scenario`` and return its :class:`~deltafmi.master.results.result.Result`.

    ``scenario``: a shipped example's name (``"delta_tracking"``), a scenario file (``.yaml``),
    an SSP archive (``.ssp``, ``.ssd``), one FMU (``.fmu``: run on its default experiment, every
    output recorded) or a :class:`Scenario` from :func:`deltafmi.load_scenario`.

    ``parameters`` and ``start_values`` (``{"controller.kp": 100, "plant.z0": [0.1, 0, -1.0]}``,
    ``"plant.z0[3]": -1.05`` for one element) set values as the YAML's ``parameters:`` do; the
    two are one mapping under two names (FMI sets both with start values; a name may be in one
    only). ``stop``, ``step`` (communication step [s]) and ``tolerance`` (every component's
    relative tolerance) replace the scenario's; ``algorithm``: ``"gauss-seidel"`` or
    ``"jacobi"``; ``record``: patterns of the variables to record (``["plant.z[*]",
    "controller.*"]``), replacing the scenario's ``outputs:``; ``allow_nan``: let Reals become
    NaN without stopping the run; ``fmi_version``: build the components given by ``source:`` as
    FMI 2.0 or 3.0 FMUs. The options are those of ``deltafmi run``: ``--set``, ``--stop``,
    ``--step``, ``--tolerance``, ``--algorithm``, ``--record``, ``--allow-nan``,
    ``--fmi-version``, ``-o``, ``-v``. ``realtime``/``speed`` pace the run to the wall clock
    (``--realtime``, ``--speed``; the summary's ``live`` says how well it kept up; ``behind``:
    "warn" or "error" when it falls a whole step behind); ``replay``: the
    results file of an earlier run of this scenario whose live inputs stand in for its live
    sources (``--replay``; not paced unless ``realtime`` or ``speed`` says so); ``threads``: step
    the units that do not depend on each other on this many threads (``--threads``,
    ``master.threads``; the same results, bit for bit).

    ``output``: also write the results to this file (``.csv``, ``.parquet``, ``.mat``) as the
    run goes. ``verbose``: the FMUs send their debug messages too. ``on_message(component,
    status, category, text)`` receives every FMU message instead of :mod:`logging`.

    Raises :class:`~deltafmi.errors.ScenarioError` (an invalid scenario, an unknown variable) or
    :class:`~deltafmi.errors.BadInput` (a bad option) before anything runs, and
    :class:`~deltafmi.errors.SimulationError` (or :class:`~deltafmi.errors.Interrupted` after
    Ctrl-C, :class:`~deltafmi.errors.ResultWriteError` when ``output`` cannot take more rows)
    when the run fails; the error's ``result`` holds every row computed up to the failure.
    """
    from .results.safe_file import check_writable
    from .results.writers import writer_for
    from .scenario.overrides import with_overrides
    from .scenario.resolve import resolve_system
    from .stepping.master import Master

    if output is not None:
        writer_for(output)  # an unknown extension fails before anything is built
    for name, flag in (("verbose", verbose), ("allow_nan", allow_nan), ("realtime", realtime)):
        if flag is not None and type(flag).__name__ not in ("bool", "bool_"):  # "yes" would reach the FMUs
            raise BadInput(f"simulate({name}={flag!r}): expected True or False")
    if on_message is not None and not callable(on_message):
        raise BadInput(f"simulate(on_message={on_message!r}): expected a function (component, status, "
                       "category, text)")
    _check_mapping(parameters, "parameters")
    _check_mapping(start_values, "start_values")
    with ExitStack() as resources:
        loaded = load_any(scenario, resources, stop)
        _check_given_once(loaded, parameters or {}, start_values or {})
        loaded = with_overrides(loaded, parameters or {}, origin="parameters")
        loaded = with_overrides(loaded, start_values or {}, stop=stop, step=step, tolerance=tolerance,
                                allow_nan=allow_nan, algorithm=algorithm, record=record, fmi_version=fmi_version,
                                realtime=False if replay is not None and realtime is None and speed is None
                                else realtime, speed=speed, behind=behind, threads=threads, origin="start_values")
        system = resolve_system(loaded)
        scenario_log = logging.getLogger(SCENARIO_LOGGER)
        for diagnostic in system.warnings:
            scenario_log.warning("%s", diagnostic)
        recorded = system.recorded
        units = [p.unit for p in recorded]
        kept: list = []
        messages = _Messages(on_message or _log_message)

        def recorder(path: Path, names: Any, kinds: Any = None) -> ResultRecorder:
            kinds = list(kinds) if kinds is not None else ["Real"] * len(names)
            file_writer = writer_for(path)(path, names, kinds=kinds, units=units) if output is not None else None
            kept.append(ResultRecorder(names, kinds, units, file_writer, after_rows=messages.deliver))
            return kept[-1]

        if output is not None:
            check_writable(Path(output))
        master = Master(system, result=Path(output) if output is not None else _IN_MEMORY, progress=False,
                        warn=scenario_log.warning, writer_class=recorder,
                        on_message=messages.add, debug_logging=verbose,
                        replay=Path(replay) if replay is not None else None)
        try:
            summary = master.run()
        except (SimulationError, Interrupted, ResultWriteError) as exc:
            exc.result = kept[0].result() if kept else None  # type: ignore[attr-defined]
            if output is None:
                exc.message = exc.message.replace(f" in {_IN_MEMORY}", " in the error's .result")
            raise
        finally:
            messages.deliver()
    return kept[0].result(summary)


def load_any(scenario: Any, resources: ExitStack, stop: Optional[float] = None) -> Scenario:
    """A :class:`Scenario` from what the user gave (``deltafmi run`` and :func:`simulate` alike):
    a loaded one as is, one FMU (:func:`~.scenario.fmu_scenario.fmu_scenario`), an SSP archive
    (its FMUs unpacked into a temporary folder that ``resources`` removes after the run;
    ``stop`` stands in for an SSP without a stop time), else a scenario file or a shipped
    example's name (:func:`~.scenario.spec.load_scenario`)."""
    from .scenario.fmu_scenario import fmu_scenario, is_fmu
    from .scenario.spec import load_scenario
    from .ssp import is_ssp

    if isinstance(scenario, Scenario):
        return scenario
    if not isinstance(scenario, (str, Path)):
        raise BadInput(f"simulate() takes a scenario name, a file or a Scenario, not {type(scenario).__name__}")
    if is_ssp(scenario):
        from .ssp.read import load_ssp  # here: its module loads lxml

        workdir = resources.enter_context(TemporaryDirectory(prefix="deltafmi-ssp-"))
        return load_ssp(scenario, Path(workdir), stop)
    if is_fmu(scenario):
        return fmu_scenario(scenario)
    return load_scenario(scenario)


def _check_given_once(scenario: Scenario, parameters: Mapping[str, Any], start_values: Mapping[str, Any]) -> None:
    """:class:`BadInput` when a variable is in both mappings (``"plant.z0"`` and, in a
    one-component scenario, a bare ``"z0"`` are the same variable)."""
    from .scenario.overrides import split_name

    given = {split_name(scenario, str(name), "parameters"): name for name in parameters}
    both = sorted(str(name) for name in start_values if split_name(scenario, str(name), "start_values") in given)
    if both:
        raise BadInput(f"{', '.join(both)}: given in both parameters and start_values; give each name once")


def _check_mapping(values: Any, what: str) -> None:
    if values is not None and not isinstance(values, Mapping):
        raise BadInput(f"{what} must be a mapping of names to values, e.g. {{'controller.kp': 100}}, "
                       f"not {type(values).__name__}")


class _Messages:
    """FMU messages held until :meth:`deliver`: a message arrives while an FMU call runs on
    this thread, where a deltafmi FMU takes every logging record for itself (see
    :mod:`deltafmi.runtime.fmu_logging`); delivered between steps, they reach the host."""

    def __init__(self, deliver_to: Callable[[str, int, str, str], None]) -> None:
        self.held: List[Tuple[str, int, str, str]] = []
        self.deliver_to = deliver_to

    def add(self, component: str, status: int, category: str, text: str) -> None:
        """The master's ``on_message``."""
        self.held.append((component, status, category, text))

    def deliver(self) -> None:
        """Pass on every message held, in order."""
        while self.held:
            held, self.held = self.held, []
            for message in held:
                self.deliver_to(*message)


def _log_message(component: str, status: int, category: str, text: str) -> None:
    """An FMU's message to the logger ``deltafmi.fmu.<component>``."""
    level = _LEVELS[status] if 0 <= status < len(_LEVELS) else logging.ERROR
    logger = logging.getLogger(f"{FMU_LOGGER}.{component}")
    if category in ("logEvents", "logComponent", "logSolver") and level == logging.INFO:
        level = logging.DEBUG if category != "logComponent" else logging.INFO
    logger.log(level, "%s", text, extra={"fmi_category": category, "fmi_status": status})
