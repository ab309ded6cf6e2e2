"""sympy expressions as the float Python that deltafmi's code generator translates to C.

Every operation is written out (``x*x`` for ``x**2``, ``1.0/x`` for ``x**-1``, ``math.sqrt``
for ``x**(1/2)``), numbers as float literals, so that the Python kernel and its C translation do
the same double operations in the same order.
"""
from __future__ import annotations

import sympy

__all__ = ["Printer"]

_FUNCTIONS = {"sin": "math.sin", "cos": "math.cos", "tan": "math.tan", "asin": "math.asin", "acos": "math.acos",
              "atan": "math.atan", "sinh": "math.sinh", "cosh": "math.cosh", "tanh": "math.tanh",
              "exp": "math.exp", "log": "math.log", "Abs": "abs", "atan2": "math.atan2"}
_RELATIONS = {"StrictLessThan": "<", "LessThan": "<=", "StrictGreaterThan": ">", "GreaterThan": ">=",
              "Equality": "==", "Unequality": "!="}


class Printer:
    """Prints sympy expressions with symbol names given by ``names`` (a dict Symbol -> code)."""

    def __init__(self, names: dict) -> None:
        self.names = names

    def __call__(self, e: sympy.Basic) -> str:
        return self.print(e)

    def print(self, e: sympy.Basic) -> str:
        if isinstance(e, sympy.Symbol):
            return self.names.get(e, e.name)
        if e is sympy.true:
            return "True"
        if e is sympy.false:
            return "False"
        if isinstance(e, sympy.Number):
            if e is sympy.nan or e.is_infinite:
                raise ValueError(f"the expression {e} is not a finite number")
            return repr(float(e)) if float(e) >= 0 else f"({float(e)!r})"
        if e is sympy.pi:
            return "math.pi"
        if e is sympy.E:
            return "math.e"
        if isinstance(e, sympy.Add):
            terms = [self.print(a) for a in e.as_ordered_terms()]
            out = terms[0]
            for t in terms[1:]:
                out = f"{out} - {t[2:-1]}" if t.startswith("(-") and _balanced(t[2:-1]) else f"{out} + {t}"
            return f"({out})"
        if isinstance(e, sympy.Mul):
            return self.mul(e)
        if isinstance(e, sympy.Pow):
            return self.pow(e.base, e.exp)
        if isinstance(e, sympy.Piecewise):
            out = None
            for value, cond in reversed(e.args):
                branch = self.print(value)
                out = branch if out is None and cond is sympy.true else \
                    f"({branch} if {self.print(cond)} else {out if out is not None else 'math.nan'})"
            return out
        if isinstance(e, sympy.And):
            return "(" + " and ".join(self.print(a) for a in e.args) + ")"
        if isinstance(e, sympy.Or):
            return "(" + " or ".join(self.print(a) for a in e.args) + ")"
        if isinstance(e, sympy.Not):
            return f"(not {self.print(e.args[0])})"
        name = type(e).__name__
        if name in _RELATIONS:
            return f"({self.print(e.args[0])} {_RELATIONS[name]} {self.print(e.args[1])})"
        if name in _FUNCTIONS:
            return f"{_FUNCTIONS[name]}({', '.join(self.print(a) for a in e.args)})"
        raise ValueError(f"no float code for {e} ({name})")

    def mul(self, e: sympy.Mul) -> str:
        coeff, factors = e.as_coeff_mul()
        numerator, denominator = [], []
        for f in factors:
            if isinstance(f, sympy.Pow) and f.exp.is_Number and f.exp < 0:
                denominator.append(self.pow(f.base, -f.exp))
            else:
                numerator.append(self.print(f))
        sign = ""
        if coeff == -1:
            sign = "-"
        elif coeff != 1:
            if coeff < 0:
                sign = "-"
            numerator.insert(0, repr(float(abs(coeff))))
        top = "*".join(numerator) if numerator else "1.0"
        out = f"{top}/({'*'.join(denominator)})" if denominator else top
        return f"({sign}{out})"

    def pow(self, base: sympy.Basic, exp: sympy.Basic) -> str:
        b = self.print(base)
        if exp.is_Integer:
            n = int(exp)
            if n == 0:
                return "1.0"
            if 0 < n <= 4:
                return "(" + "*".join([b] * n) + ")"
            if -4 <= n < 0:
                return "(1.0/(" + "*".join([b] * -n) + "))"
        if exp == sympy.Rational(1, 2):
            return f"math.sqrt({b})"
        if exp == sympy.Rational(-1, 2):
            return f"(1.0/math.sqrt({b}))"
        return f"({b} ** {self.print(exp)})"


def _balanced(text: str) -> bool:
    depth = 0
    for ch in text:
        depth += (ch == "(") - (ch == ")")
        if depth < 0:
            return False
    return depth == 0
