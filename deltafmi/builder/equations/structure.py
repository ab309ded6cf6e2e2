"""Structural analysis: matching equations to unknowns, and BLT sorting (Tarjan).

:func:`match` assigns every equation one unknown it contains (augmenting paths, Kuhn's
algorithm with a greedy start: O(E V) at worst, instant at the sizes of models); :func:`blt`
returns the strongly connected components of the matched dependency graph in evaluation order
(Tarjan's algorithm: a component is emitted after everything it depends on).
"""
from __future__ import annotations

import sys
from typing import Optional

__all__ = ["augment", "blt", "match"]


def match(incidence: list[set], n_vars: int) -> tuple[list[Optional[int]], list[Optional[int]]]:
    """(variable of each equation or None, equation of each variable or None), maximum matching."""
    eq_var: list[Optional[int]] = [None] * len(incidence)
    var_eq: list[Optional[int]] = [None] * n_vars
    for i, vs in enumerate(incidence):  # cheap start: the first free variable
        for v in sorted(vs):
            if var_eq[v] is None:
                eq_var[i], var_eq[v] = v, i
                break
    for i in range(len(incidence)):
        if eq_var[i] is None:
            augment(i, incidence, eq_var, var_eq, set(), set())
    return eq_var, var_eq


def augment(i: int, incidence: list[set], eq_var: list, var_eq: list, seen_vars: set, seen_eqs: set) -> bool:
    """An augmenting path from equation ``i`` (iterative DFS); the visited sets are left in
    ``seen_vars``/``seen_eqs`` (Pantelides' structurally singular subset when it fails)."""
    stack = [(i, iter(sorted(incidence[i])))]
    path: list[tuple[int, int]] = []
    seen_eqs.add(i)
    while stack:
        eq, it = stack[-1]
        advanced = False
        for v in it:
            if v in seen_vars:
                continue
            seen_vars.add(v)
            if var_eq[v] is None:
                path.append((eq, v))
                for e, w in path:
                    eq_var[e], var_eq[w] = w, e
                return True
            nxt = var_eq[v]
            path.append((eq, v))
            seen_eqs.add(nxt)
            stack.append((nxt, iter(sorted(incidence[nxt]))))
            advanced = True
            break
        if not advanced:
            stack.pop()
            if path:
                path.pop()
    return False


def blt(incidence: list[set], eq_var: list[int]) -> list[list[int]]:
    """The blocks (lists of equations) in evaluation order: equation i depends on equation j when
    it contains the unknown j is matched to."""
    var_eq = {v: i for i, v in enumerate(eq_var)}
    deps = [[var_eq[v] for v in sorted(vs) if var_eq.get(v, i) != i] for i, vs in enumerate(incidence)]
    index: dict[int, int] = {}
    low: dict[int, int] = {}
    on_stack: set = set()
    stack: list[int] = []
    out: list[list[int]] = []
    counter = [0]
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(incidence) + 1000))
    try:
        def visit(v: int) -> None:
            index[v] = low[v] = counter[0]
            counter[0] += 1
            stack.append(v)
            on_stack.add(v)
            for w in deps[v]:
                if w not in index:
                    visit(w)
                    low[v] = min(low[v], low[w])
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
            if low[v] == index[v]:
                block = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    block.append(w)
                    if w == v:
                        break
                out.append(sorted(block))

        for v in range(len(incidence)):
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return out
