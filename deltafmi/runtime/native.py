"""A component's native kernels: which of its computations ``deltafmi build`` compiles to C.

A component names plain Python functions (kernels: floats, fixed-length sequences, NamedTuples,
dataclasses of floats; see deltafmi/builder/codegen/translate.py for the subset) and where each
argument comes from::

    native = NativeKernels(
        derivatives=Kernel(dynamics.state_derivative, "_plant", "states", "u", "f", "pole"),
        outputs=Kernel(dynamics.plant_outputs, "_plant", "q", "v", "u", "f", "pole",
                       returns=("y", "yd", "z", "zd", "lam", "residual", "energy")),
        attributes={"_plant": DeltaParams})

An argument is ``"t"`` (the time), ``"states"`` (all continuous states, in order), a declared
variable (its attribute name: read from the FMU's value buffer, in C) or an attribute the
component sets in ``initialize``/``update`` whose type ``attributes`` gives (a dataclass of
floats, a NamedTuple, ``Optional[...]``, float, int, bool, str). The FMU's C layer calls the
generated code where the Python methods would run: ``derivatives`` for ``fmi2GetDerivatives``
(Model Exchange, between events) and CVODE's right-hand side (Co-Simulation),
``event_indicators`` for ``fmi2GetEventIndicators`` and CVODE's root functions, ``project`` for
CVODE's projection after every internal step (Co-Simulation, a component that overrides
``project``: the projected states; Model Exchange's step-event projection stays Python),
``outputs`` for the getters, ``step`` for ``fmi2DoStep`` of a component that steps itself (a
sampled controller, a reference generator; see :class:`Kernel`), ``update`` for the event update
of a component without states (``fmi2NewDiscreteStates``, fmi3UpdateDiscreteStates at a Clock's tick,
fmi3ActivateModelPartition), ``drift`` for ``fmi2CompletedIntegratorStep`` of a component that
watches its states for drift (:meth:`~deltafmi.runtime.Component.needs_projection`: true asks for
a step event), ``jacobian`` for the float part of :meth:`~deltafmi.runtime.Component.jacobian`
(Model Exchange's directional derivatives, the Co-Simulation solver's Newton matrix): Python
calls it (ctypes) and hands its floats to the kernel's ``then``, which builds the matrices
(numpy), and ``state_jacobian`` for CVODE's Newton matrix in Co-Simulation (``d derivatives / d
states``, the ``nx * nx`` floats column by column: column j the derivatives with respect to state j;
a component with a ``jacobian()`` and a derivatives kernel: the solver then calls no Python for
it). The component's Python methods stay, and must
compute the same numbers with the same kernels: they serve initialization, events, whatever the
C cannot, and the tests that compare the two. Attributes are copied to C after initialization,
after every event update and after every step Python takes; an attribute that does not fit its
declared type then (``None`` where it is not Optional, another type, an int beyond C's) leaves
that instance on Python until the next copy. A step kernel's updates are copied back before
Python next reads them.

``functions`` names further kernels the component calls itself, from Python, mid-computation (a
filter's process model inside its sample, say): ``functions={"step": Function(rk4_step, DeltaParams,
18, 3, float)}`` with each argument's type (:class:`Function`). ``deltafmi build`` compiles them into the
same library; the component calls ``self.native_functions.step(params, x, u, h)`` and gets the
compiled function where the FMU (or, in-process, :func:`deltafmi.builder.codegen.use_compiled_functions`)
has it, the Python function otherwise, with the same numbers (see
:mod:`deltafmi.runtime.native_functions`).

``mode``: ``"required"`` (default) fails the build with the file and line of a construct the
generator cannot translate; ``"fallback"`` warns with the same text instead and ships Python only;
``"off"`` skips the kernels.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Optional

__all__ = ["Function", "Kernel", "NativeKernels"]

MODES = ("required", "fallback", "off")


@dataclass(frozen=True)
class Kernel:
    """One kernel call: ``func(*args)`` with each argument named by where it comes from.

    ``returns``: the variables its result is written to, in order (the result is flattened: a
    flat tuple of all their scalars, or one item per variable); for ``derivatives`` and
    ``event_indicators`` the result is the state derivatives / the indicators, and ``returns``
    stays empty. A ``project`` kernel returns the projected states: all of them in state order
    with ``returns`` empty, else the state variables ``returns`` names (the others stay).

    A ``step`` kernel (``fmi2DoStep`` of a component that steps itself, from ``"t"`` over
    ``"h"``) may also change attributes: its result is ``(*updates, *outputs)``, the new values of
    the attributes named in ``updates`` (dotted paths reach into an attribute: ``"_ctl.state"``)
    and then the outputs' values; with ``defer=True`` an int follows the updates: nonzero discards
    the whole C result and runs the Python ``do_step`` instead, for what C cannot do (log a warning).
    An ``update`` kernel (the event update at ``"t"`` of a component without states) returns
    ``(*updates, [defer flag], next time event (nan: none), *outputs)``, as its ``update()`` and
    ``next_time_event()`` would. A ``jacobian`` kernel returns floats (a flat sequence) and
    ``then(values)`` (a Python function, given them as a float64 array) returns what the
    component's ``jacobian(t)`` would: that method must be ``then`` of the kernel's Python."""

    func: Callable
    args: tuple
    returns: tuple = ()
    updates: tuple = ()
    defer: bool = False
    then: Optional[Callable] = None

    def __init__(self, func: Callable, *args: str, returns: tuple = (), updates: tuple = (),
                 defer: bool = False, then: Optional[Callable] = None) -> None:
        object.__setattr__(self, "func", func)
        object.__setattr__(self, "args", tuple(args))
        object.__setattr__(self, "returns", tuple(returns))
        object.__setattr__(self, "updates", tuple(updates))
        object.__setattr__(self, "defer", bool(defer))
        object.__setattr__(self, "then", then)


@dataclass(frozen=True)
class Function:
    """A plain-float function the component calls itself, compiled: ``func`` and the type of each
    of its parameters, in order.

    A type is ``float``, ``int`` or ``bool``; an int ``n``: n floats (a sequence or a float64
    array; the C reads a copy); a dataclass whose fields are all floats (parameters); a NamedTuple
    class; or a fixed-length ``tuple[...]`` of these. The result: a number (returned as a Python
    number) or any fixed-length nesting of tuples and lists of numbers, returned flattened as a new
    float64 array (the compiled function and the Python one alike)."""

    func: Callable
    args: tuple

    def __init__(self, func: Callable, *args: Any) -> None:
        object.__setattr__(self, "func", func)
        object.__setattr__(self, "args", tuple(args))


@dataclass(frozen=True)
class NativeKernels:
    """The kernels of a component compiled to C (see the module docstring)."""

    derivatives: Optional[Kernel] = None
    event_indicators: Optional[Kernel] = None
    outputs: Optional[Kernel] = None
    step: Optional[Kernel] = None
    update: Optional[Kernel] = None
    project: Optional[Kernel] = None
    jacobian: Optional[Kernel] = None
    drift: Optional[Kernel] = None
    attributes: Mapping[str, Any] = field(default_factory=dict)
    mode: str = "required"
    state_jacobian: Optional[Kernel] = None
    functions: Mapping[str, Function] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name, function in self.functions.items():
            if not (name.isidentifier() and name.isascii()) or not isinstance(function, Function):
                raise ValueError(f"NativeKernels functions: {name!r} must be an ASCII identifier naming a "
                                 f"Function(func, *argument types)")
            if name.startswith("_") or name == "compiled":
                raise ValueError(f"NativeKernels functions: {name!r} is taken (names starting with '_' and "
                                 f"'compiled' are the function set's own)")
        if self.mode not in MODES:
            raise ValueError(f"NativeKernels mode {self.mode!r} must be one of {', '.join(MODES)}")
        if self.jacobian is not None and self.jacobian.then is None:
            raise ValueError("NativeKernels: a jacobian kernel needs then=, the function that builds "
                             "jacobian()'s matrices from its floats")

    def kernels(self) -> dict[str, Kernel]:
        """The declared kernels by role (``derivatives``, ``event_indicators``, ``outputs``, ``step``,
        ``update``, ``project``, ``jacobian``, ``drift``, ``state_jacobian``)."""
        return {role: k for role, k in (("derivatives", self.derivatives), ("event_indicators", self.event_indicators),
                                        ("outputs", self.outputs), ("step", self.step), ("update", self.update),
                                        ("project", self.project), ("jacobian", self.jacobian),
                                        ("drift", self.drift), ("state_jacobian", self.state_jacobian))
                if k is not None}
