"""The :class:`Component` base class that models and controllers derive from."""
from __future__ import annotations

import copy
import logging
import math
import struct
from operator import methodcaller
from contextlib import nullcontext
from typing import Any, Callable, ClassVar, ContextManager, Optional, Sequence, Tuple

import numpy as np

from .layout import Layout, build_layout
from .native_values import ValueDescriptor, ValueHolder
from .native_functions import FunctionSet
from .variables import _REAL_ARRAY, Experiment

__all__ = ["Component"]

#: attributes the runtime keeps on a component (its value buffers, log sink, ...): not its own state
RUNTIME_ATTRIBUTES = frozenset({"_real", "_real_view", "_real_item", "_real_items", "_int", "_int_item",
                                "_int_items", "_str", "_str_items", "_log_sink", "_control", "resources_dir",
                                "own_modules", "_c_step", "_native_functions"})

_ATOMS = frozenset((float, int, bool, str, bytes, complex, type(None)))


def _unchangeable(value: Any) -> bool:
    """Whether ``value`` cannot change in place: a number, a string, None, or a tuple of such (a
    NamedTuple too). Not a frozen dataclass: ``object.__setattr__`` still changes one."""
    kind = type(value)
    if kind in _ATOMS:
        return True
    if isinstance(value, tuple):
        if kind is not tuple and hasattr(value, "__dict__"):
            return False
        # a long tuple of numbers (a path's samples) checked without a call each
        return all(type(item) in _ATOMS or _unchangeable(item) for item in value)
    return False


#: the key under which an internal state lists the attributes it shares (not a str: no attribute's name)
_SHARED = ("deltafmi", "shared")


def _copied(attributes: dict, shared: Optional[frozenset] = None) -> dict:
    """A deep copy of ``attributes`` in which values that cannot change in place are shared (the
    others copied together, so that the references among them are kept); ``shared``: the keys of
    those values when known (the values of a snapshot: looking through them again would give the same)."""
    keep = frozenset(k for k, v in attributes.items() if _unchangeable(v)) if shared is None else shared
    fresh = copy.deepcopy({k: v for k, v in attributes.items() if k not in keep})
    return {k: v if k in keep else fresh[k] for k, v in attributes.items()}


#: Component.log levels -> (FMI status, log category)
LOG_LEVELS = {"debug": (0, "logComponent"), "info": (0, "logComponent"), "warning": (1, "logStatusWarning"),
              "error": (3, "logStatusError")}


class _StatesView(ValueDescriptor):
    """View of all continuous states (flat)."""

    def __init__(self, nx: int) -> None:
        super().__init__()
        span = slice(0, nx)
        self._install(_REAL_ARRAY, 0, span, methodcaller("_real_items", span), None)


class Component(ValueHolder):
    """A physical model or controller that becomes one FMI 2.0 FMU (Model Exchange + Co-Simulation).

    Declare variables as class attributes (:class:`Parameter`, :class:`Input`, :class:`Output`,
    :class:`State`) and override the hooks below. The first line of the class docstring becomes
    the FMU description.
    """

    model_name: ClassVar[Optional[str]] = None
    default_experiment: ClassVar[Experiment] = Experiment()
    n_event_indicators: ClassVar[int] = 0
    #: options of the internal CVODE used by Co-Simulation ``doStep``: rtol (default: the
    #: experiment's tolerance), rtol_factor (multiplies it), atol (default: rtol * nominals),
    #: max_step, method ("bdf" or "adams")
    cs_options: ClassVar[dict] = {}
    author: ClassVar[str] = ""
    version: ClassVar[str] = "1.0"
    #: offer Co-Simulation only (no ``<ModelExchange>``, no directional derivatives): for a
    #: component whose ``do_step`` is all it does, such as a whole scenario run by a master
    co_simulation_only: ClassVar[bool] = False
    #: whether fmi2SerializeFMUstate can write this component's state (see :meth:`internal_state`)
    can_serialize_state: ClassVar[bool] = True

    _layout: ClassVar[Layout]

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._layout = build_layout(cls)
        cls.states = _StatesView(cls._layout.nx)  # read as the variable declarations are
        cls._real_spans = {}  # names -> spans of the real buffer, for read_reals()
        cls._real_packers = {}  # names -> (start, end, struct) per span, for write_reals()

    def __init__(self, resources_dir: str = "") -> None:
        self._attach(resources_dir, [])

    def _attach(self, resources_dir: str, log_sink: list, buffers: Optional[tuple] = None,
                control: Optional[np.ndarray] = None,
                own_modules: Callable[[], ContextManager] = nullcontext) -> None:
        """Set start values (into ``buffers`` when given, so their addresses stay), then setup().

        ``control``: the runtime's flags the native loader reads ([0] nonzero: the component ended
        the simulation, [1] the time it reached, NaN when the step's end). ``own_modules``: in an
        FMU, a context under which ``import deltafmi...`` finds the FMU's own copy of deltafmi
        (:attr:`own_modules`; outside the model's import, a host's deltafmi or none is found)."""
        layout = self._layout
        if buffers is None:
            buffers = (np.empty_like(layout.real_start), np.empty_like(layout.int_start), [])
        self._real, self._int, self._str = buffers
        self._real_view = memoryview(self._real)  # indexing it is cheaper than ndarray.item()
        # what the variable declarations' getters call (see variables.py): C all the way
        self._real_item, self._real_items = self._real_view.__getitem__, self._real.__getitem__
        self._int_item, self._int_items = memoryview(self._int).__getitem__, self._int.__getitem__
        self._str_items = self._str.__getitem__
        self._bind_buffers(self._real, self._int)
        self._real[:] = layout.real_start
        self._int[:] = layout.int_start
        self._str[:] = layout.str_start
        self._log_sink = log_sink
        self._control = control if control is not None else np.array([0.0, math.nan])
        self.resources_dir = resources_dir
        #: ``with self.own_modules(): ...`` runs code that imports deltafmi modules while the FMU
        #: runs (not only when its model is imported) against the FMU's own copy
        self.own_modules = own_modules
        self.setup()

    # --- hooks ------------------------------------------------------------------------------
    def setup(self) -> None:
        """Create internal (non-FMI) state. Called at construction and at ``fmi2Reset``."""

    def setup_experiment(self, start: float, stop: Optional[float]) -> None:
        """The importer's start and stop time (None: no stop time), before initialization."""

    def initialize(self, t: float) -> None:
        """Compute calculated start values from parameters (runs during initialization mode)."""

    def derivatives(self, t: float) -> Sequence[float]:
        """State derivatives, flat, in State declaration order."""
        return ()

    def outputs(self, t: float) -> None:
        """Assign the outputs for the current time, states and inputs."""

    def event_indicators(self, t: float) -> Sequence[float]:
        """``n_event_indicators`` values; an event happens where one changes sign."""
        return ()

    def jacobian(self, t: float) -> Optional[dict[str, Any]]:
        """Exact partial derivatives at the current time, states and inputs; None: none given.

        A dict from unknowns to matrices with one column per known: the continuous states, then
        the Real inputs, in declaration order (``nx + n_real_inputs`` columns). Key ``"der"``
        holds the state derivatives (``nx`` rows); an Output's attribute name holds that
        output's scalars. Whatever is left out (or everything, by default) the runtime
        differentiates numerically: central differences with steps from the nominals. The FMU
        answers ``fmi2GetDirectionalDerivative`` from these, and its Co-Simulation solver uses
        ``"der"`` as its Newton matrix. The runtime reuses a result while the time and every
        variable keep their values, until the next event.
        """
        return None

    def update(self, t: float) -> Optional[bool]:
        """Discrete update at an event; return True if another event iteration is needed."""
        return None

    def next_time_event(self, t: float) -> Optional[float]:
        """The next time event strictly after ``t``, or None."""
        return None

    def project(self, t: float) -> None:
        """Move the states onto an invariant manifold (e.g. closed kinematic loops), in place.

        The Co-Simulation solver (CVODE's projection method) calls it after every internal
        step. In Model Exchange the importer integrates; there it runs at a step event when
        :meth:`needs_projection` says the states drifted.
        """

    def needs_projection(self, t: float) -> bool:
        """Model Exchange: have the states drifted so far off the manifold that they need :meth:`project`?

        Asked at every ``fmi2CompletedIntegratorStep``; True requests a step event, in which
        :meth:`project` runs and the FMU reports ``valuesOfContinuousStatesChanged`` so the
        importer restarts its integrator from the projected states. Overriding it makes the FMU
        declare that it needs ``fmi2CompletedIntegratorStep``.
        """
        return False

    def internal_state(self) -> Any:
        """What an FMU state saves besides the variables (``fmi2GetFMUstate``): by default a deep
        copy of the component's own attributes (those that cannot change in place, numbers and
        tuples of them, are kept as they are). Override with :meth:`restore_internal_state`
        when an attribute cannot be copied (a handle of another library)."""
        attributes = {k: v for k, v in vars(self).items() if k not in RUNTIME_ATTRIBUTES}
        shared = frozenset(k for k, v in attributes.items() if _unchangeable(v))
        state = _copied(attributes, shared)
        state[_SHARED] = shared  # type: ignore[index]
        return state

    def restore_internal_state(self, state: Any) -> None:
        """Restore what :meth:`internal_state` returned (which stays valid for another restore)."""
        if not isinstance(state, dict) or not all(isinstance(k, str) for k in state if k != _SHARED):
            raise TypeError("not an internal state of a component: attributes are named by strings")
        if not RUNTIME_ATTRIBUTES.isdisjoint(state):  # the instance's, never in a state (a buffer, its resources)
            raise ValueError(f"not an internal state of a component: it sets {sorted(RUNTIME_ATTRIBUTES & state.keys())}")
        shared = state.get(_SHARED)  # a state saved by an older runtime has none
        # copied before any attribute goes: a state that cannot be restored leaves the component as it was
        restored = _copied({k: v for k, v in state.items() if k != _SHARED}, shared)
        attributes = vars(self)
        for key in [k for k in attributes if k not in RUNTIME_ATTRIBUTES]:
            del attributes[key]
        attributes.update(restored)

    def do_step(self, t: float, h: float) -> None:
        """Advance from ``t`` to ``t + h``. Override only for purely discrete components."""
        raise NotImplementedError

    # --- services ---------------------------------------------------------------------------
    def read_reals(self, *names: str) -> list[float]:
        """The values of the named Real variables (attribute names), flat, as Python floats.

        Equal to concatenating ``self.<name>`` for each name, but one slice of the value buffer
        instead of one descriptor call and one numpy view per variable: for a model whose
        compiled or plain-Python math wants lists (``y, yd = v[0:3], v[3:6]``), it is the cheap
        way to read many inputs at once.
        """
        spans = self._real_spans.get(names)
        if spans is None:
            spans = self._real_spans[names] = self._spans_of(names)
        view = self._real_view
        if len(spans) == 1:
            return view[spans[0][0]:spans[0][1]].tolist()
        values: list[float] = []
        for start, end in spans:
            values += view[start:end].tolist()
        return values

    def write_reals(self, values: Sequence[float], *names: str) -> None:
        """Assign the named Real variables from one flat sequence of numbers, in order.

        The inverse of :meth:`read_reals`: ``self.write_reals((1.0, 2.0, 3.0, 4.0), "r", "s")``
        for a 3-vector ``r`` and a scalar ``s``. The numbers are packed straight into the value
        buffer (one struct per contiguous stretch, no numpy arrays made).
        """
        entry = self._real_packers.get(names)
        if entry is None:
            spans = self._spans_of(names)
            entry = self._real_packers[names] = (sum(end - start for start, end in spans), [
                (start, end - start, struct.Struct(f"={end - start}d")) for start, end in spans])
        size, packers = entry
        if len(values) != size:
            raise ValueError(f"write_reals: {len(values)} values for the {size} scalars of {', '.join(names)}")
        buffer = self._real
        if len(packers) == 1:
            packers[0][2].pack_into(buffer, 8 * packers[0][0], *values)
            return
        first = 0
        for start, n, packer in packers:
            packer.pack_into(buffer, 8 * start, *values[first:first + n])
            first += n

    @classmethod
    def _spans_of(cls, names: tuple) -> list[tuple[int, int]]:
        """(start, end) slices of the real buffer holding ``names``, neighbours merged."""
        declarations = {d.name: d for d in cls._layout.declarations}
        spans: list[tuple[int, int]] = []
        for name in names:
            decl = declarations.get(name)
            if decl is None or decl.type is not float:
                raise ValueError(f"{name!r} is not a Real variable of {cls.__name__}")
            if spans and spans[-1][1] == decl.offset:
                spans[-1] = (spans[-1][0], decl.offset + decl.size)
            else:
                spans.append((decl.offset, decl.offset + decl.size))
        return spans

    def log(self, message: str, level: str = "info") -> None:
        """Send a message to the importer's FMI logger: ``debug``/``info`` (category logComponent,
        sent when the importer enables it), ``warning`` (logStatusWarning) or ``error``
        (logStatusError, always sent). The same as logging through :attr:`logger`; never print().
        """
        status, category = LOG_LEVELS.get(level, LOG_LEVELS["info"])
        self._log_sink.append((status, category, str(message)))

    @property
    def logger(self) -> logging.Logger:
        """The logger of the component's module (``logging.getLogger(__name__)`` in its source).

        In an FMU its records go to the importer's FMI logger only: DEBUG and INFO as logComponent,
        WARNING as logStatusWarning, ERROR as logStatusError. ``warnings.warn`` works too."""
        return logging.getLogger(type(self).__module__)

    def terminate_simulation(self, reason: str) -> None:
        """End the simulation here, for ``reason`` (sent to the FMI logger as logStatusDiscard).

        Callable from any hook; from ``update`` (at a time or state event) it ends at an exact
        time. Model Exchange: the next fmi2CompletedIntegratorStep or fmi2NewDiscreteStates
        reports terminateSimulation = true (importers may skip the former: the FMU declares it
        not needed unless :meth:`needs_projection` is overridden). Co-Simulation: the step stops
        where it is (at the event when called from ``update``) and fmi2DoStep returns fmi2Discard;
        fmi2GetBooleanStatus(fmi2Terminated) is then true and
        fmi2GetRealStatus(fmi2LastSuccessfulTime) the time reached."""
        if not self._control[0]:
            self._control[0] = 1.0
            self._log_sink.append((2, "logStatusDiscard", f"ending the simulation: {reason}"))

    @property
    def terminated(self) -> bool:
        """Whether :meth:`terminate_simulation` was called (until fmi2Reset)."""
        return bool(self._control[0])

    @classmethod
    def fmi_model_name(cls) -> str:
        """The FMI model name and model identifier."""
        return cls.model_name or cls.__name__

    @classmethod
    def overrides_project(cls) -> bool:
        """True when the component projects its states onto an invariant manifold."""
        return cls.project is not Component.project

    @classmethod
    def watches_drift(cls) -> bool:
        """True when the component checks its states for drift after every ME integrator step."""
        return cls.needs_projection is not Component.needs_projection

    @classmethod
    def provides_jacobian(cls) -> bool:
        """True when the component gives exact partial derivatives (:meth:`jacobian`)."""
        return cls.jacobian is not Component.jacobian

    @classmethod
    def _compiled_step(cls) -> Optional[Tuple[int, int, int]]:
        """None, or a Co-Simulation step the component takes in C: the addresses of its step
        ``int step(void *context, double t, double h, double *real, int *ints)`` (the step's
        outputs written too) and outputs ``int outputs(const void *context, double t, double
        *real, int *ints, double *unused)``, each returning 0 when it did the work (otherwise
        :meth:`do_step` or :meth:`outputs` runs), and the size in bytes of their context. In an
        FMU the instance gives the component ``self._c_step`` (:class:`.instance.CompiledStep`):
        the context's bytes, and the flag under which the FMU's C layer calls the functions."""
        return None

    @classmethod
    def overrides_do_step(cls) -> bool:
        """True when the component steps itself in Co-Simulation."""
        return cls.do_step is not Component.do_step

    @property
    def native_functions(self) -> FunctionSet:
        """The functions ``native = NativeKernels(functions=...)`` declares, by name: compiled where
        the FMU carries them (in-process: where the builder's ``use_compiled_functions`` registered
        them), else the Python functions; the same results either way
        (:mod:`.native_functions`)."""
        functions = self.__dict__.get("_native_functions")
        if functions is None:
            functions = self._native_functions = FunctionSet.for_class(type(self))
        return functions

    @property
    def states(self) -> np.ndarray:
        """View of all continuous states (flat)."""
        return self._real[: self._layout.nx]
