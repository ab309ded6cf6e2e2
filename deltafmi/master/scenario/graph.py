"""Dependency graphs of a connected system: stepping order, initialization order, algebraic loops
and how to tear them.

Pure graph logic, no FMI: a *link* is ``(source "comp.out", target "comp.in")`` and
*feedthrough* maps ``comp -> {output: {inputs it depends on directly}}``.
"""
from __future__ import annotations

import itertools
from typing import Callable, Dict, Iterable, List, Mapping, Optional, Sequence, Set, Tuple

__all__ = ["block_stepping_order", "initialization_order", "loop_groups", "stepping_order", "strongly_connected",
           "tear"]

Link = Tuple[str, str]
Feedthrough = Mapping[str, Mapping[str, Set[str]]]


def component_of(reference: str) -> str:
    """``"plant.y[1]"`` -> ``"plant"``."""
    return reference.split(".", 1)[0]


def variable_of(reference: str) -> str:
    """``"plant.y[1]"`` -> ``"y[1]"``."""
    return reference.split(".", 1)[1]


def variable_graph(links: Iterable[Link], feedthrough: Feedthrough) -> Dict[str, List[str]]:
    """Edges output -> input (connections) and input -> output (direct feedthrough in a component)."""
    links = list(links)
    graph: Dict[str, List[str]] = {}
    sources = {s for s, _ in links}
    for source, target in links:
        graph.setdefault(source, []).append(target)
        graph.setdefault(target, [])
    for source in sources:
        comp, out = component_of(source), variable_of(source)
        for inp in sorted(feedthrough.get(comp, {}).get(out, ())):
            node = f"{comp}.{inp}"
            if node in graph:
                graph[node].append(source)
    return graph


def strongly_connected(graph: Mapping[str, Sequence[str]]) -> List[List[str]]:
    """Tarjan's strongly connected components (iterative), in reverse topological order."""
    index: Dict[str, int] = {}
    low: Dict[str, int] = {}
    on_stack: Set[str] = set()
    stack: List[str] = []
    result: List[List[str]] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(graph.get(root, ())))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            advanced = False
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(graph.get(child, ()))))
                    advanced = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if advanced:
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                members = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    members.append(member)
                    if member == node:
                        break
                result.append(members)
    return result


def initialization_order(links: Sequence[Link], feedthrough: Feedthrough) -> List[Link]:
    """Links sorted so that each input is set after everything its source output depends on."""
    graph = variable_graph(links, feedthrough)
    rank = {node: i for i, node in enumerate(_topological(graph))}
    return sorted(links, key=lambda link: rank[link[1]])


def _topological(graph: Mapping[str, Sequence[str]]) -> List[str]:
    # strongly_connected returns components in reverse topological order
    return [node for members in reversed(strongly_connected(graph)) for node in members]


def stepping_order(components: Sequence[str], links: Iterable[Link], feedthrough: Feedthrough) -> List[str]:
    """Gauss-Seidel order of the components.

    A component steps after the components that feed it. A feedback loop (components that reach
    each other) is cut at a connection into an input that reaches none of the loop's connections
    directly (a plant's actuator input), so the component whose outputs in the loop react
    instantly to their inputs (a controller) sees fresh values. Ties keep the scenario's order.
    """
    links = list(links)
    position = {c: i for i, c in enumerate(components)}
    coupled: Dict[str, List[str]] = {c: [] for c in components}
    for source, target in links:
        coupled[component_of(source)].append(component_of(target))
    loop_of = {c: i for i, members in enumerate(strongly_connected(coupled)) for c in members}
    # outputs that feed a component of their own feedback loop
    in_loop = {s for s, t in links if loop_of[component_of(s)] == loop_of[component_of(t)]}
    edges: Dict[str, Dict[str, bool]] = {c: {} for c in components}
    for source, target in links:
        a, b = component_of(source), component_of(target)
        if a == b:
            continue
        strong = any(variable_of(target) in deps and f"{b}.{out}" in in_loop
                     for out, deps in feedthrough.get(b, {}).items())
        edges[a][b] = edges[a].get(b, False) or strong
    remaining = set(components)
    order: List[str] = []
    while remaining:
        def blocked(node: str, strong_only: bool) -> bool:
            return any(node in edges[a] and (edges[a][node] or not strong_only) for a in remaining if a != node)
        for strong_only in (False, True):
            ready = [c for c in remaining if not blocked(c, strong_only)]
            if ready:
                break
        else:
            ready = list(remaining)
        chosen = min(ready, key=position.__getitem__)
        order.append(chosen)
        remaining.discard(chosen)
    return order


# --- algebraic loops the master solves -----------------------------------------------------------
#: loops with up to this many components are torn optimally (every evaluation order is tried)
EXHAUSTIVE_TEARING = 7


def loop_groups(links: Iterable[Link], feedthrough: Feedthrough) -> List[List[Link]]:
    """The connections of every algebraic loop, grouped by the components that must step together.

    A loop is a strongly connected component of :func:`variable_graph` (every cycle in it runs
    through connections and direct feedthrough); its connections are those whose both ends are
    in it. Loops that share a component are one group: a component steps once per step.
    """
    links = list(links)
    graph = variable_graph(links, feedthrough)
    groups: List[Tuple[Set[str], List[Link]]] = []
    for members in strongly_connected(graph):
        if len(members) < 2:
            continue
        inside = set(members)
        loop = [(s, t) for s, t in links if s in inside and t in inside]
        components = {component_of(ref) for ref in inside}
        for other in [g for g in groups if g[0] & components]:
            groups.remove(other)
            components |= other[0]
            loop = other[1] + loop
        groups.append((components, loop))
    return sorted((sorted(loop) for _, loop in groups), key=lambda loop: loop[0])


def tear(components: Sequence[str], links: Sequence[Link],
         tearable: Callable[[str], bool]) -> Tuple[List[str], List[str]]:
    """An evaluation order of a loop's ``components`` and its tear variables.

    The loop is evaluated by stepping its components one after another, each taking the fresh
    outputs of those before it. A connection from a component at or after its target in that
    order runs backwards: its source output is a *tear variable*, whose value is guessed and
    iterated until the guess and what the source then gives agree. The order chosen makes the
    tear set smallest (fewest distinct torn outputs, every one of them ``tearable``): exactly, by
    trying every order, up to :data:`EXHAUSTIVE_TEARING` components (ties keep the order of
    ``components``); above that, with the Eades-Lin-Smyth heuristic for a feedback arc set.
    Raises ``ValueError`` when every order tears an output that is not ``tearable``.
    """
    components = list(components)
    best: Optional[Tuple[int, List[str], List[str]]] = None
    candidates = (itertools.permutations(components) if len(components) <= EXHAUSTIVE_TEARING
                  else [_eades_lin_smyth(components, links)])
    for order in candidates:
        torn = _torn(order, links)
        if all(tearable(s) for s in torn) and (best is None or len(torn) < best[0]):
            best = (len(torn), list(order), torn)
    if best is None:
        raise ValueError("every evaluation order tears a connection that cannot be iterated on")
    return best[1], best[2]


def _torn(order: Sequence[str], links: Sequence[Link]) -> List[str]:
    """Sources of the connections that run backwards in ``order`` (self-loops included)."""
    position = {c: i for i, c in enumerate(order)}
    torn: List[str] = []
    for source, target in links:
        if position[component_of(source)] >= position[component_of(target)] and source not in torn:
            torn.append(source)
    return torn


def _eades_lin_smyth(components: Sequence[str], links: Sequence[Link]) -> List[str]:
    """A good order for a large loop (Eades, Lin and Smyth 1993): sinks go last, sources first,
    otherwise the component with the most outgoing minus incoming connections goes first."""
    weight: Dict[Tuple[str, str], int] = {}
    for source, target in links:
        a, b = component_of(source), component_of(target)
        if a != b:
            weight[(a, b)] = weight.get((a, b), 0) + 1
    remaining = list(components)
    head: List[str] = []
    tail: List[str] = []

    def flow(node: str, outgoing: bool) -> int:
        return sum(w for (a, b), w in weight.items() if (a if outgoing else b) == node
                   and (b if outgoing else a) in remaining)

    while remaining:
        sinks = [c for c in remaining if flow(c, True) == 0]
        if sinks:
            tail.insert(0, sinks[0])
            remaining.remove(sinks[0])
            continue
        sources = [c for c in remaining if flow(c, False) == 0]
        chosen = sources[0] if sources else max(remaining, key=lambda c: flow(c, True) - flow(c, False))
        head.append(chosen)
        remaining.remove(chosen)
    return head + tail


def block_stepping_order(components: Sequence[str], links: Iterable[Link], feedthrough: Feedthrough,
                         blocks: Sequence[Sequence[str]]) -> List[str]:
    """:func:`stepping_order` where each block (an algebraic loop's components, in their
    evaluation order) steps as one: its components come together, in that order.

    Each block is one node of the graph; its outputs depend directly on the inputs from which
    a path of connections and direct feedthrough inside the block reaches them.
    """
    links = list(links)
    block_of: Dict[str, int] = {c: i for i, block in enumerate(blocks) for c in block}
    names = [f"<loop {i + 1}>" for i in range(len(blocks))]

    def node(reference: str) -> str:
        comp = component_of(reference)
        return f"{names[block_of[comp]]}.{reference}" if comp in block_of else reference

    graph = variable_graph(links, feedthrough)
    merged: Dict[str, Dict[str, Set[str]]] = {name: {} for name in names}
    for source, _ in links:
        comp = component_of(source)
        if comp not in block_of:
            continue
        members = set(blocks[block_of[comp]])
        reach = _reaching(graph, source, members)
        merged[names[block_of[comp]]][source] = {ref for ref in reach if ref != source}
    condensed: List[str] = []
    for c in components:
        name = names[block_of[c]] if c in block_of else c
        if name not in condensed:
            condensed.append(name)
    order = stepping_order(condensed, [(node(s), node(t)) for s, t in links],
                           {**feedthrough, **merged})
    expanded: List[str] = []
    for name in order:
        expanded.extend(blocks[names.index(name)] if name in names else [name])
    return expanded


def _reaching(graph: Mapping[str, Sequence[str]], target: str, members: Set[str]) -> Set[str]:
    """Variables of ``members`` from which ``target`` is reached inside ``members``."""
    backwards: Dict[str, List[str]] = {}
    for node, children in graph.items():
        for child in children:
            backwards.setdefault(child, []).append(node)
    seen = {target}
    frontier = [target]
    while frontier:
        node = frontier.pop()
        for parent in backwards.get(node, ()):
            if parent not in seen and component_of(parent) in members:
                seen.add(parent)
                frontier.append(parent)
    return seen
