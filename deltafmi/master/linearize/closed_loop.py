"""Linearization of a scenario's closed loop at a communication point, as the discrete map over
one communication step that the master takes there (:func:`linearize_scenario`).

The master runs to the instant; then each unit becomes a linear one-step map:

- a Model Exchange unit: its A, B, C, D, discretized exactly over the step with its inputs held
  (zero-order hold, as the master holds them): Phi = e^(A h), Gamma = int_0^h e^(A s) ds B;
- a Co-Simulation unit, whose state FMI keeps hidden: a minimal realization
  (:mod:`.realization`) of its Markov parameters, its outputs after steps 1, 2, ... in
  answer to a pulse on each input, each a central difference between two runs from the same
  saved FMU state (fmi2GetFMUstate / fmi2SetFMUstate). This assumes the unit time-invariant over
  those steps (exactly so at rest);
- a Co-Simulation unit that no tracked signal drives (a reference generator) is a constant.

The units are then composed as the master steps them (Gauss-Seidel in its order, or Jacobi).
The closed loop's state: the units' states, plus every connected value that a unit reads
before its producer has stepped (a value held over the step, like a sampled controller's
torque), plus requested outputs that are not functions of the states at the communication
point. Inputs are perturbations added to chosen FMU inputs; outputs are chosen FMU outputs, at
the communication points: x[k+1] = Phi x[k] + Gamma u[k], y[k] = C x[k].
"""
from __future__ import annotations

import math
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np
import scipy.linalg

from deltafmi.errors import BadInput, did_you_mean

from ..scenario.modelinfo import UnknownVariable
from ..stepping.jacobians import FD_STEP, REAL_TYPES, FmuJacobian, Key, RealValues, real_nominals, scalar_key
from .linear_model import LinearModel
from .realization import era

__all__ = ["expand_references", "linearize_scenario"]

Signal = Tuple[str, Key]  # (component, scalar key: value reference and element)


@dataclass
class _Block:
    """One unit as a linear one-step map: s' = F s + G w, y(after the step) = C s + D w."""

    name: str
    inputs: List[Key]  # the tracked inputs (w)
    outputs: List[Key]  # the tracked outputs (y)
    F: np.ndarray
    G: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_names: List[str]
    x0: np.ndarray
    #: Model Exchange only: outputs at a communication point, y = Cc s + Dc w
    Cc: Optional[np.ndarray] = None
    Dc: Optional[np.ndarray] = None
    order: List[int] = field(default_factory=list)


def linearize_scenario(path: Path, *, at: Optional[float] = None, inputs: Sequence[str] = (),
                       outputs: Sequence[str] = (), markov_steps: int = 24,
                       rank_tolerance: float = 1e-7, system: Any = None) -> LinearModel:
    """The closed loop of the scenario at ``path`` as a discrete-time map over one communication
    step at time ``at`` (default: the start); see the module docstring.

    Args:
        inputs: inputs of components ("controller.r[1]", "controller.r") that the model's inputs
            perturb (added to whatever drives them).
        outputs: outputs of components ("plant.z") that the model's outputs are.
        markov_steps: steps of each Co-Simulation unit's pulse responses (even; the realization
            finds at most markov_steps / 2 states per input and output).
        rank_tolerance: relative singular value below which a realization stops (see :func:`.realization.era`).
        system: the scenario already resolved (:func:`~deltafmi.master.scenario.resolve.resolve_system`), if it is.
    """
    from ..stepping.master import Master
    from ..scenario.resolve import resolve_system
    from ..scenario.spec import load_scenario

    system = system or resolve_system(load_scenario(str(path)))
    from ..scenario.live_components import refuse_live
    refuse_live(system, "linearize")
    experiment = system.scenario.experiment
    start, h = experiment.start, experiment.step
    at = start if at is None else float(at)
    if not math.isfinite(at):
        raise BadInput(f"--at {at:g}: a linearization instant must be a finite number")
    k = round((at - start) / h)
    if k < 0 or abs(start + k * h - at) > 1e-9 * max(h, abs(at)):
        raise BadInput(f"--at {at:g}: a linearization instant must be a communication point at or after the "
                       f"start ({start:g} s) on the grid of the step {h:g} s")
    multi = [c.name for c in system.components if c.spec.step_multiple != 1]
    if multi:
        raise BadInput(f"linearize needs every component on the communication step; step_multiple is set for "
                       f"{', '.join(multi)}")
    by_name = {c.name: c for c in system.components}
    perturbed = [_port(by_name, ref, "input") for ref in inputs]
    observed = [_port(by_name, ref, "output") for ref in outputs]
    steps = markov_steps + (markov_steps % 2)
    workdir = tempfile.mkdtemp(prefix="deltafmi-linearize-")
    master = Master(system, result=Path(workdir) / "run.csv",
                    stop=max(experiment.stop, at + (steps + 3) * h))
    try:
        master.open()
        ordered = master.ordered_units()
        for step in range(k):
            master.step_all(ordered, start + step * h, h)
        units = {u.name: u for u in master.units}
        links = [l for l in system.links if l.source.type == "Real"]
        single = [l.source for l in links if l.source.fmi_type not in ("", "Float64")]
        if single:
            raise BadInput(f"linearize follows Float64 signals; '{single[0].ref}' is {single[0].fmi_type}")
        tracked_in, tracked_out = _tracked(system, links, perturbed, observed)
        blocks: Dict[str, _Block] = {}
        for unit in master.units:
            if unit.name not in tracked_in:
                continue  # a Co-Simulation unit nothing drives: its outputs are constants here
            w, y = tracked_in[unit.name], tracked_out.get(unit.name, [])
            if unit.interface == "ME":
                blocks[unit.name] = _model_exchange_block(unit, w, y, h)
            else:
                blocks[unit.name] = _co_simulation_block(unit, w, y, at, h, steps, rank_tolerance)
        order = [u.name for u in ordered]
        return _compose(system, master.algorithm, order, blocks, links, perturbed, observed, units, at, h, path)
    finally:
        master.close()
        shutil.rmtree(workdir, ignore_errors=True)


def _tracked(system: Any, links: list, perturbed: list, observed: list) -> Tuple[dict, dict]:
    """Which inputs and outputs of which units the linear model follows: the units that anything
    dynamic drives (every Model Exchange unit, and Co-Simulation units fed by a tracked unit or
    by a perturbed input), their inputs from tracked units, and the outputs feeding those."""
    names = [c.name for c in system.components]
    dynamic = {c.name for c in system.components if c.interface == "ME"} | {p.component for p in perturbed}
    changed = True
    while changed:
        changed = False
        for link in links:
            if link.source.component in dynamic and link.target.component not in dynamic:
                dynamic.add(link.target.component)
                changed = True
    tracked_in: Dict[str, List[Key]] = {n: [] for n in names if n in dynamic}
    tracked_out: Dict[str, List[Key]] = {}
    for link in links:
        if link.source.component in dynamic and link.target.component in dynamic:
            _add(tracked_in[link.target.component], _key(link.target))
            _add(tracked_out.setdefault(link.source.component, []), _key(link.source))
    for port in perturbed:
        _add(tracked_in[port.component], _key(port))
    for port in observed:
        if port.component in dynamic:
            _add(tracked_out.setdefault(port.component, []), _key(port))
    return tracked_in, tracked_out


def _add(values: list, value: Any) -> None:
    if value not in values:
        values.append(value)


def _key(port: Any) -> Key:
    return port.vr, port.index


def _model_exchange_block(unit: Any, w: List[Key], y: List[Key], h: float) -> _Block:
    """A, B, C, D at the unit's current point, discretized over h with held inputs."""
    jac = FmuJacobian(unit.fmu, unit.info)
    nx = jac.nx
    J = jac.block(jac.derivatives + y, jac.states + w)
    A, B, Cc, Dc = J[:nx, :nx], J[:nx, nx:], J[nx:, :nx], J[nx:, nx:]
    n, m = nx, len(w)
    augmented = np.zeros((n + m, n + m))
    augmented[:n, :n], augmented[:n, n:] = A * h, B * h
    E = scipy.linalg.expm(augmented)
    Phi, Gamma = E[:n, :n], E[:n, n:]
    names = [f"{unit.name}.{name}" for name in jac.state_names]
    return _Block(unit.name, w, y, Phi, Gamma, Cc @ Phi, Cc @ Gamma + Dc, names, jac.get_states(), Cc, Dc)


def _co_simulation_block(unit: Any, w: List[Key], y: List[Key], at: float, h: float, steps: int,
                         rank_tolerance: float) -> _Block:
    """A minimal realization of the unit's step map from its pulse responses (module docstring)."""
    if not y:  # nothing it outputs is followed: its state plays no part
        return _Block(unit.name, w, y, np.zeros((0, 0)), np.zeros((0, len(w))), np.zeros((0, 0)),
                      np.zeros((0, len(w))), [], np.zeros(0))
    if not unit.can_save_state:
        raise BadInput(f"component '{unit.name}' cannot save and restore its state (canGetAndSetFMUstate is "
                       "false): linearize needs that to take its pulse responses")
    values = RealValues(unit.fmu, unit.info)
    nominal = real_nominals(unit.info)
    w0 = values.get(w)
    saved = unit.save_state()
    markov = np.zeros((steps + 1, len(y), len(w)))
    try:
        for j, key in enumerate(w):
            delta = FD_STEP * max(abs(w0[j]), nominal.get(key, 1.0))
            runs = []
            for sign in (1.0, -1.0):
                unit.restore_state(saved)
                pulse = w0.copy()
                pulse[j] += sign * delta
                values.set(w, pulse)
                response = []
                for step in range(steps + 1):
                    unit.do_step(at + step * h, h)
                    response.append(values.get(y))
                    if step == 0:
                        values.set(w, w0)
                runs.append(np.array(response, dtype=float).reshape(steps + 1, len(y)))
            markov[:, :, j] = (runs[0] - runs[1]) / (2.0 * delta)
        unit.restore_state(saved)
    finally:
        unit.free_state(saved)
    scaled, rows, columns = _scaled(markov)
    realization = era(list(scaled), rank_tolerance)
    F = realization.F
    G = realization.G * columns[None, :]
    C = rows[:, None] * realization.C
    names = [f"{unit.name}.xi[{i + 1}]" for i in range(F.shape[0])]
    return _Block(unit.name, w, y, F, G, C, markov[0], names, np.zeros(F.shape[0]))


def _scaled(markov: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(h~, r, c) with h = diag(r) h~ diag(c) and every output row, then every input column, of
    h~ of unit size: a relative singular-value threshold then means the same for torques and
    angles."""
    rows = np.max(np.abs(markov), axis=(0, 2))
    rows[rows == 0.0] = 1.0
    scaled = markov / rows[None, :, None]
    columns = np.max(np.abs(scaled), axis=(0, 1))
    columns[columns == 0.0] = 1.0
    return scaled / columns[None, None, :], rows, columns


def _compose(system: Any, algorithm: str, order: List[str], blocks: Dict[str, _Block], links: list,
             perturbed: list, observed: list, units: dict, at: float, h: float, path: Path) -> LinearModel:
    """Compose the blocks into the closed loop's one-step map, as the master steps them."""
    position = {name: i for i, name in enumerate(order)}
    feeds: Dict[Signal, List[Tuple[Signal, float]]] = {}  # tracked input -> (source signal, factor)
    for link in links:
        if link.target.component in blocks and link.source.component in blocks:
            feeds.setdefault((link.target.component, _key(link.target)), []).append(
                ((link.source.component, _key(link.source)), link.factor))
    # values read before their producer steps are held from the previous step: they are states
    held: List[Signal] = []
    for target, sources in feeds.items():
        for source, _ in sources:
            if algorithm != "gauss-seidel" or position[target[0]] <= position[source[0]]:
                _add(held, source)
    for port in observed:
        block = blocks.get(port.component)
        signal = (port.component, _key(port))
        if block is None or signal in held:
            continue
        info = units[port.component].info
        if block.Cc is None or any(scalar_key(info, n) in block.inputs
                                   for n in _feedthrough(units[port.component], port.name)):
            _add(held, signal)  # not a function of the states at the communication point
    names = [b for b in (c.name for c in system.components) if b in blocks]
    offsets, n = {}, 0
    for name in names:
        offsets[name] = n
        n += blocks[name].F.shape[0]
    slot = {signal: n + i for i, signal in enumerate(held)}
    nX, m = n + len(held), len(perturbed)
    bus: Dict[Signal, Tuple[np.ndarray, np.ndarray]] = {}
    for signal, index in slot.items():
        bus[signal] = (np.eye(nX)[index], np.zeros(m))
    perturbation = {(p.component, _key(p)): i for i, p in enumerate(perturbed)}

    def inputs_of(block: _Block) -> Tuple[np.ndarray, np.ndarray]:
        Pw, Qw = np.zeros((len(block.inputs), nX)), np.zeros((len(block.inputs), m))
        for i, key in enumerate(block.inputs):
            for source, factor in feeds.get((block.name, key), []):
                P, Q = bus[source]
                Pw[i] += factor * P
                Qw[i] += factor * Q
            if (block.name, key) in perturbation:
                Qw[i, perturbation[(block.name, key)]] += 1.0
        return Pw, Qw

    new_states: Dict[str, Tuple[np.ndarray, np.ndarray]] = {}

    def step(block: _Block, Pw: np.ndarray, Qw: np.ndarray) -> None:
        S = np.eye(nX)[offsets[block.name]:offsets[block.name] + block.F.shape[0]]
        new_states[block.name] = (block.F @ S + block.G @ Pw, block.G @ Qw)
        Py, Qy = block.C @ S + block.D @ Pw, block.D @ Qw
        for i, key in enumerate(block.outputs):
            bus[(block.name, key)] = (Py[i], Qy[i])

    stepping = [name for name in order if name in blocks]
    if algorithm == "gauss-seidel":
        for name in stepping:
            step(blocks[name], *inputs_of(blocks[name]))
    else:
        gathered = {name: inputs_of(blocks[name]) for name in stepping}
        for name in stepping:
            step(blocks[name], *gathered[name])
    Phi, Gamma = np.zeros((nX, nX)), np.zeros((nX, m))
    for name in names:
        rows = slice(offsets[name], offsets[name] + blocks[name].F.shape[0])
        Phi[rows], Gamma[rows] = new_states[name]
    for signal, index in slot.items():
        Phi[index], Gamma[index] = bus[signal]
    C = np.zeros((len(observed), nX))
    for i, port in enumerate(observed):
        signal, block = (port.component, _key(port)), blocks.get(port.component)
        if signal in slot:
            C[i, slot[signal]] = 1.0
        elif block is not None and block.Cc is not None:
            row = block.outputs.index(_key(port))
            C[i, offsets[port.component]:offsets[port.component] + block.F.shape[0]] = block.Cc[row]
    state_names = [s for name in names for s in blocks[name].state_names]
    state_names += [f"{c}.{_name(units[c], key)} (held)" for c, key in held]
    x0 = np.concatenate([blocks[name].x0 for name in names] +
                        [np.array([_value(units[c], key) for c, key in held])])
    notes = [f"{name}: {blocks[name].F.shape[0]} states realized from its pulse responses"
             for name in names if blocks[name].Cc is None]
    notes += [f"{name}: discretized exactly over the step (inputs held)" for name in names if blocks[name].Cc is not None]
    return LinearModel(Phi, Gamma, C, np.zeros((len(observed), m)), state_names, [p.ref for p in perturbed],
                       [p.ref for p in observed], h, at, x0,
                       np.array([_value(units[p.component], _key(p)) for p in perturbed]),
                       np.array([_value(units[p.component], _key(p)) for p in observed]), str(path), notes)


def _feedthrough(unit: Any, output: str) -> set:
    return unit.info.feedthrough.get(output, set())


def _name(unit: Any, key: Key) -> str:
    return next(name for name in unit.info.variables if scalar_key(unit.info, name) == key)


def _value(unit: Any, key: Key) -> float:
    return float(RealValues(unit.fmu, unit.info).get([key])[0])


def _port(components: Mapping[str, Any], reference: str, causality: str) -> Any:
    """The scenario port named ``reference`` ("comp.var"); arrays are not expanded here."""
    from ..scenario.system import Port
    comp_name, component, names = _expanded(components, reference)
    if len(names) != 1:
        raise BadInput(f"'{reference}' names {len(names)} variables; name one (arrays are expanded by the command)")
    info = component.info
    variable = info.variables[names[0]]
    if variable.causality != causality or variable.type not in REAL_TYPES:
        raise BadInput(f"'{reference}' is a {variable.type} {variable.causality}; linearize takes Real {causality}s here")
    return Port(comp_name, names[0], variable.valueReference, "Real", info.unit(names[0]),
                fmi_type=variable.type if info.fmi3 else "", index=info.positions.get(names[0], 0))


def expand_references(components: Mapping[str, Any], references: Sequence[str]) -> List[str]:
    """``comp.var`` references with arrays expanded (``plant.z`` -> ``plant.z[1]`` ...)."""
    out = []
    for reference in references:
        comp_name, _, names = _expanded(components, reference)
        out += [f"{comp_name}.{n}" for n in names]
    return out


def _expanded(components: Mapping[str, Any], reference: str) -> Tuple[str, Any, List[str]]:
    """(component name, component, its variable names) of ``comp.var`` (arrays expanded);
    :class:`BadInput` naming what is not there."""
    comp_name, _, var = reference.partition(".")
    component = components.get(comp_name)
    if component is None or not var:
        raise BadInput(f"'{reference}': no component '{comp_name}' in the scenario"
                       f"{did_you_mean(comp_name, list(components))}")
    try:
        return comp_name, component, component.info.expand(var)
    except UnknownVariable as exc:
        raise BadInput(f"'{reference}': component '{comp_name}' has no variable '{exc.reference}'"
                       f"{did_you_mean(exc.reference, exc.names)}") from None
