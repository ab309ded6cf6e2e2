"""Dependency graphs of a connected system: stepping order, initialization order, algebraic loops.

Pure graph logic, no FMI: a *link* is ``(source "comp.out", target "comp.in")`` and
*feedthrough* maps ``comp -> {output: {inputs it depends on directly}}``.
"""
from __future__ import annotations

from typing import Dict, Iterable, List, Mapping, Sequence, Set, Tuple

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


def algebraic_loops(links: Iterable[Link], feedthrough: Feedthrough) -> List[List[str]]:
    """Every algebraic loop as one closed chain of variables ``[a.y, b.u, b.y, a.u]``."""
    graph = variable_graph(links, feedthrough)
    loops = []
    for members in strongly_connected(graph):
        if len(members) > 1:
            loops.append(_cycle_through(graph, set(members), min(members)))
    return sorted(loops)


def _cycle_through(graph: Mapping[str, Sequence[str]], members: Set[str], start: str) -> List[str]:
    """A shortest cycle from ``start`` back to itself inside ``members`` (breadth first)."""
    parent: Dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for node in frontier:
            for child in graph[node]:
                if child not in members:
                    continue
                if child == start:
                    chain = [node]
                    while chain[-1] != start:
                        chain.append(parent[chain[-1]])
                    return chain[::-1]
                if child not in parent:
                    parent[child] = node
                    nxt.append(child)
        frontier = nxt
    return sorted(members)


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
