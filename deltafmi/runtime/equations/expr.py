"""The expressions an equation model is written in: a small tree that the builder turns into sympy.

Numbers, variables and the nodes below combine with the Python operators (``+ - * / ** -x``,
``< <= > >=`` give relations, ``&``, ``|``, ``~`` combine conditions); ``a == b`` between
expressions is an :class:`Equation`. Arrays are numpy object arrays of expressions
(:class:`Vec`), so ``R @ v``, ``M.T``, slicing and ``np.array`` constants work as in numpy;
``vec == other`` on them is a list of scalar equations. Nothing here needs more than the
standard library and numpy: a model file is imported inside the FMU too.
"""
from __future__ import annotations

import numbers
import os
import sys
from typing import Any, Iterable, Sequence

import numpy as np

__all__ = ["Equation", "Expr", "Var", "Vec", "abs_", "acos", "as_expr", "asin", "atan", "atan2", "caller", "cat", "cos",
           "cosh", "der", "edge", "equation_list", "equations", "exp", "ifelse", "jacobian", "log", "pre", "sin",
           "sinh", "sqrt", "tan", "tanh", "text", "time", "vec", "zeros"]

#: the functions of one argument a model may call (the builder maps them to sympy and C's libm)
FUNCTIONS = ("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "log", "sqrt", "abs")


class Expr:
    """A node of an equation model's expression tree (immutable; built by the operators)."""

    __slots__ = ("op", "args")

    def __init__(self, op: str, *args: Any) -> None:
        self.op = op
        self.args = args

    # arithmetic
    def __add__(self, o: Any) -> Any:
        return _binary("add", self, o)

    def __radd__(self, o: Any) -> Any:
        return _binary("add", o, self)

    def __sub__(self, o: Any) -> Any:
        return _binary("sub", self, o)

    def __rsub__(self, o: Any) -> Any:
        return _binary("sub", o, self)

    def __mul__(self, o: Any) -> Any:
        return _binary("mul", self, o)

    def __rmul__(self, o: Any) -> Any:
        return _binary("mul", o, self)

    def __truediv__(self, o: Any) -> Any:
        return _binary("div", self, o)

    def __rtruediv__(self, o: Any) -> Any:
        return _binary("div", o, self)

    def __pow__(self, o: Any) -> Any:
        return _binary("pow", self, o)

    def __rpow__(self, o: Any) -> Any:
        return _binary("pow", o, self)

    def __neg__(self) -> "Expr":
        return Node("neg", self)

    def __pos__(self) -> "Expr":
        return self

    # relations and logic (conditions of when, if-equations and ifelse)
    def __lt__(self, o: Any) -> Any:
        return _binary("lt", self, o)

    def __le__(self, o: Any) -> Any:
        return _binary("le", self, o)

    def __gt__(self, o: Any) -> Any:
        return _binary("gt", self, o)

    def __ge__(self, o: Any) -> Any:
        return _binary("ge", self, o)

    def __and__(self, o: Any) -> Any:
        return _binary("and", self, o)

    def __rand__(self, o: Any) -> Any:
        return _binary("and", o, self)

    def __or__(self, o: Any) -> Any:
        return _binary("or", self, o)

    def __ror__(self, o: Any) -> Any:
        return _binary("or", o, self)

    def __invert__(self) -> "Expr":
        return Node("not", self)

    def __eq__(self, o: Any) -> Any:  # type: ignore[override]
        if isinstance(o, np.ndarray):
            return NotImplemented
        return Equation(self, as_expr(o))

    def __ne__(self, o: Any) -> Any:  # type: ignore[override]
        return _binary("ne", self, o)

    __hash__ = object.__hash__

    def __bool__(self) -> bool:
        raise TypeError(f"an equation model's expression has no truth value here ({self}): use & | ~ "
                        f"for and/or/not, ifelse(c, a, b) for a conditional, and == only in equations")

    def __repr__(self) -> str:
        return text(self)

    def is_(self, value: Any) -> "Expr":
        """The relation ``self == value`` (``==`` itself makes an equation): ``contact.is_(1)``."""
        return _binary("eq", self, value)


class Node(Expr):
    """An operation node (``op`` and its arguments). Variables are a sibling class, not a
    subclass, so that Python never swaps the operands of ``node == variable``."""

    __slots__ = ()


class Var(Expr):
    """One scalar variable of the flat model, by its flat name (``arm1.q[2]``)."""

    __slots__ = ("name", "kind")

    def __init__(self, name: str, kind: str) -> None:
        super().__init__("var")
        self.name = name
        self.kind = kind  # "parameter", "input", "unknown", "discrete", "time"

    def __reduce__(self) -> tuple:
        return Var, (self.name, self.kind)


class Equation:
    """``lhs == rhs`` of an equation model (``where``: the model line it was written on)."""

    __slots__ = ("lhs", "rhs", "where")

    def __init__(self, lhs: Any, rhs: Any, where: str = "") -> None:
        self.lhs, self.rhs, self.where = as_expr(lhs), as_expr(rhs), where or caller()

    def __bool__(self) -> bool:
        raise TypeError(f"{self} is an equation, not a condition: write relations with is_(), < or <=")

    def __repr__(self) -> str:
        return f"{text(self.lhs)} == {text(self.rhs)}"


class Vec(np.ndarray):
    """A numpy object array of expressions whose ``==`` is a list of equations."""

    def __eq__(self, other: Any) -> Any:  # type: ignore[override]
        return equations(self, other)

    def __hash__(self) -> int:  # pragma: no cover - arrays are not hashed
        return id(self)


_HERE = os.path.dirname(os.path.abspath(__file__))
_NUMPY = os.path.dirname(np.__file__)


def caller() -> str:
    """``file:line`` of the model code that is running (the first frame outside this package and numpy)."""
    frame = sys._getframe(1)
    while frame is not None:
        path = frame.f_code.co_filename
        if not (path.startswith(_HERE) or path.startswith(_NUMPY)):
            return f"{os.path.basename(path)}:{frame.f_lineno}"
        frame = frame.f_back
    return "?"


def vec(items: Iterable[Any]) -> Vec:
    """A 1-D (or nested: 2-D) array of expressions and numbers."""
    data = list(items)
    out = np.empty(len(data), dtype=object)
    for k, item in enumerate(data):
        out[k] = item
    if data and isinstance(data[0], (list, tuple, np.ndarray)):
        return np.array([list(row) for row in data], dtype=object).view(Vec)
    return out.view(Vec)


def equations(lhs: Any, rhs: Any) -> list:
    """The scalar equations ``lhs[k] == rhs[k]`` of two arrays (or an array and a scalar)."""
    a, b = np.asarray(lhs, dtype=object), np.asarray(rhs, dtype=object)
    a, b = np.broadcast_arrays(a, b)
    return [Equation(x, y) for x, y in zip(a.ravel().tolist(), b.ravel().tolist())]


def as_expr(value: Any) -> Expr:
    """``value`` as an expression: numbers become constants."""
    if isinstance(value, Expr):
        return value
    if isinstance(value, (bool, np.bool_)):
        return Node("const", float(bool(value)))
    if isinstance(value, numbers.Real):
        return Node("const", float(value))
    raise TypeError(f"{value!r} ({type(value).__name__}) is not a number or an expression of an equation model")


def _binary(op: str, a: Any, b: Any) -> Any:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return NotImplemented
    try:
        return Node(op, as_expr(a), as_expr(b))
    except TypeError:
        return NotImplemented


def _elementwise(op: str, x: Any, *extra: Any) -> Any:
    if isinstance(x, np.ndarray):
        out = np.empty(x.shape, dtype=object)
        for index, item in np.ndenumerate(x):
            out[index] = Node(op, as_expr(item), *extra)
        return out.view(Vec)
    return Node(op, as_expr(x), *extra)


def _function(name: str) -> Any:
    def call(x: Any) -> Any:
        return _elementwise("call", x, name)
    call.__name__ = name
    call.__doc__ = f"``{name}(x)`` of an expression (elementwise on arrays)."
    return call


sin, cos, tan, asin, acos, atan = (_function(n) for n in FUNCTIONS[:6])
sinh, cosh, tanh, exp, log, sqrt = (_function(n) for n in FUNCTIONS[6:12])
abs_ = _function("abs")


def atan2(y: Any, x: Any) -> Expr:
    """``atan2(y, x)``."""
    return Node("atan2", as_expr(y), as_expr(x))


def der(x: Any) -> Any:
    """The time derivative ``der(x)`` of a variable or an expression (elementwise on arrays)."""
    return _elementwise("der", x)


def pre(x: Any) -> Any:
    """``pre(x)``: the value of ``x`` just before the event (in when bodies and conditions)."""
    return _elementwise("pre", x)


def edge(b: Any) -> Expr:
    """``edge(b) = b and not pre(b)``: the condition became true at this event."""
    return Node("edge", as_expr(b))


def ifelse(condition: Any, then: Any, otherwise: Any) -> Expr:
    """``if condition then a else b`` as an expression (Modelica's if-expression)."""
    return Node("if", as_expr(condition), as_expr(then), as_expr(otherwise))


def jacobian(f: Any, x: Any) -> Vec:
    """The matrix ``d f_i / d x_j`` of arrays ``f`` and ``x`` of expressions (``x`` variables),
    differentiated by the builder through the equations that define ``f``."""
    fs, xs = np.atleast_1d(np.asarray(f, dtype=object)), np.atleast_1d(np.asarray(x, dtype=object))
    out = np.empty((len(fs), len(xs)), dtype=object)
    for i, fi in enumerate(fs):
        for j, xj in enumerate(xs):
            if not isinstance(xj, Var):
                raise TypeError(f"jacobian(): differentiate with respect to variables, not {xj!r}")
            out[i, j] = Node("diff", as_expr(fi), xj)
    return out.view(Vec)


def cat(*parts: Any) -> Vec:
    """Modelica's ``cat(1, a, b, ...)`` of 1-D arrays (and scalars)."""
    return vec([item for part in parts for item in np.atleast_1d(np.asarray(part, dtype=object)).ravel()])


def zeros(n: int) -> Vec:
    """``zeros(n)``: n constants 0."""
    return vec([0.0] * n)


#: the simulation time, for equations and relations (``time >= 1.5`` is a state event at 1.5 s)
time = Var("time", "time")

_TEXT = {"add": "+", "sub": "-", "mul": "*", "div": "/", "pow": "^", "lt": "<", "le": "<=", "gt": ">",
         "ge": ">=", "and": " and ", "or": " or ", "eq": "==", "ne": "<>"}


def text(e: Any) -> str:
    """The expression in Modelica-like text (for messages and the model's structural key)."""
    if not isinstance(e, Expr):
        return repr(e)
    if isinstance(e, Var):
        return e.name
    op, args = e.op, e.args
    if op == "const":
        return repr(args[0])
    if op in _TEXT:
        return f"({text(args[0])}{_TEXT[op]}{text(args[1])})"
    if op == "neg":
        return f"(-{text(args[0])})"
    if op == "not":
        return f"(not {text(args[0])})"
    if op == "call":
        return f"{args[1]}({text(args[0])})"
    if op == "if":
        return f"(if {text(args[0])} then {text(args[1])} else {text(args[2])})"
    if op == "diff":
        return f"d({text(args[0])})/d({text(args[1])})"
    return f"{op}({', '.join(text(a) for a in args)})"


def walk(e: Expr) -> Iterable[Expr]:
    """Every node of ``e``, depth first."""
    stack = [e]
    while stack:
        node = stack.pop()
        yield node
        stack.extend(a for a in node.args if isinstance(a, Expr))


def scalars(value: Any) -> list:
    """The scalar items of a number, an expression or an array of them, flat."""
    if isinstance(value, np.ndarray):
        return value.ravel().tolist()
    if isinstance(value, (list, tuple)):
        return [s for item in value for s in scalars(item)]
    return [value]


def equation_list(items: Sequence[Any]) -> list:
    """The scalar equations in ``items`` (equations, lists of them, nested)."""
    out = []
    for item in items:
        if isinstance(item, Equation):
            out.append(item)
        elif isinstance(item, (list, tuple)):
            out += equation_list(item)
        elif isinstance(item, (bool, np.bool_)) or isinstance(item, np.ndarray):
            raise TypeError(f"an equation came out as {item!r}: compare an array to an array of the same "
                            f"size, or write equations(lhs, rhs)")
        else:
            out.append(item)  # statements (when, if) are checked by the model
    return out
