"""A component's internal state (what an FMU state holds besides the variables): a restore that
does not fit changes nothing."""
from __future__ import annotations

import numpy as np
import pytest

from deltafmi.component import Component, Parameter


class _Gain(Component):
    """A component with attributes of its own and one of the instance's (its value buffer)."""

    k = Parameter(2.0)


def _component() -> _Gain:
    component = object.__new__(_Gain)
    vars(component).update(_real=np.zeros(3), gain=2.0, history=[1.0, 2.0])
    return component


@pytest.mark.parametrize("state", [
    {"gain": 3.0, "_real": np.ones(3)},          # the instance's value buffer: never in a state
    {"gain": 3.0, "resources_dir": "/etc"},      # where the component reads its files
    {"gain": 3.0, ("deltafmi", "shaRed"): None},  # an attribute named by no string
    ["gain", 3.0],
])
def test_a_restore_that_does_not_fit_changes_nothing(state):
    component = _component()
    buffer = component._real
    with pytest.raises((TypeError, ValueError)):
        component.restore_internal_state(state)
    assert vars(component).keys() == {"_real", "gain", "history"}
    assert component._real is buffer and component.gain == 2.0 and component.history == [1.0, 2.0]


def test_a_state_restores_the_components_own_attributes_and_keeps_the_instances():
    component = _component()
    buffer = component._real
    saved = component.internal_state()
    component.gain, component.history = 5.0, [9.0]
    component.extra = "made after the state"
    component.restore_internal_state(saved)
    assert vars(component).keys() == {"_real", "gain", "history"}
    assert component._real is buffer and component.gain == 2.0 and component.history == [1.0, 2.0]
    component.history.append(3.0)  # a copy: the state stays valid for another restore
    component.restore_internal_state(saved)
    assert component.history == [1.0, 2.0]
