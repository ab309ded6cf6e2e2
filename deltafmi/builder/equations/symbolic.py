"""A flat equation model in sympy: symbols, definitions, time derivatives through definitions.

``der(w)`` of a variable that an equation ``w == e`` (``w`` alone on the left) defines is the time
derivative of ``e``, taken symbolically with the chain rule (the seed's ``h1 = der(h0)``); of any
other unknown it is that unknown's derivative, which makes it a state. ``jacobian(f, x)`` is the
partial derivative of ``f``, again through the definitions. Parameters and discrete variables are
constant between events; the derivative of an input is an error.
"""
from __future__ import annotations

from typing import Any

import sympy

from deltafmi.runtime.equations.expr import Equation, Expr, Var, text
from deltafmi.runtime.equations.model import EquationModelError, FlatModel, Statement

_FUNCS = {"sin": sympy.sin, "cos": sympy.cos, "tan": sympy.tan, "asin": sympy.asin, "acos": sympy.acos,
          "atan": sympy.atan, "sinh": sympy.sinh, "cosh": sympy.cosh, "tanh": sympy.tanh, "exp": sympy.exp,
          "log": sympy.log, "sqrt": sympy.sqrt, "abs": sympy.Abs}


class _RawDer(sympy.Function):
    """der() of an expression, expanded once the definitions are known."""


class _RawDiff(sympy.Function):
    """d f / d x of jacobian(), expanded once the definitions are known."""


class _Pre(sympy.Function):
    """pre() of an expression at an event."""


class _Edge(sympy.logic.boolalg.BooleanFunction):
    """edge() of a condition at an event."""


class Symbols:
    """The sympy side of a flat model: one symbol per scalar, der() and pre() symbols on demand."""

    def __init__(self, flat: FlatModel) -> None:
        self.flat = flat
        self.var: dict[str, sympy.Symbol] = {}
        self.kind: dict[sympy.Symbol, str] = {}
        for v in flat.variables.values():
            s = sympy.Symbol(v.name, real=True)
            self.var[v.name] = s
            self.kind[s] = "unknown" if v.kind == "output" else v.kind
        self.time = sympy.Symbol("time", real=True)
        self.kind[self.time] = "time"
        self.der_of: dict[sympy.Symbol, sympy.Symbol] = {}  # x -> der(x)
        self.base_of: dict[sympy.Symbol, sympy.Symbol] = {}  # der(x) -> x
        self.pre_of: dict[sympy.Symbol, sympy.Symbol] = {}
        self.defs: dict[sympy.Symbol, sympy.Expr] = {}
        self.def_where: dict[sympy.Symbol, str] = {}
        self._dt: dict = {}
        self._expanding: set = set()

    # ---------------------------------------------------------------- conversion
    def der(self, s: sympy.Symbol) -> sympy.Symbol:
        if s not in self.der_of:
            d = sympy.Symbol(f"der({s.name})", real=True)
            self.der_of[s], self.base_of[d] = d, s
            self.kind[d] = "unknown"
        return self.der_of[s]

    def pre(self, s: sympy.Symbol) -> sympy.Symbol:
        if s not in self.pre_of:
            p = sympy.Symbol(f"pre({s.name})", real=True)
            self.pre_of[s] = p
            self.kind[p] = "pre"
        return self.pre_of[s]

    def convert(self, e: Any, where: str = "") -> sympy.Expr:
        if not isinstance(e, Expr):
            return sympy.Float(float(e)) if not float(e).is_integer() else sympy.Integer(int(e))
        if isinstance(e, Var):
            if e.kind == "time":
                return self.time
            return self.var[e.name]
        op, args = e.op, e.args
        c = lambda a: self.convert(a, where)  # noqa: E731
        if op == "const":
            value = float(args[0])
            return sympy.Integer(int(value)) if value.is_integer() else sympy.Float(value)
        if op == "add":
            return c(args[0]) + c(args[1])
        if op == "sub":
            return c(args[0]) - c(args[1])
        if op == "mul":
            return c(args[0]) * c(args[1])
        if op == "div":
            return c(args[0]) / c(args[1])
        if op == "pow":
            return c(args[0]) ** c(args[1])
        if op == "neg":
            return -c(args[0])
        if op == "call":
            return _FUNCS[args[1]](c(args[0]))
        if op == "atan2":
            return sympy.atan2(c(args[0]), c(args[1]))
        if op == "der":
            inner = c(args[0])
            if isinstance(inner, sympy.Symbol) and self.kind.get(inner) == "input":
                raise EquationModelError(f"{where}: der({inner}) of an input: inputs are not differentiated")
            return self.der(inner) if isinstance(inner, sympy.Symbol) else _RawDer(inner)
        if op == "pre":
            inner = c(args[0])
            return self.pre(inner) if isinstance(inner, sympy.Symbol) else _Pre(inner)
        if op == "edge":
            return _Edge(c(args[0]))
        if op == "diff":
            return _RawDiff(c(args[0]), c(args[1]))
        if op in ("lt", "le", "gt", "ge", "eq", "ne"):
            a, b = c(args[0]), c(args[1])
            return {"lt": sympy.StrictLessThan, "le": sympy.LessThan, "gt": sympy.StrictGreaterThan,
                    "ge": sympy.GreaterThan, "eq": sympy.Eq, "ne": sympy.Ne}[op](a, b, evaluate=False)
        if op == "and":
            return sympy.And(_bool(c(args[0])), _bool(c(args[1])))
        if op == "or":
            return sympy.Or(_bool(c(args[0])), _bool(c(args[1])))
        if op == "not":
            return sympy.Not(_bool(c(args[0])))
        if op == "if":
            return sympy.Piecewise((c(args[1]), _bool(c(args[0]))), (c(args[2]), True))
        raise EquationModelError(f"{where}: cannot translate {text(e)}")

    # ---------------------------------------------------------------- definitions and derivatives
    def add_definitions(self, items: list) -> None:
        """The definitions of a list of (equation, lhs, rhs): first every ``w == e`` with ``w``
        alone on the left (``der(x) == v`` defines der(x)); then an equation ``w == der(x)`` whose
        ``x`` nothing defines makes ``w`` the derivative of ``x`` (``der(x) := w``: ``w`` is the
        state then, as a Modelica tool selects it, not der(x)); then aliases ``a == b``."""
        rest = []
        for eq, lhs, rhs in items:
            if isinstance(rhs, sympy.Symbol) and rhs in self.base_of and isinstance(lhs, sympy.Symbol) \
                    and self.kind.get(lhs) == "unknown":
                rest.append((eq, lhs, rhs))
                continue
            self.add_definition(eq, lhs, rhs)
        for eq, lhs, rhs in rest:
            base = self.base_of[rhs]
            if base not in self.defs and rhs not in self.defs and not self._depends(lhs, rhs):
                self.defs[rhs] = lhs
                self.def_where[rhs] = eq.where
            else:
                self.add_definition(eq, lhs, rhs)

    def add_definition(self, eq: Equation, lhs: sympy.Expr, rhs: sympy.Expr) -> None:
        """``lhs == rhs`` with lhs a lone unknown (or der() of one) defines it, if nothing did before."""
        if isinstance(lhs, sympy.Symbol) and self.kind.get(lhs) == "unknown" and lhs not in self.defs \
                and lhs not in rhs.free_symbols:
            self.defs[lhs] = rhs
            self.def_where[lhs] = eq.where
        elif isinstance(rhs, sympy.Symbol) and isinstance(lhs, sympy.Symbol) and self.kind.get(rhs) == "unknown" \
                and rhs not in self.defs and lhs != rhs and not self._depends(lhs, rhs):
            self.defs[rhs] = lhs  # an alias a == b whose a is defined already defines b
            self.def_where[rhs] = eq.where

    def _depends(self, s: sympy.Symbol, on: sympy.Symbol) -> bool:
        """Whether the definition of ``s`` reaches ``on`` (an alias the other way would be circular)."""
        seen, todo = set(), [s]
        while todo:
            x = todo.pop()
            if x == on:
                return True
            if x in seen or x not in self.defs:
                continue
            seen.add(x)
            todo += list(self.defs[x].free_symbols)
        return False

    def expand(self, e: sympy.Expr, where: str = "") -> sympy.Expr:
        """``e`` with every raw der(), jacobian() and der() of a defined variable worked out."""
        if not isinstance(e, sympy.Basic) or e.is_Atom and not isinstance(e, sympy.Symbol):
            return e
        replacements = {}
        for f in e.atoms(_RawDer, _RawDiff):
            if isinstance(f, _RawDer):
                replacements[f] = self.dt(self.expand(f.args[0], where), where)
            else:
                replacements[f] = self.partial(self.expand(f.args[0], where), f.args[1], where)
        for s in e.free_symbols:
            base = self.base_of.get(s)
            if base is not None and base in self.defs:
                replacements[s] = self.dt(self.definition(base, where), where)
        return e.xreplace(replacements) if replacements else e

    def definition(self, s: sympy.Symbol, where: str) -> sympy.Expr:
        if s in self._expanding:
            raise EquationModelError(f"{where}: the definitions of {s} are circular "
                                     f"({', '.join(str(x) for x in self._expanding)})")
        self._expanding.add(s)
        try:
            value = self.expand(self.defs[s], self.def_where.get(s, where))
        finally:
            self._expanding.discard(s)
        self.defs[s] = value
        return value

    def dt(self, e: sympy.Expr, where: str = "") -> sympy.Expr:
        """The total time derivative of ``e`` (its symbols through their definitions)."""
        key = e
        if key in self._dt:
            return self._dt[key]
        out = sympy.Integer(0)
        for s in e.free_symbols:
            kind = self.kind.get(s)
            if kind in ("parameter", "discrete", "pre"):
                continue
            if kind == "input":
                raise EquationModelError(f"{where}: differentiating {e} needs der({s}) of an input")
            ds = sympy.Integer(1) if kind == "time" else self.dt_symbol(s, where)
            partial = sympy.diff(e, s)
            if partial != 0:
                out += partial * ds
        self._dt[key] = out
        return out

    def dt_symbol(self, s: sympy.Symbol, where: str) -> sympy.Expr:
        if s in self.defs:
            return self.dt(self.definition(s, where), where)
        return self.der(s)

    def partial(self, f: sympy.Expr, x: sympy.Symbol, where: str) -> sympy.Expr:
        """d f / d x with the variables of ``f`` replaced by their definitions until ``x`` shows."""
        full = self.substitute(f, where, keep={x})
        return sympy.diff(full, x)

    def substitute(self, e: sympy.Expr, where: str, keep: set = frozenset()) -> sympy.Expr:
        """``e`` with every defined unknown replaced by its definition (recursively)."""
        for _ in range(100):
            found = {s: self.definition(s, where) for s in e.free_symbols if s in self.defs and s not in keep}
            if not found:
                return e
            e = e.xreplace(found)
        raise EquationModelError(f"{where}: the definitions nest more than 100 deep")


def _bool(e: sympy.Basic) -> sympy.Basic:
    if isinstance(e, (sympy.logic.boolalg.Boolean, _Edge)):
        return e
    return sympy.Ne(e, 0, evaluate=False)


def statement_where(item: Any) -> str:
    return getattr(item, "where", "") or ""


__all__ = ["Symbols", "Statement", "statement_where"]
