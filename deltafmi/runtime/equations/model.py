"""Equation models and their parts: declarations, sub-model instances, connectors, flattening.

A :class:`Model` declares variables as class attributes (``Real`` unknowns, ``Parameter``s,
connectors, instances of other models) and returns its equations from ``equations(self)``; the
enclosing model is ``self.outer``. :func:`flatten` turns a model class into one flat list of
scalar variables and equations, with instance prefixes (``arm1.q[2]``) and the equations that
``connect`` implies: equal potentials and flows summing to zero in every connection set, zero
flow into a connector that nothing connects. Pure Python and numpy: the FMU runs it as well, to
find its compiled equations again (see :mod:`.component`).
"""
from __future__ import annotations

import hashlib
import inspect
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np

from deltafmi.runtime.errors import DeltaFmiError
from deltafmi.runtime.variables import Input, Output, Parameter, State, Variable

from .expr import Equation, Expr, Var, as_expr, caller, equation_list, text, vec

__all__ = ["Connector", "Discrete", "EquationModelError", "FlatModel", "Flow", "If", "Model", "Potential", "Real",
           "Statement", "assign", "connect", "default_section", "flatten", "reinit", "statement_text", "when"]



def default_section(function: Any) -> Any:
    """Marks a base class's empty ``equations``/``initial_equations``/``algorithm``."""
    function._default = True
    return function


class EquationModelError(DeltaFmiError, ValueError):
    """The model cannot be flattened or compiled (the message names the model line)."""

    exit_code = 2  # bad input

    def __repr__(self) -> str:  # shown inside other errors' messages: the message alone
        return str(self)


class Real:
    """An unknown of an equation model: a state if the model takes its ``der()``, else algebraic.

    ``start``: the start value (of a state: its initial value unless initial equations say
    otherwise; of an algebraic unknown: the first guess of a nonlinear solve)."""

    kind = "unknown"

    def __init__(self, start: Any = 0.0, *, shape: Optional[int] = None, unit: str = "", description: str = "",
                 nominal: Optional[float] = None, name: Optional[str] = None) -> None:
        if not isinstance(start, (int, float)):
            start = [float(v) for v in np.asarray(start, dtype=float).ravel()]
            shape = len(start)
        elif shape is not None:
            start = [float(start)] * shape
        self.start, self.shape, self.unit, self.description = start, shape, unit, description
        self.nominal, self.fmi_name, self.name = nominal, name, ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        self.fmi_name = self.fmi_name or name


class Discrete(Real):
    """A discrete unknown: constant between events, changed by ``when`` bodies and algorithms."""

    kind = "discrete"


class Potential(Real):
    """A potential variable of a connector (voltage, angle): equal across a connection."""


class Flow(Real):
    """A flow variable of a connector (current, torque): sums to zero at a connection."""


class Connector:
    """A connector type: declare its :class:`Potential` and :class:`Flow` variables in a subclass
    (``class Pin(Connector): v = Potential(unit="V"); i = Flow(unit="A")``), then declare
    connectors as ``p = Pin()`` in a model."""

    def __init__(self) -> None:
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    @classmethod
    def variables(cls) -> dict:
        return {k: v for c in reversed(cls.__mro__) for k, v in vars(c).items() if isinstance(v, Real)}


class Statement:
    """A ``when`` clause, an if-equation or statement, ``reinit`` or an assignment."""

    def __init__(self, kind: str, *args: Any) -> None:
        self.kind, self.args, self.where = kind, args, caller()


def when(condition: Any, *body: Any) -> Statement:
    """``when condition then body end when``: ``body`` (``reinit``, ``assign``) runs at the event
    at which ``condition`` becomes true."""
    return Statement("when", as_expr(condition), _flat_body(body))


def reinit(state: Any, value: Any) -> Statement:
    """``reinit(x, value)``: the state jumps to ``value`` at the event."""
    return Statement("reinit", state, as_expr(value))


def assign(variable: Any, value: Any) -> Statement:
    """``variable := value`` at an event (a discrete variable)."""
    return Statement("assign", variable, as_expr(value))


def If(condition: Any, then: Any, otherwise: Any = ()) -> Statement:  # noqa: N802 (Modelica's keyword)
    """An if-equation (in ``equations``: the branch's equations hold, the condition depending on
    parameters and discrete variables only) or an if-statement (in ``algorithm``)."""
    return Statement("if", as_expr(condition), _flat_body([then]), _flat_body([otherwise]))


def _flat_body(items: Any) -> list:
    out: list = []
    for item in items:
        if isinstance(item, (list, tuple)):
            out += _flat_body(item)
        else:
            out.append(item)
    return out


def connect(a: "ConnectorInstance", b: "ConnectorInstance") -> Statement:
    """``connect(a, b)`` of two connectors of one type: their potentials are equal, their flows
    (with the flows of every other connector in the same connection set) sum to zero."""
    if not isinstance(a, ConnectorInstance) or not isinstance(b, ConnectorInstance):
        raise EquationModelError(f"{caller()}: connect() takes two connectors, not {a!r} and {b!r}")
    if a.connector_type is not b.connector_type:
        raise EquationModelError(f"{caller()}: connect({a.prefix}, {b.prefix}): a {a.connector_type.__name__} "
                                 f"and a {b.connector_type.__name__}")
    return Statement("connect", a, b)


class Model:
    """Base class of equation models and of their parts (see the module docstring)."""

    def __init__(self, **modifiers: Any) -> None:
        self.modifiers = modifiers
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    @default_section
    def equations(self) -> list:
        """The model's equations (and if-equations, when clauses, connects)."""
        return []

    @default_section
    def initial_equations(self) -> list:
        """Equations that hold at the start only (consistent initial states)."""
        return []

    @default_section
    def algorithm(self) -> list:
        """Statements run in order at every event (if, assign, reinit), until nothing changes."""
        return []


@dataclass
class FlatVariable:
    """One scalar of the flat model."""

    name: str  #: flat name, e.g. ``arm1.q[2]``
    kind: str  #: parameter, input, output, unknown, discrete
    start: Any
    group: str  #: the declaration's flat name (``arm1.q``)
    index: Optional[int]  #: 0-based index in the declaration, None for a scalar
    declaration: Any = None  #: the top-level Component declaration, when there is one
    unit: str = ""
    description: str = ""
    nominal: Optional[float] = None
    fmi_group: str = ""  #: the FMI name of the declaration (``lambda`` for ``lam``)


@dataclass
class FlatModel:
    """A model flattened: scalar variables, equations and the statements of its events."""

    name: str
    variables: dict = field(default_factory=dict)  #: flat name -> FlatVariable
    equations: list = field(default_factory=list)  #: Equation or Statement("if", ...)
    initial: list = field(default_factory=list)
    whens: list = field(default_factory=list)
    algorithm: list = field(default_factory=list)

    def key(self) -> str:
        """A digest of everything the compiled code depends on."""
        digest = hashlib.sha256(self.name.encode())
        for v in self.variables.values():
            digest.update(f"{v.name}|{v.kind}|{v.start}\n".encode())
        for section in (self.equations, self.initial, self.whens, self.algorithm):
            digest.update(b"#section\n")
            for item in section:
                digest.update((statement_text(item) + "\n").encode())
        return digest.hexdigest()


def statement_text(item: Any) -> str:
    """An equation or statement as text."""
    if isinstance(item, Equation):
        return f"{text(item.lhs)} = {text(item.rhs)}"
    if isinstance(item, Statement):
        return f"{item.kind}(" + ", ".join(
            "[" + "; ".join(statement_text(s) for s in a) + "]" if isinstance(a, list) else
            (text(a) if isinstance(a, Expr) else statement_text(a) if isinstance(a, Statement) else
             getattr(a, "prefix", repr(a))) for a in item.args) + ")"
    return repr(item)


class ConnectorInstance:
    """A connector in a flattened model: its variables by attribute, prefixed."""

    def __init__(self, connector_type: type, prefix: str, values: dict) -> None:
        self.connector_type, self.prefix = connector_type, prefix
        self.__dict__.update(values)
        self._values = values

    def __repr__(self) -> str:
        return self.prefix


class Instance:
    """``self`` in a model's ``equations``: its variables as expressions, its parts as instances."""

    def __init__(self, cls: type, prefix: str, outer: Optional["Instance"], flat: "_Flattener",
                 modifiers: dict) -> None:
        self._cls, self._prefix, self.outer = cls, prefix, outer
        for name, decl in declarations(cls).items():
            flat_name = prefix + name
            if isinstance(decl, Model):
                value: Any = Instance(type(decl), flat_name + ".", self, flat, decl.modifiers)
                flat.instances.append(value)
            elif isinstance(decl, Connector):
                values = {k: flat.declare(f"{flat_name}.", k, d, self._cls) for k, d in decl.variables().items()}
                value = ConnectorInstance(type(decl), flat_name, values)
                flat.connectors[flat_name] = (value, decl)
            elif name in modifiers and isinstance(decl, (Parameter, Real)):
                value = modifiers[name]
                if isinstance(value, Variable):  # Arm(l1=l1) in a class body: the outer's parameter
                    value = getattr(outer, value.name)
                value = _as_value(value, decl)
            else:
                value = flat.declare(prefix, name, decl, cls)
            setattr(self, name, value)
        unknown = set(modifiers) - set(declarations(cls))
        if unknown:
            raise EquationModelError(f"{cls.__name__}: no parameter named {', '.join(sorted(unknown))} to modify")

    def __getattr__(self, name: str) -> Any:
        member = getattr(self._cls, name, None)
        if callable(member):
            return member.__get__(self, type(self))
        raise AttributeError(f"{self._cls.__name__} instance {self._prefix.rstrip('.') or 'model'} has no "
                             f"variable, part or method {name!r}")


def _as_value(value: Any, decl: Any) -> Any:
    shape = decl.shape
    if shape is None:
        return as_expr(value) if not isinstance(value, np.ndarray) else value
    return vec(np.asarray(value, dtype=object).ravel().tolist())


def declarations(cls: type) -> dict:
    """The declarations of a model class (variables, parts, connectors), in order, bases first."""
    out: dict = {}
    for c in reversed(cls.__mro__):
        for k, v in vars(c).items():
            if isinstance(v, (Real, Variable, Model, Connector)):
                out[k] = v
    return out


class _Flattener:
    def __init__(self, model: FlatModel) -> None:
        self.model = model
        self.instances: list = []
        self.connectors: dict = {}

    def declare(self, prefix: str, name: str, decl: Any, owner: type) -> Any:
        top = prefix == ""
        if isinstance(decl, Parameter):
            kind = "parameter" if top else "parameter"
        elif isinstance(decl, Input):
            kind = "input" if top else "unknown"
        elif isinstance(decl, Output):
            kind = ("discrete" if decl.type is not float else "output") if top else "unknown"
        elif isinstance(decl, State):
            kind = "unknown"
        elif isinstance(decl, Real):
            kind = decl.kind
        else:
            raise EquationModelError(f"{owner.__name__}.{name}: {type(decl).__name__} is not a variable of an "
                                     f"equation model")
        if isinstance(decl, Parameter) and not top:
            raise EquationModelError(f"{owner.__name__}.{name}: a part's parameter must be bound where the part is "
                                     f"declared ({name}=...): the FMU's parameters are the top-level model's")
        group = prefix + name
        fmi_group = prefix + (getattr(decl, "fmi_name", None) or name)
        starts = decl.start if isinstance(decl, Real) else [v for v in decl.start]
        shape = decl.shape
        if shape is None:
            start = starts[0] if isinstance(starts, list) else starts
            self._add(FlatVariable(group, kind, start, group, None, decl if top else None, decl.unit,
                                   decl.description, decl.nominal, fmi_group))
            return Var(group, _expr_kind(kind))
        items = []
        for k in range(shape):
            scalar = f"{group}[{k + 1}]"
            start = starts[k] if isinstance(starts, list) else starts
            self._add(FlatVariable(scalar, kind, start, group, k, decl if top else None, decl.unit,
                                   decl.description, decl.nominal, fmi_group))
            items.append(Var(scalar, _expr_kind(kind)))
        return vec(items)

    def _add(self, variable: FlatVariable) -> None:
        self.model.variables[variable.name] = variable


def _expr_kind(kind: str) -> str:
    return "unknown" if kind == "output" else kind


def flatten(cls: type) -> FlatModel:
    """The flat model of equation model class ``cls`` (its instances expanded, connects resolved)."""
    model = FlatModel(cls.__name__)
    flattener = _Flattener(model)
    top = Instance(cls, "", None, flattener, {})
    instances = [top] + flattener.instances
    connects = []
    for instance in instances:
        where = f"{instance._cls.__name__}.equations"
        for item in _run(instance, "equations", where):
            if isinstance(item, Statement) and item.kind == "connect":
                connects.append(item)
            elif isinstance(item, Statement) and item.kind == "when":
                model.whens.append(item)
            elif isinstance(item, (Equation, Statement)):
                model.equations.append(item)
            else:
                raise EquationModelError(f"{where}: {item!r} is not an equation")
        model.initial += [e for e in _run(instance, "initial_equations", where)]
        model.algorithm += _run(instance, "algorithm", where)
    model.equations += _connection_equations(connects, flattener.connectors)
    return model


def _run(instance: Instance, method: str, where: str) -> list:
    """The items ``method`` of every class of the instance's model returns, bases first (a
    subclass extends its base's equations, as Modelica's ``extends``)."""
    out: list = []
    for owner in reversed(instance._cls.__mro__):
        function = vars(owner).get(method)
        if function is None or getattr(function, "_default", False):
            continue
        try:
            result = function(instance)
        except EquationModelError:
            raise
        except (TypeError, ValueError, AttributeError, IndexError) as exc:
            raise EquationModelError(f"{_location(function)}: {owner.__name__}.{method}: {exc}") from None
        out += equation_list(list(result or []))
    return out



def _location(function: Any) -> str:
    try:
        return f"{inspect.getsourcefile(function).rsplit('/', 1)[-1]}:{function.__code__.co_firstlineno}"
    except (TypeError, AttributeError):
        return "?"


def _connection_equations(connects: list, connectors: dict) -> list:
    """Equal potentials and zero flow sums of every connection set; zero flow where unconnected."""
    parent = {name: name for name in connectors}

    def find(x: str) -> str:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for statement in connects:
        a, b = statement.args
        parent[find(a.prefix)] = find(b.prefix)
    sets: dict = {}
    for name in connectors:
        sets.setdefault(find(name), []).append(name)
    out = []
    for members in sets.values():
        first, decl = connectors[members[0]]
        where = f"connect({', '.join(members)})" if len(members) > 1 else f"{members[0]} (not connected)"
        for var_name, var in decl.variables().items():
            values = [getattr(connectors[m][0], var_name) for m in members]
            if isinstance(var, Flow):
                total = values[0]
                for v in values[1:]:
                    total = total + v
                out.append(Equation(total, 0.0, where))
            else:
                out += [Equation(values[0], v, where) for v in values[1:]]
    return out
