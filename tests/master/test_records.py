"""The master's records behave as the dataclasses they replace: the same repr, equality, hash,
immutability, and the dataclasses functions on them (checked against ``@dataclass`` classes of
the same fields, and on the scenario's own records)."""
from __future__ import annotations

import dataclasses
import pickle
from dataclasses import dataclass, field
from typing import Optional, Tuple

import pytest

from deltafmi.master.scenario.records import record
from deltafmi.master.scenario.spec import Experiment, MasterSettings, Realtime
from deltafmi.master.scenario.system import Port


@record
class Point:
    x: float
    y: float = 0.0
    tags: Tuple[str, ...] = ()


@dataclass(frozen=True)
class PointDataclass:
    x: float
    y: float = 0.0
    tags: Tuple[str, ...] = ()


@record(frozen=False)
class Tally:
    name: str
    counts: list = field(default_factory=list)
    note: Optional[str] = None


@dataclass
class TallyDataclass:
    name: str
    counts: list = field(default_factory=list)
    note: Optional[str] = None


@record
class Nothing:
    pass


def test_a_frozen_record_is_what_a_frozen_dataclass_is():
    for args in [(1.0,), (1.0, -2.5), (float("nan"), 3.0, ("a", "b")), ("text", None)]:
        ours, theirs = Point(*args), PointDataclass(*args)
        assert repr(ours) == repr(theirs).replace("PointDataclass", "Point")
        assert hash(ours) == hash(theirs)
        assert (ours == Point(*args)) == (theirs == PointDataclass(*args))  # a NaN field: equal as the same object, as in a tuple
        assert ours == ours and theirs == theirs  # the same object: equal, as tuples compare
    assert Point(1.0) != Point(2.0) and Point(1.0) != PointDataclass(1.0)
    assert Point(1.0).__eq__(PointDataclass(1.0)) is NotImplemented
    assert len({Point(1.0), Point(1.0, 0.0), Point(2.0)}) == 2
    with pytest.raises(dataclasses.FrozenInstanceError):
        Point(1.0).x = 2.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        del Point(1.0).y  # type: ignore[misc]
    assert repr(Nothing()) == "Nothing()" and Nothing() == Nothing() and hash(Nothing()) == hash(())


def test_a_mutable_record_is_what_a_dataclass_is():
    ours, theirs = Tally("a", [1, 2]), TallyDataclass("a", [1, 2])
    assert repr(ours) == repr(theirs).replace("TallyDataclass", "Tally")
    assert ours == Tally("a", [1, 2]) and ours != Tally("a", [1])
    assert Tally.__hash__ is None and TallyDataclass.__hash__ is None
    ours.note = "changed"
    assert ours.note == "changed" and Tally("b").counts == [] and Tally("b").counts is not Tally("b").counts


def test_records_are_dataclasses_for_the_dataclasses_functions():
    point = Point(1.0, 2.0, ("t",))
    assert [f.name for f in dataclasses.fields(point)] == ["x", "y", "tags"]
    assert dataclasses.asdict(point) == {"x": 1.0, "y": 2.0, "tags": ("t",)}
    assert dataclasses.replace(point, y=5.0) == Point(1.0, 5.0, ("t",))
    assert pickle.loads(pickle.dumps(point)) == point


def test_the_scenarios_records():
    settings = MasterSettings()
    assert settings == MasterSettings() and hash(settings) == hash(MasterSettings())
    assert dataclasses.replace(settings, threads=2) != settings
    assert repr(Experiment(0.0, 1.0, 0.001)) == "Experiment(start=0.0, stop=1.0, step=0.001, tolerance=None)"
    assert repr(settings.realtime) == ("Realtime(enabled=False, speed=1.0, behind='warn', tolerance=None, "
                                       "spin=None, priority=None, lead=None)")
    assert settings.realtime == Realtime()
    names = [f.name for f in dataclasses.fields(Port)]
    assert Port.__record_fields__ == tuple(names)
