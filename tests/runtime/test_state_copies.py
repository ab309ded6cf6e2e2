"""A component's FMU state (Component.internal_state) copies what can change in place and shares
what cannot: the restored attributes equal a deep copy's, and changing the component afterwards
never reaches the snapshot."""
from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import NamedTuple

from deltafmi.runtime.base import _copied


class Point(NamedTuple):
    x: float
    y: float


@dataclass(frozen=True)
class Frozen:
    values: tuple


def test_numbers_and_tuples_are_shared_the_rest_copied_with_its_references():
    samples = tuple((0.001 * i, float(i)) for i in range(1000))
    history = [1.0, 2.0]
    frozen = Frozen((1.0, 2.0))
    attributes = {"samples": samples, "gain": 2.5, "name": "arm", "point": Point(1.0, -0.0),
                  "history": history, "same_history": history, "frozen": frozen, "mixed": (1.0, history)}
    state = _copied(attributes)
    assert state == copy.deepcopy(attributes)
    assert state["samples"] is samples and state["point"] is attributes["point"]
    assert state["history"] is not history and state["frozen"] is not frozen and state["mixed"] is not attributes["mixed"]
    # references among the copied values are kept, as one deep copy keeps them
    assert state["history"] is state["same_history"] is state["mixed"][1]
    history.append(3.0)
    object.__setattr__(frozen, "values", ())
    assert state["history"] == [1.0, 2.0] and state["frozen"].values == (1.0, 2.0)
    again = _copied(state)  # a restore copies again: the snapshot stays valid for the next
    again["history"].append(4.0)
    assert state["history"] == [1.0, 2.0]


def test_a_snapshot_names_what_it_shares_and_its_restore_shares_the_same():
    """A restore told which values the snapshot shares (the keys Component.internal_state keeps
    with it) copies exactly what one that looks through the values again copies."""
    samples = tuple((0.001 * i, float(i)) for i in range(100))
    history = [1.0, 2.0]
    attributes = {"samples": samples, "gain": 2.5, "history": history, "mixed": (1.0, history)}
    shared = frozenset(k for k, v in attributes.items() if k in ("samples", "gain"))
    told, looked = _copied(attributes, shared), _copied(attributes)
    assert told == looked == copy.deepcopy(attributes)
    assert told["samples"] is samples and told["history"] is not history and told["mixed"][1] is told["history"]
