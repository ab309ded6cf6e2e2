"""Dependency graphs: Gauss-Seidel order, initialization order, algebraic loops (no FMUs)."""
from __future__ import annotations

import pytest

from deltafmi.master.scenario.graph import (block_stepping_order, initialization_order, loop_groups, stepping_order,
                                  strongly_connected, tear)

# plant: y depends on its states only, lambda on u; controller: u depends on y and r
FEEDTHROUGH = {
    "plant": {"y": set(), "lambda": {"u"}},
    "controller": {"u": {"y", "r"}},
    "trajectory": {"r": set()},
}
LOOP = [("trajectory.r", "controller.r"), ("plant.y", "controller.y"), ("controller.u", "plant.u")]


def test_feedback_through_a_plant_is_no_algebraic_loop():
    assert loop_groups(LOOP, FEEDTHROUGH) == []


def test_feedthrough_both_ways_is_a_loop_of_its_connections():
    feedthrough = dict(FEEDTHROUGH, plant={"y": {"u"}})
    assert loop_groups(LOOP, feedthrough) == [[("controller.u", "plant.u"), ("plant.y", "controller.y")]]


def test_self_loop_through_own_feedthrough():
    assert loop_groups([("a.y", "a.u")], {"a": {"y": {"u"}}}) == [[("a.y", "a.u")]]


def test_loops_sharing_a_component_step_together():
    # a has two independent channels, each closing a loop with its own partner: a steps once
    links = [("a.y1", "b.u"), ("b.y", "a.u1"), ("a.y2", "c.u"), ("c.y", "a.u2"), ("d.y", "e.u"), ("e.y", "d.u")]
    feedthrough = {"a": {"y1": {"u1"}, "y2": {"u2"}}, "b": {"y": {"u"}}, "c": {"y": {"u"}},
                   "d": {"y": {"u"}}, "e": {"y": {"u"}}}
    groups = loop_groups(links, feedthrough)
    assert groups == [sorted(links[:4]), sorted(links[4:])]


REAL = lambda ref: True  # noqa: E731


def test_tearing_a_ring_cuts_one_output_and_keeps_the_given_order():
    ring = [("a.y", "b.u"), ("b.y", "c.u"), ("c.y", "a.u")]
    assert tear(["a", "b", "c"], ring, REAL) == (["a", "b", "c"], ["c.y"])
    assert tear(["b", "c", "a"], ring, REAL) == (["b", "c", "a"], ["a.y"])


def test_tearing_counts_outputs_not_connections():
    # c.y feeds both a and b: tearing c.y (one output, two connections) beats any single other cut
    links = [("a.y", "b.u"), ("b.y", "c.u"), ("c.y", "a.u"), ("c.y", "b.v"), ("a.z", "c.w")]
    order, torn = tear(["c", "a", "b"], links, REAL)
    assert torn == ["c.y"] and order == ["a", "b", "c"]


def test_tearing_a_chord_ring_needs_the_fewest_tears():
    # cycles a-b-a, b-c-b and c-a-b-c: the scenario's order a, b, c tears three outputs (b.y1,
    # c.y, c.z); the fewest is two (b, c, a tears a.y and c.y; c, a, b tears b's two outputs)
    links = [("a.y", "b.u1"), ("b.y1", "a.u"), ("b.y2", "c.u"), ("c.y", "b.u2"), ("c.z", "a.v")]
    order, torn = tear(["a", "b", "c"], links, REAL)
    assert (order, torn) == (["b", "c", "a"], ["a.y", "c.y"])
    position = {c: i for i, c in enumerate(order)}
    for source, target in links:  # every connection not torn runs forwards
        if source not in torn:
            assert position[source.split(".")[0]] < position[target.split(".")[0]]


def test_tearing_avoids_outputs_that_are_not_real():
    ring = [("a.n", "b.u"), ("b.y", "a.u")]
    assert tear(["b", "a"], ring, lambda ref: ref != "a.n") == (["a", "b"], ["b.y"])
    with pytest.raises(ValueError):
        tear(["a", "b"], ring, lambda ref: False)


def test_large_loops_are_torn_by_the_heuristic():
    # ten components in a ring with every other one feeding back two places: tears every cycle
    names = [f"c{i}" for i in range(10)]
    links = [(f"{a}.y", f"{b}.u") for a, b in zip(names, names[1:] + names[:1])]
    links += [(f"{names[i]}.z", f"{names[i - 2]}.v") for i in range(0, 10, 2)]
    order, torn = tear(names, links, REAL)
    assert sorted(order) == sorted(names)
    position = {c: i for i, c in enumerate(order)}
    for source, target in links:
        if source not in torn:
            assert position[source.split(".")[0]] < position[target.split(".")[0]]


def test_a_loop_steps_as_one_block_in_its_evaluation_order():
    # source -> loop (g1, g2) -> sink; g2 is listed first but the loop's order is g1, g2
    links = [("src.y", "g1.w"), ("g1.y", "g2.u"), ("g2.y", "g1.u"), ("g2.y", "sink.u")]
    feedthrough = {"src": {"y": set()}, "g1": {"y": {"u", "w"}}, "g2": {"y": {"u"}}, "sink": {}}
    order = block_stepping_order(["sink", "g2", "src", "g1"], links, feedthrough, [["g1", "g2"]])
    assert order == ["src", "g1", "g2", "sink"]


def test_stepping_order_cuts_the_loop_at_the_plant_input():
    # scenario order puts the controller first; the controller's output reacts to y directly,
    # the plant's connected output does not react to u: plant before controller
    assert stepping_order(["controller", "plant", "trajectory"], LOOP, FEEDTHROUGH) == \
        ["trajectory", "plant", "controller"]


def test_stepping_order_ignores_feedthrough_to_unconnected_outputs():
    # lambda depends on u, but nothing reads lambda: the edge into plant.u stays weak
    links = LOOP + [("plant.lambda", "logger.x")]
    order = stepping_order(["controller", "plant", "trajectory", "logger"], links,
                           dict(FEEDTHROUGH, logger={}))
    assert order.index("plant") < order.index("controller")
    assert order.index("plant") < order.index("logger")


def test_stepping_order_keeps_scenario_order_for_independent_components():
    assert stepping_order(["b", "a", "c"], [], {}) == ["b", "a", "c"]


def test_initialization_sets_each_input_after_what_its_source_depends_on():
    # chain: source -> f1 (feedthrough) -> f2 (feedthrough) -> sink, links listed backwards
    links = [("f2.y", "sink.u"), ("f1.y", "f2.u"), ("source.y", "f1.u")]
    feedthrough = {"f1": {"y": {"u"}}, "f2": {"y": {"u"}}, "source": {"y": set()}, "sink": {}}
    assert initialization_order(links, feedthrough) == list(reversed(links))


def test_strongly_connected_components():
    graph = {"a": ["b"], "b": ["a", "c"], "c": ["d"], "d": ["c"], "e": []}
    components = sorted(sorted(c) for c in strongly_connected(graph))
    assert components == [["a", "b"], ["c", "d"], ["e"]]
