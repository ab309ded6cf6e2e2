"""What runs inside a scenario exported as one FMU: a component whose ``do_step`` is the master's.

The FMU carries the scenario (``resources/system.yaml``, every component given by ``fmu:``) and
its units' FMUs. At initialization the component loads the scenario with the FMU's parameters and
inputs as start values (the path of ``deltafmi run --set``), resolves it and opens a
:class:`~deltafmi.master.stepping.master.Master` on it: the same initialization, stepping
order, loop solving and units as ``deltafmi run``. Each ``doStep`` takes the master's fixed
steps that make it up, the unconnected inputs set first; the outputs are the recorded
variables. Where the units fit the master's C loop the FMU's C layer takes those steps itself,
with no Python (:mod:`.direct`), and hands Python what only Python does. FMU states are the
master's snapshots (every unit's FMU state and the buses).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar, Dict, List, Optional, Tuple

import numpy as np

from deltafmi.component import Component
from deltafmi.master.scenario.overrides import with_overrides
from deltafmi.master.scenario.resolve import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.scenario.system import Port, bus_type
from deltafmi.master.stepping.master import Master

from .direct import DirectStep, compiled_step

__all__ = ["SystemComponent"]

#: an FMU message's status (fmi2OK ... fmi2Fatal) -> Component.log level
_LEVELS = ("info", "warning", "warning", "error", "error", "info")
#: steps of a run whose importer gives no stop time: the horizon of the master's grid
_OPEN_ENDED_STEPS = 10 ** 8


class _NoRows:
    """The master's result writer inside the FMU: the importer records what it wants."""

    rows_written = 0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def write(self, time: float, values: np.ndarray) -> None:
        pass

    def write_rows(self, rows: np.ndarray) -> None:
        pass

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


class _Run:
    """One master run of the scenario, opened with the given start values."""

    def __init__(self, component: "SystemComponent", given: Dict[str, Any], start: float,
                 stop: Optional[float]) -> None:
        cls = type(component)
        scenario = load_scenario(Path(component.resources_dir) / cls.scenario_file)
        if abs(start - scenario.experiment.start) > 1e-9 * max(1.0, abs(start)):
            raise ValueError(f"the scenario starts at t = {scenario.experiment.start:g} s, not {start:g} s")
        if stop is None:
            stop = start + _OPEN_ENDED_STEPS * scenario.experiment.step
        scenario = with_overrides(scenario, given, stop=stop, record=[ref for _, ref in cls.outputs_exported],
                                  origin="the FMU's start values")
        system = resolve_system(scenario)
        self.given = given
        #: the units' messages so far (the C step leaves a step with one to Python, which passes it on)
        self.messages = np.zeros(1, dtype=np.int64)
        self.master = Master(system, result=Path("<system FMU>"), writer_class=_NoRows,
                             warn=lambda text: component.log(text, "warning"),
                             on_message=lambda unit, status, category, text: self._message(
                                 component, unit, status, text))
        units = {unit.name: unit for unit in system.components}
        self.inputs: List[Tuple[str, Port]] = []
        for attribute, ref in cls.inputs_exported:
            name, _, variable = ref.partition(".")
            info = units[name].info
            var = info.variables[variable]
            self.inputs.append((attribute, Port(name, variable, var.valueReference, bus_type(var.type))))
        self.applied = {attribute: given[ref] for attribute, ref in cls.inputs_exported}
        self.master.open()
        self.master.begin_fixed_steps()
        self.by_name = {unit.name: unit for unit in self.master.units}
        self.step = system.scenario.experiment.step
        # the outputs, as the master samples them: the Reals packed at once, the others one by one
        kinds = [port.type for port in system.recorded]
        self.reals = np.array([i for i, kind in enumerate(kinds) if kind == "Real"], dtype=np.intp)
        self.real_names = tuple(cls.outputs_exported[i][0] for i in self.reals)
        self.others = [(cls.outputs_exported[i][0], i) for i, kind in enumerate(kinds) if kind != "Real"]
        slot = getattr(component, "_c_step", None)
        self.direct: Optional[DirectStep] = None
        if slot is not None and DirectStep.possible(self.master):
            where = {d.name: d for d in cls._layout.declarations}

            def place(attribute: str) -> Tuple[int, bool]:
                declaration = where[attribute]
                return declaration.offset, declaration.type is not float

            try:
                self.direct = DirectStep(slot, self.master, [(*place(a), port) for a, port in self.inputs],
                                         [place(a) for a, _ in cls.outputs_exported], self.messages)
            except ValueError:  # an output the C step cannot read: Python takes every step
                self.direct = None

    def _message(self, component: "SystemComponent", unit: str, status: int, text: str) -> None:
        self.messages[0] += 1
        component.log(f"{unit}: {text}", _LEVELS[status] if 0 <= status < len(_LEVELS) else "info")

    def catch_up(self) -> None:
        """The master where the C layer's steps left it (before Python touches it)."""
        if self.direct is not None:
            applied = self.direct.catch_up()
            for (attribute, _), value in zip(self.inputs, applied or ()):
                if value != self.applied[attribute]:  # set on its unit by the C step
                    self.applied[attribute] = _plain_as(self.applied[attribute], value)

    def arm(self) -> None:
        """The next steps to the C layer where it can take them."""
        if self.direct is not None:
            self.direct.arm([self.applied[attribute] for attribute, _ in self.inputs])

    def step_to(self, component: "SystemComponent", t: float, h: float) -> None:
        """The master's steps from ``t`` to ``t + h``, with the FMU's inputs as they are now."""
        master = self.master
        if self.direct is not None and self.direct.pending():
            self.direct.finish()
            return
        if abs(t - master.time) > 1e-9 * max(1.0, abs(t)):
            raise ValueError(f"doStep from t = {t!r} s, but the system is at t = {master.time!r} s")
        n = round(h / self.step)
        if n < 1 or abs(n * self.step - h) > 1e-9 * self.step:
            raise ValueError(f"doStep of {h!r} s: the system steps in whole multiples of its scenario's "
                             f"step {self.step!r} s")
        for attribute, port in self.inputs:
            value = getattr(component, attribute)
            if value != self.applied[attribute]:
                self.by_name[port.component].set_value(port, value)
                self.applied[attribute] = value
        master.advance(master.steps + n)

    def set_outputs(self, component: "SystemComponent") -> None:
        """The exported outputs from the master's recorded values."""
        values = self.master.sampler.sample()
        component.write_reals(values[self.reals].tolist(), *self.real_names)
        for attribute, i in self.others:
            setattr(component, attribute, values[i])

    def close(self) -> None:
        self.catch_up()
        self.master.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001  (freed during interpreter shutdown, or after a failure)
            pass


class _Snapshot:
    """An FMU state of the system: the master's snapshot of every unit and bus, and where it is."""

    def __init__(self, run: _Run) -> None:
        master = run.master
        self.run = run
        self.saved = master.save()
        self.where = (master.steps, master.time, master.step_end, dict(run.applied))

    def restore(self) -> None:
        master = self.run.master
        master.restore(self.saved)
        master.steps, master.time, master.step_end, applied = self.where
        self.run.applied = dict(applied)

    def __del__(self) -> None:
        try:
            self.run.master.release(self.saved)
        except Exception:  # noqa: BLE001
            pass


class SystemComponent(Component):
    """Base of a scenario exported as one FMU (``deltafmi export-fmu`` writes the subclass)."""

    co_simulation_only = True
    can_serialize_state = False
    #: the scenario in the FMU's resources/, every component given by ``fmu:``
    scenario_file: ClassVar[str] = "system.yaml"
    #: (attribute, ``component.variable``) of the exported variables, by kind
    outputs_exported: ClassVar[Tuple[Tuple[str, str], ...]] = ()
    inputs_exported: ClassVar[Tuple[Tuple[str, str], ...]] = ()
    parameters_exported: ClassVar[Tuple[Tuple[str, str], ...]] = ()

    @classmethod
    def _compiled_step(cls) -> Optional[Tuple[int, int, int]]:
        return compiled_step()

    def setup(self) -> None:
        self._run: Optional[_Run] = None
        self._start, self._stop = 0.0, None

    def setup_experiment(self, start: float, stop: Optional[float]) -> None:
        self._start, self._stop = start, stop
        self._close()

    # The master imports some of its modules when it first needs them (its units' kinds, the
    # solvers): what opens, restores and closes a run does so with the FMU's own deltafmi active
    # (own_modules), whatever deltafmi the host has, if any. A step imports nothing, and runs
    # without the swap, which would cost more than the step.

    def initialize(self, t: float) -> None:
        given = self._given()
        if self._run is None or self._run.given != given:
            self._close()
            with self.own_modules():
                self._run = _Run(self, given, self._start, self._stop)
        self._run.catch_up()
        self._run.arm()

    # The C layer takes the steps it can (direct.py): every method here that touches the master
    # takes its position back first (catch_up) and hands the steps back to C when done (arm).

    def outputs(self, t: float) -> None:
        if self._run is not None:
            self._run.catch_up()
            self._run.set_outputs(self)
            self._run.arm()

    def do_step(self, t: float, h: float) -> None:
        if self._run is None:
            raise RuntimeError("doStep before initialization")
        self._run.catch_up()
        self._run.step_to(self, t, h)
        self._run.arm()

    def internal_state(self) -> Any:
        if self._run is None:
            return None
        self._run.catch_up()
        snapshot = _Snapshot(self._run)
        self._run.arm()
        return snapshot

    def restore_internal_state(self, state: Any) -> None:
        if state is None:
            self._close()
        elif state.run is not self._run:
            raise RuntimeError("this FMU state belongs to an earlier run of the system (before a reset or a new "
                               "initialization)")
        else:
            self._run.catch_up()
            with self.own_modules():
                state.restore()
            self._run.arm()

    def _given(self) -> Dict[str, Any]:
        """The FMU's parameters and inputs as start values of the scenario's components."""
        return {ref: _plain(getattr(self, attribute))
                for attribute, ref in self.parameters_exported + self.inputs_exported}

    def _close(self) -> None:
        run, self._run = self._run, None
        if run is not None:
            with self.own_modules():
                run.close()


def _plain_as(like: Any, value: float) -> Any:
    """``value`` (a float from C) as the Python type of ``like`` (an input's bool, int or float)."""
    return bool(value) if isinstance(like, bool) else int(value) if isinstance(like, int) else value


def _plain(value: Any) -> Any:
    """A Python float, int or bool (the scenario's checks take no numpy scalars or enum members)."""
    if isinstance(value, bool) or isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    return float(value)
