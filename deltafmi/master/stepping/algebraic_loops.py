"""Algebraic loops solved by the master, at initialization and at every communication step.

A loop (:class:`~deltafmi.master.scenario.resolve.AlgebraicLoop`) is a set of components whose connections
and direct feedthrough close a cycle. Its components are evaluated in the loop's order, each
taking the fresh outputs of those before it; the outputs read by a component at or before their
own in that order are the *tear variables* ``tau``. Evaluating the loop with guessed values
``tau`` gives ``G(tau)``, the values those outputs then take; the loop is solved when
``G(tau) = tau``, to ``|G_i - tau_i| <= tolerance * scale_i`` for every tear, where ``scale_i`` is
``max(|tau_i|, |G_i(tau)|, nominal_i)`` at the solve's first guess (the last solution, or the
start values at initialization). The scale stays fixed during a solve: measured against the
current guess instead, a loop without solution would "converge" by running off to huge values.

* At initialization (:class:`InitialLoop`) an evaluation sets the loop's inputs and reads its
  outputs in initialization mode: outputs depend on inputs directly, nothing is stepped.
* At every communication step (:class:`LoopBlock`) an evaluation *is* the loop's step: every
  component restores the FMU state saved at the step's start (fmi2SetFMUstate), takes its
  inputs (the tears' guesses, the fresh outputs of the components before it, and the rest as
  the master's algorithm gives them) and steps. The accepted step is the evaluation at the
  solution, so its states and outputs are consistent with the inputs held over it.

The solver (:class:`TearSolver`) tries fixed-point iterations ``tau <- G(tau)`` first, and goes
on with Newton's method on ``G(tau) - tau`` when an iteration does not halve the residual (from
then on that loop goes to Newton at once: with a Jacobian at hand Newton needs about two
evaluations per step, which fixed-point iterations match only on very weakly coupled loops):
MINPACK's hybrid Powell method (scipy.optimize.root, ``hybr``: Newton steps in a trust region,
Broyden updates of the Jacobian between its evaluations). The Jacobian comes from
fmi2GetDirectionalDerivative chained through the loop, or from forward differences of loop
evaluations (one per tear; the last one is reused at the next step while it serves). By default
(``jacobian: auto``) the directional derivatives are used where they are the loop's exact
Jacobian and every FMU in it provides them: at initialization, and at steps when no member has
states. Through a step a held input also moves the states (``dx(t+h)/du``), which no partial
derivative at one instant contains; finite differences of whole evaluations do. A difference
step is ``sqrt(accuracy)`` times the tear's scale, where the accuracy is the relative tolerance
of the members' solvers when one of them integrates states (an evaluation is no more accurate
than its solver), machine epsilon otherwise. A loop that is not solved within its budget fails
the run with its connections and the residual named.
"""
from __future__ import annotations

import math
from typing import Any, Callable, Dict, List, Optional, Protocol, Sequence, Tuple

import numpy as np

from deltafmi.errors import DeltaFmiError

from ..scenario.records import record
from ..scenario.system import AlgebraicLoop, Link, Port
from ..scenario.spec import Loops
from .unit_base import Unit

__all__ = ["InitialLoops", "LoopBlock", "LoopStatistics", "Stepper"]

#: relative accuracy of a loop evaluation that integrates no states
_EPSILON = float(np.finfo(float).eps)
#: relative tolerance assumed for a member with states whose solver tolerance nothing gives
_DEFAULT_RTOL = 1e-6
#: a fixed-point iteration that does not shrink the residual by this factor hands over to Newton
_CONTRACTION = 0.5


class LoopFailure(DeltaFmiError, RuntimeError):
    """An algebraic loop was not solved; the message names its connections and the residual."""


class Stepper(Protocol):
    """What the master steps: a :class:`~deltafmi.master.stepping.unit_base.Unit` or a :class:`LoopBlock`."""

    name: str
    step_multiple: int

    def pull(self) -> None: ...

    def do_step(self, time: float, step: float) -> None: ...

    def fetch(self) -> None: ...


class EventHolder(Protocol):
    """The master's event rows held back while a loop's step may still be redone."""

    def hold_events(self) -> Any: ...

    def rewind_events(self, mark: Any) -> None: ...

    def release_events(self, mark: Any) -> None: ...


@record(frozen=False)
class LoopStatistics:
    """How much solving the loops cost: solves, loop evaluations, the most in one solve."""

    solves: int = 0
    evaluations: int = 0
    most: int = 0

    def __str__(self) -> str:
        return (f"{self.solves} solves, {self.evaluations} evaluations "
                f"({self.evaluations / max(self.solves, 1):.2g} per solve, at most {self.most})")

    def add(self, other: "LoopStatistics") -> None:
        """Add ``other``'s figures to these."""
        self.solves += other.solves
        self.evaluations += other.evaluations
        self.most = max(self.most, other.most)


class _Converged(Exception):
    """Raised from inside scipy's solver at the first evaluation within tolerance."""


class _OutOfBudget(Exception):
    """Raised from inside scipy's solver when the evaluations allowed are spent."""


class TearSolver:
    """Solves ``G(tau) = tau`` for one loop: fixed-point iterations, then Newton (scipy ``hybr``).

    ``evaluate(tau)`` must leave the loop in the state of the guess ``tau`` and return
    ``G(tau)``; the solver's last call to it is always at the solution it returns, so the loop
    is left there.
    """

    def __init__(self, settings: Loops, nominal: Sequence[float], name: str, tear_names: Sequence[str],
                 accuracy: float = _EPSILON) -> None:
        """``accuracy``: relative accuracy of an evaluation (sets the finite-difference step)."""
        self.settings = settings
        self.fd_step = math.sqrt(max(accuracy, _EPSILON))
        self.nominal = np.maximum(np.abs(np.asarray(nominal, dtype=float)), np.finfo(float).tiny)
        self.name = name
        self.tear_names = list(tear_names)
        self.statistics = LoopStatistics()
        #: fixed-point iterations handed over to Newton once: go to Newton at once from then on
        self._newton_at_once = False
        #: d(G - tau)/d tau from the last finite differences, reused while Newton makes progress with it
        self._cached_jacobian: Optional[np.ndarray] = None

    def solve(self, evaluate: Callable[[np.ndarray], np.ndarray], guess: np.ndarray,
              jacobian: Optional[Callable[[], np.ndarray]] = None) -> np.ndarray:
        """The tear values that solve the loop, starting from ``guess``; raises :class:`LoopFailure`.

        ``jacobian()``: dG/dtau at the last evaluation (directional derivatives); None: finite
        differences.
        """
        attempt = _Attempt(evaluate, self.nominal)
        settings = self.settings
        try:
            guess = np.array(guess, dtype=float)
            self._fixed_point(attempt, guess)
            if settings.method == "newton":
                self._newton(attempt, guess, jacobian)
                if jacobian is not None:  # the chained partial derivatives did not get there
                    self._newton(attempt, guess, None)
        except _Converged:
            solution = attempt.tau.copy()
            attempt.move_to(solution)  # usually there already: the last evaluation
            return solution
        finally:
            self.statistics.solves += 1
            self.statistics.evaluations += attempt.evaluations
            self.statistics.most = max(self.statistics.most, attempt.evaluations)
        raise LoopFailure(self._failure(attempt))

    # --- the two phases -----------------------------------------------------------------------
    def _fixed_point(self, attempt: "_Attempt", tau: np.ndarray) -> None:
        settings = self.settings
        limit = settings.max_iterations if settings.method == "fixed-point" else settings.fixed_point_iterations
        if self._newton_at_once:
            limit = 0
        previous = math.inf
        for _ in range(limit):
            error = attempt.error_at(tau)
            if error <= settings.tolerance:
                raise _Converged
            if settings.method == "newton" and error > _CONTRACTION * previous:
                self._newton_at_once = True
                return
            previous = error
            tau = attempt.g.copy()
        attempt.fixed_point = attempt.evaluations
        if limit > 0 and settings.method == "newton":
            self._newton_at_once = True

    def _newton(self, attempt: "_Attempt", guess: np.ndarray, jacobian: Optional[Callable[[], np.ndarray]]) -> None:
        from scipy import optimize  # here: a run whose system has no loop never pays for importing scipy

        settings = self.settings
        start = attempt.best_tau.copy() if len(attempt.best_tau) else guess
        attempt.fixed_point = min(attempt.fixed_point, attempt.evaluations)
        if attempt.error_at(start) <= settings.tolerance:
            raise _Converged
        scale = attempt.scale
        cache_used = [False]

        def residual(z: np.ndarray) -> np.ndarray:
            if attempt.evaluations - attempt.fixed_point >= settings.max_iterations and not attempt.known(z * scale):
                raise _OutOfBudget
            if attempt.error_at(z * scale) <= settings.tolerance:
                raise _Converged
            return attempt.residual / scale

        last: List[Any] = [None, None]  # scipy asks twice at the start (a shape check): answer once

        def derivative(z: np.ndarray) -> np.ndarray:
            if last[0] is not None and np.array_equal(z, last[0]):
                return last[1]
            if jacobian is None and self._cached_jacobian is not None and not cache_used[0]:
                cache_used[0] = True  # the last one, once per solve: hybr asks again when it does not serve
                unscaled = self._cached_jacobian
            elif jacobian is not None:
                attempt.move_to(z * scale)
                unscaled = jacobian() - np.eye(len(z))
            else:
                cache_used[0] = True
                steps = self.fd_step * np.maximum(np.abs(z), 1.0)
                unscaled = optimize.approx_fprime(z, residual, steps) * scale[:, None] / scale[None, :]
                self._cached_jacobian = unscaled
            last[0], last[1] = z.copy(), unscaled * scale[None, :] / scale[:, None]
            return last[1]

        try:
            result = optimize.root(residual, start / scale, jac=derivative, method="hybr",
                                   options={"maxfev": 100 * (settings.max_iterations + len(start))})
        except _OutOfBudget:
            attempt.note = f"{settings.max_iterations} Newton evaluations spent"
            return
        attempt.note = "scipy hybr: " + " ".join(str(result.message).split())
        end = result.x * scale
        budget_left = attempt.evaluations - attempt.fixed_point < settings.max_iterations
        if (budget_left or attempt.known(end)) and attempt.error_at(end) <= settings.tolerance:
            raise _Converged
        self._cached_jacobian = None

    def _failure(self, attempt: "_Attempt") -> str:
        if not len(attempt.best_tau):  # every evaluation gave NaN
            return (f"{self.name} not solved: the loop's outputs are not numbers (NaN) after "
                    f"{attempt.evaluations} evaluations")
        i = attempt.worst
        tau, r = attempt.best_tau, attempt.best_residual
        newton = attempt.evaluations - attempt.fixed_point
        phases = (f"{attempt.evaluations} fixed-point iterations" if self.settings.method == "fixed-point" else
                  f"{attempt.fixed_point} fixed-point and {newton} Newton evaluations")
        note = f"; {attempt.note}" if attempt.note else ""
        return (f"{self.name} not solved: residual {abs(r[i]):.3g} at {self.tear_names[i]} "
                f"(guess {tau[i]:.9g}, the loop gives {tau[i] + r[i]:.9g}; relative to its scale "
                f"{attempt.scale[i]:.3g}: {attempt.best_error:.3g}, tolerance {self.settings.tolerance:g}) "
                f"after {phases}{note}")


class _Attempt:
    """One solve: the points evaluated (remembered, so none is evaluated twice), where the loop
    is now, counts, and the best point seen."""

    def __init__(self, evaluate: Callable[[np.ndarray], np.ndarray], nominal: np.ndarray) -> None:
        self._evaluate, self.nominal = evaluate, nominal
        self._seen: Dict[bytes, np.ndarray] = {}
        self._loop_at: Optional[bytes] = None
        self.evaluations = 0
        self.fixed_point = math.inf  # evaluations spent in the fixed-point phase
        self.tau = self.g = self.residual = np.zeros(0)
        self.scale = np.zeros(0)  # set at the first evaluation
        self.best_error = math.inf
        self.best_tau = self.best_residual = np.zeros(0)
        self.error = math.inf
        self.worst = 0
        self.note = ""

    def known(self, tau: np.ndarray) -> bool:
        """Whether ``tau`` was evaluated in this solve."""
        return np.asarray(tau, dtype=float).tobytes() in self._seen

    def error_at(self, tau: np.ndarray) -> float:
        """Scaled residual of ``tau`` (also in :attr:`g`, :attr:`residual`), evaluating the loop
        there unless it was evaluated there before."""
        self.tau = np.array(tau, dtype=float)
        key = self.tau.tobytes()
        if key not in self._seen:
            self._seen[key] = np.asarray(self._evaluate(self.tau), dtype=float)
            self._loop_at = key
            self.evaluations += 1
        self.g = self._seen[key]
        self.residual = self.g - self.tau
        if not len(self.scale):
            self.scale = np.maximum(np.maximum(np.abs(self.tau), np.abs(self.g)), self.nominal)
            self.scale[~np.isfinite(self.scale)] = 1.0
        scaled = np.abs(self.residual) / self.scale
        self.error = float(np.max(scaled)) if len(scaled) else 0.0
        if self.error < self.best_error:  # NaN never becomes the best
            self.best_error, self.best_tau, self.best_residual = self.error, self.tau, self.residual
            self.worst = int(np.argmax(scaled))
        return self.error

    def move_to(self, tau: np.ndarray) -> None:
        """Put the loop at ``tau`` (evaluating it again if it is elsewhere now)."""
        tau = np.array(tau, dtype=float)
        if tau.tobytes() != self._loop_at:
            self._seen.pop(tau.tobytes(), None)
            self.error_at(tau)


class _Chain:
    """dG/dtau from fmi2GetDirectionalDerivative, chained through a loop's components in order.

    Every component's outputs in the loop react to its inputs in the loop through its partial
    derivatives (at its current time, states and inputs); an input reads either a tear (its
    source steps at or after it) or the fresh output of a component before it.
    """

    def __init__(self, loop: AlgebraicLoop, units: Sequence[Unit]) -> None:
        self.tears = {port.ref: i for i, port in enumerate(loop.tears)}
        # only Real variables have partial derivatives; the others carry no sensitivity
        self.plans = [(unit, [(l, torn) for l, torn in inputs if l.target.type == "Real"],
                       [port for port in outputs if port.type == "Real"])
                      for unit, inputs, outputs in _members(loop, units)]

    def jacobian(self) -> np.ndarray:
        """dG/dtau at the loop's current point, one row per tear."""
        n = len(self.tears)
        fresh: Dict[str, np.ndarray] = {}
        for unit, inputs, outputs in self.plans:
            if not inputs or not outputs:
                for port in outputs:
                    fresh[port.ref] = np.zeros(n)
                continue
            seeds = np.zeros((len(inputs), n))
            for k, (link, torn) in enumerate(inputs):
                if torn:
                    seeds[k, self.tears[link.source.ref]] = link.factor
                elif link.source.ref in fresh:
                    seeds[k] = link.factor * fresh[link.source.ref]
            knowns = [link.target.vr for link, _ in inputs]
            unknowns = [port.vr for port in outputs]
            columns = np.zeros((len(outputs), n))
            for j in range(n):
                if np.any(seeds[:, j]):
                    columns[:, j] = unit.call(unit.fmu.getDirectionalDerivative, unknowns, knowns, list(seeds[:, j]))
            for k, port in enumerate(outputs):
                fresh[port.ref] = columns[k]
        return np.array([fresh[ref] for ref in self.tears])


def _members(loop: AlgebraicLoop, units: Sequence[Unit]) -> List[Tuple[Unit, List[Tuple[Link, bool]], List[Port]]]:
    """Per member of ``loop`` in its order (``units`` in that order): the loop's connections into
    it, each with whether it reads a tear (its source is at or after the member), and the
    member's outputs that the loop reads."""
    position = {name: i for i, name in enumerate(loop.members)}
    return [(unit,
             [(l, position[l.source.component] >= position[unit.name])
              for l in loop.links if l.target.component == unit.name],
             list({l.source.ref: l.source for l in loop.links if l.source.component == unit.name}.values()))
            for unit in units]


def _provides_directional_derivatives(units: Sequence[Unit]) -> bool:
    for unit in units:
        md = unit.info.md
        element = md.modelExchange if unit.interface == "ME" else md.coSimulation
        if not element.providesDirectionalDerivative:
            return False
    return True


def _accuracy(units: Sequence[Unit]) -> float:
    """Relative accuracy of a step of ``units``: the loosest solver tolerance among those with states."""
    accuracy = _EPSILON
    for unit in units:
        md = unit.info.md
        if md.numberOfContinuousStates:
            default = md.defaultExperiment.tolerance if md.defaultExperiment is not None else None
            rtol = unit.component.spec.solver.get("rtol") or default or _DEFAULT_RTOL
            accuracy = max(accuracy, float(rtol))
    return accuracy


def _tear_solver(loop: AlgebraicLoop, units: Sequence[Unit], settings: Loops) -> Tuple[TearSolver, Optional["_Chain"]]:
    """The solver of ``loop`` (``units``: its members in order) and, when its Jacobian is to come
    from directional derivatives, their chain."""
    by_name = {u.name: u for u in units}
    nominal = []
    for port in loop.tears:
        variable = by_name[port.component].info.variables[port.name]
        nominal.append(float(variable.nominal) if getattr(variable, "nominal", None) else 1.0)
    solver = TearSolver(settings, nominal, str(loop) + (" at initialization" if loop.initial else ""),
                        [port.ref for port in loop.tears], 0.0 if loop.initial else _accuracy(units))
    exact = loop.initial or not any(unit.info.md.numberOfContinuousStates for unit in units)
    use_chain = settings.jacobian == "directional-derivative" or (
        settings.jacobian == "auto" and exact and _provides_directional_derivatives(units))
    return solver, (_Chain(loop, units) if use_chain else None)


class LoopBlock:
    """The units of one algebraic loop, stepped as one: the master steps it like a unit.

    :meth:`pull` keeps the buses as they are when the master would set the loop's inputs (so
    each evaluation starts from the same values, whatever the algorithm); :meth:`do_step`
    saves every unit's FMU state and solves the loop, each evaluation a redo of the step.
    """

    def __init__(self, loop: AlgebraicLoop, units: Sequence[Unit], buses: Dict[str, np.ndarray],
                 tear_slots: Sequence[int], settings: Loops, events: EventHolder) -> None:
        by_name = {u.name: u for u in units}
        self.loop = loop
        self.units = [by_name[name] for name in loop.members]
        self.name = ", ".join(loop.members)
        self.step_multiple = self.units[0].step_multiple
        self.buses = buses
        self._kept = {kind: bus.copy() for kind, bus in buses.items()}
        self.tear_slots = np.asarray(tear_slots, dtype=np.intp)
        #: the last solution: the next step's first guess
        self._guess: Optional[np.ndarray] = None
        self.events = events
        self.solver, self._chain = _tear_solver(loop, self.units, settings)
        for unit in self.units:
            unit.no_prior_state = 0  # every step may be redone

    @property
    def statistics(self) -> LoopStatistics:
        """Solves and evaluations so far."""
        return self.solver.statistics

    def pull(self) -> None:
        """Keep the buses: every evaluation of the step starts from these values."""
        for kind, bus in self.buses.items():
            np.copyto(self._kept[kind], bus)

    def do_step(self, time: float, step: float) -> None:
        """Solve the loop over the step from ``time``; its units end at the accepted evaluation."""
        units, buses, kept, slots = self.units, self.buses, self._kept, self.tear_slots
        real = buses["Real"]
        states = [unit.save_state() for unit in units]
        mark = self.events.hold_events()

        def evaluate(tau: np.ndarray) -> np.ndarray:
            for unit, state in zip(units, states):
                unit.restore_state(state)
            for kind, bus in buses.items():
                np.copyto(bus, kept[kind])
            self.events.rewind_events(mark)
            real[slots] = tau
            for unit in units:
                unit.pull()
                unit.do_step(time, step)
                unit.fetch()
            return real[slots].copy()

        guess = kept["Real"][slots] if self._guess is None else self._guess
        try:
            self._guess = self.solver.solve(evaluate, guess, self._chain.jacobian if self._chain else None)
        except LoopFailure:
            self.events.rewind_events(mark)
            raise
        finally:
            for unit, state in zip(units, states):
                unit.free_state(state)
            self.events.release_events(mark)

    def fetch(self) -> None:
        """Nothing to do: the accepted evaluation fetched every unit's outputs."""


class InitialLoop:
    """One loop of the initialization, solved in initialization mode by setting inputs and
    reading outputs (no state to save: nothing is stepped)."""

    def __init__(self, loop: AlgebraicLoop, by_name: Dict[str, Unit], settings: Loops) -> None:
        self.loop = loop
        self.units = [by_name[name] for name in loop.members]
        self._plan = _members(loop, self.units)
        self.solver, self._chain = _tear_solver(loop, self.units, settings)

    def solve(self) -> None:
        """Set every input of the loop consistently with its outputs."""
        tears = {port.ref: i for i, port in enumerate(self.loop.tears)}
        by_name = {u.name: u for u in self.units}
        fresh: Dict[str, Any] = {}

        def evaluate(tau: np.ndarray) -> np.ndarray:
            for unit, inputs, outputs in self._plan:
                for link, torn in inputs:
                    value = tau[tears[link.source.ref]] if torn else fresh[link.source.ref]
                    if link.target.type == "Real":
                        value = link.factor * value + link.offset
                    unit.set_value(link.target, value)
                for port in outputs:
                    fresh[port.ref] = unit.get_value(port)
            return np.array([fresh[port.ref] for port in self.loop.tears], dtype=float)

        guess = np.array([by_name[p.component].get_value(p) for p in self.loop.tears], dtype=float)
        self.solver.solve(evaluate, guess, self._chain.jacobian if self._chain else None)


class InitialLoops:
    """The initialization's loops, each solved when the master reaches its first connection."""

    def __init__(self, loops: Sequence[AlgebraicLoop], by_name: Dict[str, Unit], settings: Loops) -> None:
        self.loops = [InitialLoop(loop, by_name, settings) for loop in loops]
        self._of = {link: solver for solver in self.loops for link in solver.loop.links}
        self._solved: set = set()

    def solve_with(self, link: Link) -> bool:
        """True when ``link`` belongs to a loop (solved now if it was not yet): skip it."""
        solver = self._of.get(link)
        if solver is None:
            return False
        if id(solver) not in self._solved:
            self._solved.add(id(solver))
            solver.solve()
        return True

    @property
    def statistics(self) -> LoopStatistics:
        """Solves and evaluations of every initialization loop."""
        total = LoopStatistics()
        for solver in self.loops:
            total.add(solver.solver.statistics)
        return total
