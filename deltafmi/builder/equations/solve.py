"""Straight-line float code for the blocks of a sorted system: assignments and linear solves.

:class:`Emitter` collects sympy assignments in stages (one ``sympy.cse`` per stage, so that a
subexpression is computed once) and writes a dense linear solve with partial pivoting as
unrolled code over scalar variables: the code generator's lists have no item assignment, and at
the sizes of models' blocks (up to a few dozen unknowns) unrolled code with the structural zeros
left out is what a C compiler optimises best. Row swaps happen where a later row has the larger
pivot candidate, so the solve is as stable as LU with partial pivoting; an exactly zero pivot
raises ``ArithmeticError`` (a singular system at that point).
"""
from __future__ import annotations

import sympy

from .printer import Printer

__all__ = ["Emitter"]


class Emitter:
    """Lines of a kernel body, with the code names of the symbols assigned so far."""

    def __init__(self, names: dict, prefix: str = "c") -> None:
        self.names = dict(names)
        self.lines: list[str] = []
        self.stage: list[tuple[str, sympy.Expr]] = []
        self.pending: dict = {}  # symbols solved by assignments, inlined into what uses them
        self.indent = 1
        self.counter = 0
        self.prefix = prefix

    def fresh(self, base: str) -> str:
        self.counter += 1
        return f"{base}{self.counter}"

    def line(self, text: str) -> None:
        self.lines.append("    " * self.indent + text)

    def define(self, symbol: sympy.Symbol, expr: sympy.Expr) -> None:
        """``symbol`` is ``expr``: inlined where it is used (common subexpressions are shared by cse)."""
        self.pending[symbol] = sympy.sympify(expr).xreplace(self.pending)

    def assign(self, name: str, expr: sympy.Expr) -> None:
        """``name = expr`` in the current stage."""
        self.stage.append((name, sympy.sympify(expr).xreplace(self.pending)))

    def flush(self) -> None:
        """Write the stage's assignments, common subexpressions first."""
        if not self.stage:
            return
        exprs = [sympy.sympify(e) for _, e in self.stage]
        tag = self.fresh(self.prefix) + "_"
        replacements, reduced = sympy.cse(exprs, symbols=sympy.numbered_symbols(tag), order="none")
        printer = Printer(self.names)
        for sym, value in replacements:
            self.line(f"{sym.name} = {printer(value)}")
        for (name, _), value in zip(self.stage, reduced):
            self.line(f"{name} = {printer(value)}")
        self.stage = []

    def linear_solve(self, A: dict, b: list, n: int, what: str) -> list[str]:
        """Solve ``A x = b`` (``A``: (row, col) -> code name of a structurally nonzero entry,
        ``b``: code names); returns the code names of x."""
        augmented = dict(A)
        augmented.update({(i, n): name for i, name in enumerate(b)})
        return [x or "0.0" for x in self.solve_augmented(augmented, n, 1, what)[0]]

    def solve_augmented(self, A: dict, n: int, m: int, what: str) -> list[list]:
        """Solve ``A[:, :n] X = A[:, n:n+m]`` for m right-hand sides (entries: (row, col) -> code
        name, structural zeros absent): LU with partial pivoting over the structurally nonzero
        candidates of each column, row swaps where a later row's entry is larger. Returns X by
        column, None for structurally zero entries."""
        tag = self.fresh("L")
        a = {key: f"{tag}a{key[0]}_{key[1]}" for key in A}
        for key, name in A.items():
            self.line(f"{a[key]} = {name}")
        struct = set(A)
        width = n + m

        def entry(i: int, j: int) -> str:
            if (i, j) not in a:
                a[(i, j)] = f"{tag}a{i}_{j}"
                self.line(f"{a[(i, j)]} = 0.0")
                struct.add((i, j))
            return a[(i, j)]

        for k in range(n):
            candidates = [i for i in range(k + 1, n) if (i, k) in struct]
            for i in candidates:
                cols = sorted({j for j in range(k, width) if (k, j) in struct or (i, j) in struct})
                left = [entry(k, j) for j in cols]
                right = [entry(i, j) for j in cols]
                self.line(f"if abs({a[(i, k)]}) > abs({entry(k, k)}):")
                self.line(f"    {', '.join(left + right)} = {', '.join(right + left)}")
            pivot = entry(k, k)
            self.line(f"if {pivot} == 0.0:")
            self.line(f"    raise ArithmeticError('singular linear system: {what}')")
            row_k = sorted(j for j in range(k + 1, width) if (k, j) in struct)
            for i in candidates:
                factor = f"{tag}f{i}_{k}"
                self.line(f"{factor} = {a[(i, k)]} / {pivot}")
                for j in row_k:
                    target = entry(i, j)
                    self.line(f"{target} = {target} - {factor} * {a[(k, j)]}")
        out = []
        for c in range(m):
            x: list = [None] * n
            for k in reversed(range(n)):
                terms = [f" - {a[(k, j)]} * {x[j]}" for j in range(k + 1, n) if (k, j) in struct and x[j]]
                if (k, n + c) not in struct and not terms:
                    continue
                x[k] = f"{tag}x{k}_{c}"
                self.line(f"{x[k]} = ({a[(k, n + c)] if (k, n + c) in struct else '0.0'}{''.join(terms)}) / "
                          f"{a[(k, k)]}")
            out.append(x)
        return out

    def body(self) -> list[str]:
        self.flush()
        return self.lines

