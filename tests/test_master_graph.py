"""Dependency graphs: Gauss-Seidel order, initialization order, algebraic loops (no FMUs)."""
from __future__ import annotations

from deltafmi.cosim.graph import algebraic_loops, initialization_order, stepping_order, strongly_connected

# plant: y depends on its states only, lambda on u; controller: u depends on y and r
FEEDTHROUGH = {
    "plant": {"y": set(), "lambda": {"u"}},
    "controller": {"u": {"y", "r"}},
    "trajectory": {"r": set()},
}
LOOP = [("trajectory.r", "controller.r"), ("plant.y", "controller.y"), ("controller.u", "plant.u")]


def test_feedback_through_a_plant_is_no_algebraic_loop():
    assert algebraic_loops(LOOP, FEEDTHROUGH) == []


def test_feedthrough_both_ways_is_a_named_loop():
    feedthrough = dict(FEEDTHROUGH, plant={"y": {"u"}})
    assert algebraic_loops(LOOP, feedthrough) == [["controller.u", "plant.u", "plant.y", "controller.y"]]


def test_self_loop_through_own_feedthrough():
    assert algebraic_loops([("a.y", "a.u")], {"a": {"y": {"u"}}}) == [["a.u", "a.y"]]


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
