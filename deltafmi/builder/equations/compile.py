"""The equation compiler: a flat model -> sorted, differentiated, solved -> Python kernels.

Steps, for every mode (combination of if-equation branches):

1. residuals ``lhs - rhs`` in sympy, der() and jacobian() worked out through the definitions;
2. states: the variables whose derivative occurs; unknowns: their derivatives and the other
   variables;
3. index reduction: an equation in which no unknown occurs, once the defined variables are
   replaced by their definitions, constrains the states (``x^2 + y^2 == L^2``): it is replaced by
   its time derivative until an unknown occurs (each order kept as an invariant for the
   projection and the initialization; with ``constraint_pole`` p > 0 the last derivative is
   stabilised: ``g'' + 2 p g' + p^2 g == 0``);
4. counts, matching and BLT (:mod:`.structure`), with errors naming equations and unknowns;
5. per block: an assignment, or a torn system (explicit equations substituted, the rest linear:
   a pivoting solve; nonlinear: Newton on the tearing variables);
6. code: plain float Python (:mod:`.printer`, :mod:`.solve`) that deltafmi's code generator
   also translates to C.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any, Optional

import sympy

from deltafmi.runtime.equations.expr import Equation
from deltafmi.runtime.equations.model import EquationModelError, FlatModel, Statement, statement_text

from . import structure
from .printer import Printer
from .solve import Emitter
from .symbolic import Symbols


@dataclass
class Residual:
    expr: sympy.Expr
    where: str
    text: str


@dataclass
class Block:
    kind: str  #: "assign", "linear", "newton"
    solved: list  #: the symbols it determines
    eqs: list  #: Residual
    assignments: list = field(default_factory=list)  #: (symbol, expr) of an assign/torn part
    tear: list = field(default_factory=list)
    residuals: list = field(default_factory=list)  #: sympy residuals in the tearing variables


@dataclass
class ModeSystem:
    condition: sympy.Basic
    blocks: list
    unknowns: list
    invariants: list  #: state-level residuals that hold on the solution (position, velocity, ...)
    residuals: list  #: the final residuals (for the Jacobian)
    matched: list = field(default_factory=list)  #: the unknown (index) each residual determines


class Compiler:
    """Compiles one flat model (see the module docstring); :meth:`module_source` is the result."""

    def __init__(self, flat: FlatModel, constraint_pole: float = 0.0) -> None:
        self.flat = flat
        self.pole = float(constraint_pole)
        self.S = Symbols(flat)
        self.vars = flat.variables
        self.kind = self.S.kind
        self.plain: list[tuple[Equation, sympy.Expr, sympy.Expr]] = []
        self.branches: list[tuple[sympy.Basic, list, list, str]] = []
        self._convert()
        self._states()
        self.modes = [self._analyse(cond, eqs) for cond, eqs in self._mode_equations()]

    # ------------------------------------------------------------------ conversion
    def _convert(self) -> None:
        S = self.S
        for item in self.flat.equations:
            if isinstance(item, Equation):
                lhs, rhs = S.convert(item.lhs, item.where), S.convert(item.rhs, item.where)
                self.plain.append((item, lhs, rhs))
            elif isinstance(item, Statement) and item.kind == "if":
                cond, then, other = item.args
                c = S.convert(cond, item.where)
                bad = [s for s in c.free_symbols if self.kind.get(s) not in ("parameter", "discrete")]
                if bad:
                    raise EquationModelError(f"{item.where}: an if-equation's condition may use parameters and "
                                             f"discrete variables only, not {', '.join(map(str, bad))} (write the "
                                             f"continuous case with ifelse())")
                conv = lambda eqs: [(e, S.convert(e.lhs, e.where), S.convert(e.rhs, e.where))  # noqa: E731
                                    for e in eqs if isinstance(e, Equation)]
                self.branches.append((c, conv(then), conv(other), item.where))
            else:
                raise EquationModelError(f"{getattr(item, 'where', '?')}: {statement_text(item)} is not an equation")
        S.add_definitions(self.plain)

    def _mode_equations(self) -> list:
        if not self.branches:
            return [(sympy.true, self.plain)]
        out = []
        for choice in itertools.product((True, False), repeat=len(self.branches)):
            cond = sympy.And(*[c if take else sympy.Not(c) for (c, _, _, _), take in zip(self.branches, choice)])
            eqs = list(self.plain)
            for (c, then, other, where), take in zip(self.branches, choice):
                eqs += then if take else other
            out.append((cond, eqs))
        return out

    def _states(self) -> None:
        """States: every symbol whose derivative occurs (after expansion), in declaration order."""
        S = self.S
        self.expanded: dict[int, sympy.Expr] = {}
        seen: set = set()
        all_eqs = list(self.plain) + [e for _, t, o, _ in self.branches for e in t + o]
        for eq, lhs, rhs in all_eqs:
            r = S.expand(lhs - rhs, eq.where)
            self.expanded[id(eq)] = r
            seen |= {s for s in r.free_symbols if s in S.base_of}
        for d in list(S.defs):
            seen |= {s for s in S.definition(d, "").free_symbols if s in S.base_of}
        bases = {S.base_of[d] for d in seen}
        order = list(S.var.values()) + [S.der_of[s] for s in S.var.values() if s in S.der_of]
        self.states = [s for s in order if s in bases and s not in S.defs]
        extra = bases - set(self.states) - set(S.defs)
        self.states += sorted(extra, key=str)
        for s in self.states:
            if self.kind.get(s) != "unknown":
                raise EquationModelError(f"der({s}): {s} is a {self.kind.get(s)}, not an unknown of the model")
        self.state_set = set(self.states)

    # ------------------------------------------------------------------ analysis of one mode
    def _analyse(self, condition: sympy.Basic, eqs: list) -> ModeSystem:
        S = self.S
        unknowns = [s for name, s in S.var.items() if self.vars[name].kind in ("unknown", "output")
                    and s not in self.state_set] + [S.der_of[s] for s in self.states
                                                    if S.der_of[s] not in self.state_set]
        unknowns += [d for d in S.base_of if d not in unknowns and d not in self.state_set
                     and any(d in self.expanded.get(id(e), sympy.S.Zero).free_symbols for e, _, _ in eqs)]
        uset = set(unknowns)
        residuals, invariants = [], []
        for eq, lhs, rhs in eqs:
            r = self.expanded.get(id(eq))
            if r is None:
                r = S.expand(lhs - rhs, eq.where)
            text = statement_text(eq)
            chain = []
            for _ in range(4):
                full = S.substitute(r, eq.where)
                if full.free_symbols & uset:
                    break
                if full.free_symbols - {s for s in full.free_symbols if self.kind.get(s) in ("parameter", "discrete")}:
                    chain.append(full)
                    r = S.dt(full, eq.where)
                else:
                    break
            else:
                states = sorted({str(x) for g in chain for x in g.free_symbols if x in self.state_set})
                raise EquationModelError(f"{eq.where}: {text}: over-determined: it constrains [{', '.join(states)}], "
                                         f"which the other equations determine already (three time derivatives of "
                                         f"it hold no unknown)")
            if chain:
                invariants += chain
                if self.pole > 0.0:
                    p = sympy.Float(self.pole)
                    weights = [p ** 2, 2 * p] if len(chain) == 2 else [p]
                    r = r + sum(w * g for w, g in zip(weights, chain))
                text = f"d^{len(chain)}/dt^{len(chain)} ({text})"
            residuals.append(Residual(r, eq.where, text))
        self._check_counts(residuals, unknowns, condition)
        index = {s: k for k, s in enumerate(unknowns)}
        incidence = [{index[s] for s in r.expr.free_symbols if s in index} for r in residuals]
        eq_var, var_eq = structure.match(incidence, len(unknowns))
        self._check_matching(residuals, unknowns, incidence, eq_var, var_eq)
        blocks = []
        for block in structure.blt(incidence, eq_var):
            blocks.append(self._block([residuals[i] for i in block], [unknowns[eq_var[i]] for i in block]))
        return ModeSystem(condition, blocks, unknowns, invariants, residuals, list(eq_var))

    def _check_counts(self, residuals: list, unknowns: list, condition: Any) -> None:
        if len(residuals) == len(unknowns):
            return
        mode = "" if condition is sympy.true else f" (where {condition})"
        index = {s: k for k, s in enumerate(unknowns)}
        incidence = [{index[s] for s in r.expr.free_symbols if s in index} for r in residuals]
        eq_var, var_eq = structure.match(incidence, len(unknowns))
        if len(residuals) > len(unknowns):
            extra = [f"{residuals[i].where}: {residuals[i].text}" for i, v in enumerate(eq_var) if v is None]
            raise EquationModelError(f"{self.flat.name}{mode}: over-determined: {len(residuals)} equations for "
                                     f"{len(unknowns)} unknowns; no unknown is left for [{'; '.join(extra)}]")
        missing = [str(unknowns[v]) for v, e in enumerate(var_eq) if e is None]
        raise EquationModelError(f"{self.flat.name}{mode}: under-determined: {len(residuals)} equations for "
                                 f"{len(unknowns)} unknowns; no equation determines [{', '.join(missing)}]")

    def _check_matching(self, residuals: list, unknowns: list, incidence: list, eq_var: list, var_eq: list) -> None:
        free = [i for i, v in enumerate(eq_var) if v is None]
        if not free:
            return
        seen_vars: set = set()
        seen_eqs: set = set()
        structure.augment(free[0], incidence, list(eq_var), list(var_eq), seen_vars, seen_eqs)
        eqs = "; ".join(f"{residuals[i].where}: {residuals[i].text}" for i in sorted(seen_eqs))
        names = ", ".join(str(unknowns[v]) for v in sorted(seen_vars)) or "none"
        lonely = [str(unknowns[v]) for v, e in enumerate(var_eq) if e is None]
        raise EquationModelError(f"{self.flat.name}: structurally singular: the {len(seen_eqs)} equations [{eqs}] "
                                 f"determine only the {len(seen_vars)} unknowns [{names}]; no equation is left "
                                 f"for [{', '.join(lonely)}]")

    def _block(self, eqs: list, solved: list) -> Block:
        if len(eqs) == 1:
            r, s = eqs[0].expr, solved[0]
            coeff = sympy.diff(r, s)
            if s not in coeff.free_symbols and coeff != 0:
                return Block("assign", solved, eqs, assignments=[(s, _solve_linear(r, s, coeff))])
            return Block("newton", solved, eqs, tear=[s], residuals=[r])
        current = {s: e.expr for s, e in zip(solved, eqs)}
        assignments: list = []
        remaining = list(solved)
        for strict in (True, False):
            progress = True
            while progress:
                progress = False
                for s in list(remaining):
                    r = current[s]
                    coeff = sympy.diff(r, s)
                    if s in coeff.free_symbols or coeff == 0:
                        continue
                    if strict and not coeff.is_Number:
                        continue
                    if not strict and any(self.kind.get(x) != "parameter" for x in coeff.free_symbols):
                        continue  # a coefficient that states change may pass through zero: pivot instead
                    value = _solve_linear(r, s, coeff)
                    remaining.remove(s)
                    del current[s]
                    for other in remaining:
                        current[other] = current[other].xreplace({s: value})
                    assignments = [(a, e.xreplace({s: value})) for a, e in assignments] + [(s, value)]
                    progress = True
                    if len(remaining) == 1:
                        break
                if len(remaining) <= 1:
                    break
        # then any equation that gives any remaining unknown with a constant coefficient (the
        # matching paired them otherwise: z + a y^3 = c gives z even where z was matched elsewhere)
        rows = [current[s] for s in remaining]
        found = True
        while found and len(remaining) > 1:
            found = False
            for i, r in enumerate(rows):
                for s in remaining:
                    coeff = sympy.diff(r, s)
                    if coeff.is_Number and coeff != 0:
                        value = _solve_linear(r, s, coeff)
                        remaining.remove(s)
                        rows = [x.xreplace({s: value}) for k, x in enumerate(rows) if k != i]
                        assignments = [(a, e.xreplace({s: value})) for a, e in assignments] + [(s, value)]
                        found = True
                        break
                if found:
                    break
        tear = remaining
        # rows ordered so that row k holds tearing variable k (a structurally nonzero diagonal)
        column = {t: k for k, t in enumerate(tear)}
        eq_var, _ = structure.match([{column[x] for x in r.free_symbols if x in column} for r in rows], len(tear))
        order = sorted(range(len(rows)), key=lambda i: eq_var[i] if eq_var[i] is not None else len(rows))
        residuals = [rows[i] for i in order]
        linear = all(not (sympy.diff(r, t).free_symbols & set(tear)) for r in residuals for t in tear)
        return Block("linear" if linear else "newton", solved, eqs, assignments=assignments, tear=tear,
                     residuals=residuals)


def _solve_linear(r: sympy.Expr, s: sympy.Symbol, coeff: sympy.Expr) -> sympy.Expr:
    return -r.xreplace({s: sympy.Integer(0)}) / coeff


# ---------------------------------------------------------------------- code generation


class ModuleWriter:
    """Writes the generated Python module of a compiled model."""

    def __init__(self, compiler: Compiler, module_name: str) -> None:
        self.c = compiler
        self.S = compiler.S
        self.module_name = module_name
        flat = compiler.flat
        self.params = _groups(flat, "parameter")
        self.inputs = _groups(flat, "input")
        self.discrete = [v for v in flat.variables.values() if v.kind == "discrete"]
        self.outputs = _groups(flat, "output")
        self.names: dict = {self.S.time: "t"}
        for k, s in enumerate(compiler.states):
            self.names[s] = f"x[{k}]"
        for prefix, groups in (("p_", self.params), ("u_", self.inputs)):
            for group, members in groups.items():
                for v in members:
                    ident = prefix + _ident(group)
                    self.names[self.S.var[v.name]] = ident if v.index is None else f"{ident}[{v.index}]"
        for k, v in enumerate(self.discrete):
            self.names[self.S.var[v.name]] = f"d[{k}]"
        # a model without states takes no state vector (an empty sequence has no C type)
        self.args = ["t"] + (["x"] if compiler.states else []) + ["u_" + _ident(g) for g in self.inputs] \
            + ["p_" + _ident(g) for g in self.params]
        if self.discrete:
            self.args.append("d")
        self.relations: list = []  # (sympy relation, indicator expr)
        self.functions: list[str] = []

    # -- kernels
    def kernel(self, name: str, targets: list, doc: str, extra: Optional[list] = None) -> None:
        """A kernel returning ``targets`` (sympy expressions of the model's symbols)."""
        lines = [f"def {name}({', '.join(self._typed_args())}):", f'    """{doc}"""']
        modes = self.c.modes
        printer_names = dict(self.names)
        for k, mode in enumerate(modes):
            body = self._mode_body(mode, targets, k)
            if len(modes) == 1:
                lines += body
            else:
                cond = Printer(printer_names)(mode.condition)
                lines.append(f"    {'if' if k == 0 else 'elif'} {cond}:" if k < len(modes) - 1 else "    else:")
                lines += ["    " + line for line in body]
        self.functions.append("\n".join(lines))

    def _typed_args(self) -> list[str]:
        out = []
        for a in self.args:
            out.append(f"{a}: float" if a == "t" else a)
        return out

    def _mode_body(self, mode: ModeSystem, targets: list, k: int) -> list[str]:
        needed = set().union(*[sympy.sympify(t).free_symbols for t in targets]) if targets else set()
        em = Emitter(self.names, prefix=f"m{k}c")
        for block in _needed_blocks(mode.blocks, needed):
            if block.kind == "linear":
                self._linear(em, block)
            elif block.kind == "newton":
                self._newton(em, block)
            for s, e in block.assignments:
                em.define(s, e)
        results = []
        for t in targets:
            results.append(em.fresh("out"))
            em.assign(results[-1], sympy.sympify(t))
        body = em.body()
        body.append(f"    return ({', '.join(results)}{',' if len(results) == 1 else ''})")
        return body

    def _linear(self, em: Emitter, block: Block) -> None:
        """A linear torn block: ``A x = b`` as a dense pivoting solve, or by block elimination
        (Schur complement) where the structure makes that cheaper (see :func:`_schur_plan`)."""
        tear, n = block.tear, len(block.tear)
        zero = {t: sympy.Integer(0) for t in tear}
        entries = {}
        for i, r in enumerate(block.residuals):
            for j, t in enumerate(tear):
                entry = sympy.diff(r, t)
                if entry != 0:
                    entries[(i, j)] = entry
        A = {}
        for key, entry in entries.items():
            A[key] = em.fresh("A")
            em.assign(A[key], entry)
        b = []
        for r in block.residuals:
            b.append(em.fresh("B"))
            em.assign(b[-1], -r.xreplace(zero))
        em.flush()
        what = ", ".join(str(t) for t in tear)
        plan = _schur_plan(n, set(entries), [self._group(t) for t in tear])
        x = em.linear_solve(A, b, n, what) if plan is None else _emit_schur(em, plan, A, b, n, what)
        for t, name in zip(tear, x):
            em.names[t] = name

    def _group(self, s: sympy.Symbol) -> str:
        base = self.S.base_of.get(s)
        if base is not None:
            return "der(" + self._group(base) + ")"
        v = self.c.vars.get(s.name)
        return v.group if v is not None else s.name

    def _newton(self, em: Emitter, block: Block) -> None:
        n = len(block.tear)
        names = []
        for t in block.tear:
            v = self.vars_start(t)
            name = em.fresh("N")
            em.line(f"{name} = {float(v)!r}")
            em.names[t] = name
            names.append(name)
        it = em.fresh("it")
        em.line(f"{it} = 0")
        em.line(f"while {it} < 50:")
        em.indent += 1
        A, b = {}, []
        for i, r in enumerate(block.residuals):
            for j, t in enumerate(block.tear):
                entry = sympy.diff(r, t)
                if entry != 0:
                    A[(i, j)] = em.fresh("J")
                    em.assign(A[(i, j)], entry)
            b.append(em.fresh("F"))
            em.assign(b[-1], -r)
        em.flush()
        dx = em.linear_solve(A, b, n, "Newton step of " + ", ".join(str(t) for t in block.tear))
        for name, d in zip(names, dx):
            em.line(f"{name} = {name} + {d}")
        small = " and ".join(f"abs({d}) <= 1e-13 * (1.0 + abs({name}))" for name, d in zip(names, dx))
        em.line(f"if {small}:")
        em.line("    break")
        em.line(f"{it} = {it} + 1")
        em.indent -= 1
        em.line(f"if {it} >= 50:")
        em.line(f"    raise ArithmeticError('Newton did not converge: {', '.join(str(t) for t in block.tear)}')")

    def vars_start(self, s: sympy.Symbol) -> float:
        v = self.c.vars.get(s.name)
        return float(v.start) if v is not None and isinstance(v.start, (int, float)) else 0.0

    def python_function(self, name: str, exprs: list, doc: str, args: Optional[list] = None) -> None:
        """A Python-only function of the knowns (cse'd), returning a list."""
        em = Emitter(self.names, prefix="q")
        results = []
        for e in exprs:
            results.append(em.fresh("out"))
            em.assign(results[-1], e)
        body = em.body()
        self.functions.append("\n".join([f"def {name}({', '.join(args or self.args)}):", f'    """{doc}"""',
                                         *body, f"    return [{', '.join(results)}]"]))


def _schur_plan(n: int, struct: set, groups: list) -> Optional[tuple]:
    """Block elimination for a sparse linear system: with the unknowns of one declaration (a
    multiplier ``lambda[6]``) as the inner tearing set C2, the other rows and unknowns fall into
    small blocks (each arm's mass matrix) solved for their dependence on C2, and C2 solves the
    small dense Schur complement. Returns (blocks [(rows, cols)], residual rows, C2) for the
    cheapest such choice, or None when a dense solve costs less."""
    best, best_cost = None, (n ** 3) / 3.0 * 2.0  # the dense pivoting solve (its swaps count too)
    for group in dict.fromkeys(groups):
        c2 = [j for j in range(n) if groups[j] == group]
        c1 = [j for j in range(n) if groups[j] != group]
        if not c1 or len(c2) > n // 2:
            continue
        rows = sorted(range(n), key=lambda i: not any((i, t) in struct for t in c2))
        c1_index = {j: k for k, j in enumerate(c1)}
        incidence = [{c1_index[j] for j in c1 if (i, j) in struct} for i in rows]
        eq_var, var_eq = structure.match(incidence, len(c1))
        if any(e is None for e in var_eq):
            continue
        matched = [k for k, v in enumerate(eq_var) if v is not None]
        residual_rows = [rows[k] for k, v in enumerate(eq_var) if v is None]
        sub = [incidence[k] for k in matched]
        sub_var = [eq_var[k] for k in matched]
        blocks = []
        for blk in structure.blt(sub, sub_var):
            blocks.append(([rows[matched[k]] for k in blk], [c1[sub_var[k]] for k in blk]))
        if max(len(r) for r, _ in blocks) > 6:
            continue
        reach: dict = {}
        cost = len(c2) ** 3 / 3.0 * 2.0
        for brows, bcols in blocks:
            cols = {t for i in brows for t in c2 if (i, t) in struct}
            cols |= {t for i in brows for j in c1 if (i, j) in struct and j not in bcols for t in reach.get(j, ())}
            for j in bcols:
                reach[j] = cols
            size = len(brows)
            cost += size ** 3 / 3.0 * 2.0 + size * size * (1 + len(cols))
        cost += sum(len(reach[j]) for i in residual_rows for j in c1 if (i, j) in struct)
        if cost < best_cost:
            best, best_cost = (blocks, residual_rows, c2), cost
    return best


def _emit_schur(em: Emitter, plan: tuple, A: dict, b: list, n: int, what: str) -> list[str]:
    """The code of :func:`_schur_plan`'s block elimination; the solution's names by column."""
    blocks, residual_rows, c2 = plan
    c_of: dict = {}  # column in C1 -> name of its part independent of C2
    d_of: dict = {}  # (column in C1, column in C2) -> name of its coefficient
    solved: set = set()
    for brows, bcols in blocks:
        local = {j: k for k, j in enumerate(bcols)}
        s = len(bcols)
        rhs_cols = sorted({t for i in brows for t in c2 if (i, t) in A}
                          | {t for i in brows for j in solved if (i, j) in A for (jj, t) in d_of if jj == j})
        aug = {}
        for r, i in enumerate(brows):
            for j in bcols:
                if (i, j) in A:
                    aug[(r, local[j])] = A[(i, j)]
            terms = [f" - {A[(i, j)]} * {c_of[j]}" for j in sorted(solved) if (i, j) in A and c_of.get(j)]
            name = em.fresh("R")
            em.line(f"{name} = {b[i]}{''.join(terms)}")
            aug[(r, s)] = name
            for k, t in enumerate(rhs_cols):
                parts = ([A[(i, t)]] if (i, t) in A else []) + [f"{A[(i, j)]} * {d_of[(j, t)]}" for j in sorted(solved)
                                                               if (i, j) in A and (j, t) in d_of]
                if parts:
                    name = em.fresh("R")
                    em.line(f"{name} = -({' + '.join(parts)})")
                    aug[(r, s + 1 + k)] = name
        X = em.solve_augmented(aug, s, 1 + len(rhs_cols), what)
        for j in bcols:
            c_of[j] = X[0][local[j]]
            for k, t in enumerate(rhs_cols):
                if X[1 + k][local[j]]:
                    d_of[(j, t)] = X[1 + k][local[j]]
        solved |= set(bcols)
    S, rhs = {}, []
    for r, i in enumerate(residual_rows):
        for k, t in enumerate(c2):
            parts = ([A[(i, t)]] if (i, t) in A else []) + [f"{A[(i, j)]} * {d_of[(j, t)]}" for j in sorted(solved)
                                                           if (i, j) in A and (j, t) in d_of]
            if parts:
                S[(r, k)] = em.fresh("S")
                em.line(f"{S[(r, k)]} = {' + '.join(parts)}")
        terms = [f" - {A[(i, j)]} * {c_of[j]}" for j in sorted(solved) if (i, j) in A and c_of.get(j)]
        rhs.append(em.fresh("R"))
        em.line(f"{rhs[-1]} = {b[i]}{''.join(terms)}")
    t2 = em.linear_solve(S, rhs, len(c2), what)
    x = ["0.0"] * n
    for k, t in enumerate(c2):
        x[t] = t2[k]
    for j in solved:
        parts = ([c_of[j]] if c_of.get(j) else []) + [f"{d_of[(j, t)]} * {t2[k]}" for k, t in enumerate(c2)
                                                       if (j, t) in d_of]
        name = em.fresh("X")
        em.line(f"{name} = {' + '.join(parts) or '0.0'}")
        x[j] = name
    return x


def _needed_blocks(blocks: list, needed: set) -> list:
    """The blocks that compute ``needed`` (and what they need), in order."""
    want = set(needed)
    keep = []
    for block in reversed(blocks):
        if set(block.solved) & want:
            keep.append(block)
            for e in block.eqs:
                want |= e.expr.free_symbols
    return list(reversed(keep))


def _groups(flat: FlatModel, kind: str) -> dict:
    out: dict = {}
    for v in flat.variables.values():
        if v.kind == kind:
            out.setdefault(v.group, []).append(v)
    return out


def _ident(name: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in name)


__all__ = ["Compiler", "ModuleWriter", "EquationModelError"]
