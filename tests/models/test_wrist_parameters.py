"""The wrist, its tool and the hole: one declaration each (deltafmi.models.wrist_declarations), one
default each, in every 6-DOF model that carries them (the plants, and the controller, the
estimator and the MPC that model the plant)."""
from __future__ import annotations

import pytest
import yaml

from deltafmi.models import AssemblyController, DeltaWrist, DeltaWristPeg, InsertionMpc, PegEstimator
from deltafmi.models.robot_parameters import DECLARATIONS as ROBOT
from deltafmi.models.wrist_declarations import HOLE_DECLARATIONS, WRIST_DECLARATIONS, hole_parameters
from deltafmi.shipped import SCENARIOS_DIR

#: model -> (the note after every wrist description, None: no wrist; which hole its pose is; the
#: note after every hole description; the hole parameters it carries)
CARRIERS = {
    DeltaWrist: ("", None, "", ()),
    DeltaWristPeg: ("", "true", "", tuple(HOLE_DECLARATIONS)),
    PegEstimator: ("as the estimator models it", "nominal", "as the estimator models it", tuple(HOLE_DECLARATIONS)),
    AssemblyController: ("as the controller models it", "nominal", "", ("hole_position", "hole_tilt")),
    InsertionMpc: (None, "nominal", "", ("hole_position", "hole_tilt", "hole_depth")),
}


def _parameters(cls: type) -> dict:
    """name -> (start, unit, min, description) of the component's parameters, in declaration order."""
    return {d.name: (d.start, d.unit, d.min, d.description) for d in cls._layout.declarations
            if d.causality == "parameter"}


def _expected(default, unit, low, description, note):
    start = list(default) if isinstance(default, tuple) else [default]
    return start, unit, low, f"{description}; {note}" if note else description


@pytest.mark.parametrize("cls", list(CARRIERS), ids=lambda c: c.__name__)
def test_a_model_declares_the_wrist_and_the_hole_from_the_one_table(cls):
    note, hole, hole_note, holes = CARRIERS[cls]
    parameters = _parameters(cls)
    expected = {}
    if note is not None:  # InsertionMpc models no wrist
        expected.update({name: _expected(*row, note) for name, row in WRIST_DECLARATIONS.items()})
    for name in holes:
        default, unit, low, description = HOLE_DECLARATIONS[name]
        expected[name] = _expected(default, unit, low, description.format(hole=hole), hole_note)
    assert {name: parameters[name] for name in expected} == expected
    # the order the bases give: the robot's, the wrist's, the hole's, then the model's own
    # (DeltaWristPeg: DeltaWrist's own before the hole's, as before)
    names = list(parameters)
    shared = [n for n in names if n in ROBOT or n in expected]
    robot = [n for n in ROBOT if n in parameters]
    wrist = [n for n in WRIST_DECLARATIONS if n in expected]
    assert shared == robot + wrist + [n for n in HOLE_DECLARATIONS if n in holes]
    if cls is not DeltaWristPeg:
        assert names[:len(shared)] == shared


def test_the_hole_has_one_default_two_centimetres_below_the_plants_starting_tip():
    tops = {cls.__name__: tuple(cls.hole_position.start) for cls in CARRIERS if cls is not DeltaWrist}
    assert set(tops.values()) == {(0.0, 0.0, -1.2)}, tops
    tip = DeltaWristPeg.tip0.start
    assert tip[:2] == [0.0, 0.0] and tip[2] - (-1.2) == pytest.approx(0.02, abs=1e-12)


def test_the_shipped_scenarios_set_the_controllers_hole_where_the_default_now_is():
    """Every shipped scenario with the insertion program gives its controller the nominal hole
    explicitly, at the default: the default (once -1.1 m in AssemblyController) changes none of them."""
    seen = 0
    for path in sorted(SCENARIOS_DIR.glob("*.yaml")):
        for component in yaml.safe_load(path.read_text()).get("components", {}).values():
            if component.get("source") == "deltafmi.models:AssemblyController":
                parameters = component.get("parameters", {})
                if parameters.get("program", True):
                    assert parameters["hole_position"] == [0.0, 0.0, -1.2], path.name
                    seen += 1
    assert seen >= 3


def test_an_unknown_hole_parameter_is_named():
    with pytest.raises(ValueError, match="no hole parameters named bore, depth"):
        hole_parameters("nominal", names=("hole_position", "depth", "bore"))
