"""FMI 3.0 export: every packaged model built with ``fmi_version=3`` is a valid FMI 3.0 FMU whose
arrays are single variables, whose ModelStructure is its FMI 2.0 build's, and which simulates in
fmpy as its FMI 2.0 build does (Co-Simulation to 1e-9, Model Exchange to the solver's tolerance,
events at the same times)."""
from __future__ import annotations

import math
import re
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from click.testing import CliRunner
from fmpy.validation import validate_fmu

from deltafmi.apps.cli import main
from deltafmi.runtime.instance import CO_SIMULATION, FmuInstance
from deltafmi.builder import build_cached
from deltafmi.models import MODELS
from deltafmi.models.bouncing_ball import BouncingBall
from deltafmi.models.delta_robot import DeltaRobot

SIMULATED = {"Oscillator": 2.0, "BouncingBall": 3.0, "DeltaRobot": 0.3}  # stop times
GEARBOX = Path(__file__).parents[1] / "components" / "gearbox" / "model.py"  # an Enumeration parameter and output


@pytest.fixture(scope="module")
def fmus2():
    return {name: build_cached(name) for name in MODELS}


@pytest.fixture(scope="module")
def fmus3():
    return {name: build_cached(name, fmi_version=3) for name in MODELS}


def _variable(name: str) -> str:
    """The FMI 3.0 variable holding the FMI 2.0 scalar ``name``: ``q[2]`` -> ``q``, ``der(q[2])``
    -> ``der(q)``."""
    return re.sub(r"\[\d+\]", "", name)


def test_every_packaged_model_is_a_valid_fmi3_fmu(fmus3):
    for name, fmu in fmus3.items():
        assert validate_fmu(str(fmu)) == [], name
        md = fmpy.read_model_description(str(fmu))
        assert md.fmiVersion == "3.0" and md.modelExchange and md.coSimulation, name
        assert md.instantiationToken == md.guid
        with zipfile.ZipFile(fmu) as archive:
            names = archive.namelist()
            readme = archive.read("resources/README.txt").decode()
        assert f"binaries/x86_64-linux/{name}.so" in names and not any("linux64" in n for n in names), name
        assert "FMI 3.0 FMU" in readme
        independent = [v for v in md.modelVariables if v.causality == "independent"]
        assert [(v.name, v.type) for v in independent] == [("time", "Float64")]


def test_a_vector_declaration_is_one_array_variable(fmus2, fmus3):
    md2 = fmpy.read_model_description(str(fmus2["DeltaRobot"]))
    md3 = fmpy.read_model_description(str(fmus3["DeltaRobot"]))
    by_name = {v.name: v for v in md3.modelVariables}
    assert "q[1]" not in by_name
    for name, size in (("q", 9), ("der(q)", 9), ("v", 9), ("u", 3), ("lambda", 6), ("z0", 3)):
        assert [d.start for d in by_name[name].dimensions] == [size], name
    scalars2 = {v.name: v for v in md2.modelVariables}
    # the same buffers: the array's value reference is that of its first FMI 2.0 scalar
    for name in ("q", "v", "u", "lambda", "payload"):
        first = scalars2[f"{name}[1]" if f"{name}[1]" in scalars2 else name]
        assert by_name[name].valueReference == first.valueReference
    assert by_name["der(q)"].derivative is by_name["q"]
    # what the binary is told (Layout.sizes3): each variable's element count at its value reference
    layout = DeltaRobot._layout
    sizes = np.zeros(layout.n_total, dtype=np.uint32)
    for v in md3.modelVariables:
        if v.valueReference < layout.n_total:
            sizes[v.valueReference] = int(np.prod([d.start for d in v.dimensions]))
    assert np.array_equal(layout.sizes3, sizes) and sizes.sum() == layout.n_total == len(md2.modelVariables)
    assert by_name["q"].unit == "rad" and by_name["u"].unit == "N.m"
    # an array's start value lists its elements
    z0 = [float(scalars2[f"z0[{i}]"].start) for i in (1, 2, 3)]
    assert [float(x) for x in str(by_name["z0"].start).split()] == z0
    types = {v.type for v in fmpy.read_model_description(str(fmus3["Trajectory"])).modelVariables}
    assert {"Float64", "Int32", "String"} <= types
    assert "Boolean" in {v.type for v in md3.modelVariables} | {
        v.type for v in fmpy.read_model_description(str(fmus3["BouncingBall"])).modelVariables}


def test_model_structure_is_the_fmi2_builds(fmus2, fmus3):
    """Every output, state derivative, initial unknown and event indicator is listed, and each
    dependency list is the FMI 2.0 build's mapped onto the variables that hold its scalars, plus
    ``time`` (FMI 3.0 declares the independent variable, so it is a known to list)."""
    for name in MODELS:
        md2 = fmpy.read_model_description(str(fmus2[name]))
        md3 = fmpy.read_model_description(str(fmus3[name]))
        for unknowns2, unknowns3, what in ((md2.outputs, md3.outputs, "outputs"),
                                           (md2.derivatives, md3.derivatives, "derivatives")):
            expected: dict[str, set[str]] = {}
            for u in unknowns2:
                expected.setdefault(_variable(u.variable.name), set()).update(
                    _variable(d.name) for d in u.dependencies)
            got = {u.variable.name: {d.name for d in u.dependencies} for u in unknowns3}
            assert got == {k: v | {"time"} for k, v in expected.items()}, (name, what)
        assert ({_variable(u.variable.name) for u in md2.initialUnknowns}
                == {u.variable.name for u in md3.initialUnknowns}), name
        assert {v.name for v in md3.modelVariables if v.causality == "output"} == {
            u.variable.name for u in md3.outputs}, name
        indicators = [u.variable for u in md3.eventIndicators]
        assert len(indicators) == md2.numberOfEventIndicators, name
        assert all(v.type == "Float64" and v.variability == "continuous" for v in indicators), name
        assert len({v.valueReference for v in indicators}) == len(indicators)


def _columns(result: np.ndarray) -> dict[str, np.ndarray]:
    """fmpy's result with every array field split into its elements ``q[1]``, ``q[2]``, ..."""
    out = {}
    for name in result.dtype.names:
        column = result[name]
        column = column.astype(float)  # booleans too, to compare by differences
        if column.ndim == 1:
            out[name] = column
        else:
            out.update({f"{name}[{i + 1}]": column[:, i] for i in range(column.shape[1])})
    return out


def _simulate(fmu, fmi_type: str, stop: float, **options) -> dict[str, np.ndarray]:
    return _columns(fmpy.simulate_fmu(str(fmu), fmi_type=fmi_type, stop_time=stop, output_interval=0.01,
                                      relative_tolerance=1e-8, **options))


@pytest.mark.parametrize("name", sorted(SIMULATED))
def test_co_simulation_equals_the_fmi2_build(fmus2, fmus3, name):
    r2 = _simulate(fmus2[name], "CoSimulation", SIMULATED[name])
    r3 = _simulate(fmus3[name], "CoSimulation", SIMULATED[name])
    assert set(r2) == set(r3) and len(r2["time"]) == len(r3["time"])
    for column, values in r2.items():
        scale = max(1.0, np.max(np.abs(values)))
        assert np.max(np.abs(r3[column] - values)) <= 1e-9 * scale, column


@pytest.mark.parametrize("name", sorted(SIMULATED))
def test_model_exchange_equals_the_fmi2_build(fmus2, fmus3, name):
    r2 = _simulate(fmus2[name], "ModelExchange", SIMULATED[name])
    r3 = _simulate(fmus3[name], "ModelExchange", SIMULATED[name])
    # fmpy records a row before and after each event: the same rows, so events at the same times
    assert len(r2["time"]) == len(r3["time"])
    assert np.max(np.abs(r3["time"] - r2["time"])) < 1e-6
    for column, values in r2.items():
        scale = max(1.0, np.max(np.abs(values)))
        assert np.max(np.abs(r3[column] - values)) <= 1e-5 * scale, column


@pytest.mark.parametrize("name, stop", [("BouncingBall", 3.0), ("Oscillator", 4.0), ("TactileSensor", 0.3)])
def test_event_mode_co_simulation_returns_at_each_event(fmus2, fmus3, name, stop):
    """fmpy in FMI 3.0 event mode: the FMU returns early at each event (the ball's impacts; the
    oscillator's wall and its force switched on and off by time events; the sensor's samples),
    the importer handles it, and on the grid (after any event there) the trajectory is the FMI 2.0
    build's, which handles its events inside doStep."""
    r2 = _simulate(fmus2[name], "CoSimulation", stop)
    r3 = _simulate(fmus3[name], "CoSimulation", stop, use_event_mode=True, early_return_allowed=True)
    me = _simulate(fmus2[name], "ModelExchange", stop)
    events_me = me["time"][1:][np.diff(me["time"]) == 0]  # fmpy records a row before and after an event
    on_grid = np.isclose(r3["time"] / 0.01, np.round(r3["time"] / 0.01), atol=1e-9, rtol=0)
    early = np.unique(r3["time"][~on_grid])
    assert len(early) >= 3
    assert all(np.min(np.abs(events_me - t)) < 1e-6 for t in early)
    grid_times = r3["time"][on_grid]
    after_events = np.append(np.diff(grid_times) != 0, True)  # the last row at each grid time
    for column, values in r2.items():
        got = r3[column][on_grid][after_events]
        assert np.max(np.abs(got - values)) <= 1e-9 * max(1.0, np.max(np.abs(values))), column


def test_event_mode_step_leaves_the_event_to_the_importer():
    """The Python side of CS event mode, step by step: do_step stops at the first event, reports
    it in control without handling it, and after the importer's event update the next steps give
    the very trajectory of steps that handle their events inside."""
    trajectories, stops = {}, []
    for event_mode in (0.0, 1.0):
        instance = FmuInstance(BouncingBall, fmu_type=CO_SIMULATION)
        instance.enter_initialization(0.0, math.nan, math.nan)
        instance.exit_initialization(event_mode)
        if event_mode:
            while instance.event_update(0.0)[0]:
                pass
        t, rows = 0.0, []
        for k in range(1, 151):
            while t < k * 0.01:
                contact = int(instance.component.contact)
                instance.do_step(t, k * 0.01 - t, event_mode)
                if instance.control[2]:
                    t = instance.control[1]
                    assert instance.component.contact == contact  # not handled
                    stops.append(t)
                    while instance.event_update(t)[0]:
                        pass
                else:
                    t = k * 0.01
            rows.append(instance.component._real[:2].copy())
        trajectories[event_mode] = np.array(rows)
    assert len(stops) >= 5
    assert np.array_equal(trajectories[0.0], trajectories[1.0])


def test_a_mode_switch_tells_the_importer_to_restart_its_integrator():
    """At the ball's first impact the contact law switches on: the states keep their values but
    their derivatives jump, and the event update says valuesOfContinuousStatesChanged, so that an
    importer that restarts its integrator only on that flag (the Reference FMUs' fmusim) does not
    go on with the free fall's solver history."""
    instance = FmuInstance(BouncingBall, fmu_type=CO_SIMULATION)
    instance.enter_initialization(0.0, math.nan, math.nan)
    instance.exit_initialization(1.0)
    while instance.event_update(0.0)[0]:
        pass
    instance.do_step(0.0, 1.0, 1.0)
    assert instance.control[2]
    t, states, contact = instance.control[1], instance.component._real[:2].copy(), int(instance.component.contact)
    flags = [instance.event_update(t)]
    while flags[-1][0]:
        flags.append(instance.event_update(t))
    assert (contact, int(instance.component.contact)) == (0, 1)
    assert np.array_equal(instance.component._real[:2], states)
    assert flags[0][3] is True


def test_cli_builds_every_model_as_fmi3(tmp_path):
    result = CliRunner().invoke(main, ["build", "--all", "--fmi-version", "3", "-o", f"{tmp_path}/"])
    assert result.exit_code == 0, result.output
    built = sorted(p.stem for p in tmp_path.glob("*.fmu"))
    assert built == sorted(MODELS)
    assert {fmpy.read_model_description(str(p)).fmiVersion for p in tmp_path.glob("*.fmu")} == {"3.0"}


def test_an_int_enum_declaration_is_an_enumeration():
    """``Parameter(Gear.LOW)`` with an IntEnum: an Enumeration type in both versions' model
    descriptions, set and read as its integer value, and read by the model as the member (the
    component raises otherwise)."""
    for version in (2, 3):
        fmu = build_cached(GEARBOX, fmi_version=version)
        assert validate_fmu(str(fmu)) == [], version
        md = fmpy.read_model_description(str(fmu))
        (gear_type,) = md.typeDefinitions
        assert gear_type.name == "Gear"
        assert [(item.name, int(item.value)) for item in gear_type.items] == [("LOW", 1), ("HIGH", 2), ("REVERSE", 3)]
        variables = {v.name: v for v in md.modelVariables}
        assert variables["gear"].type == variables["engaged"].type == "Enumeration"
        assert variables["gear"].declaredType is gear_type and int(variables["gear"].start) == 1
    fmu2 = build_cached(GEARBOX)
    for gear, ratio in ((1, 1.0), (2, 3.0), (3, -1.0)):
        result = fmpy.simulate_fmu(str(fmu2), fmi_type="CoSimulation", start_values={"gear": gear, "u": 2.0})
        assert np.all(result["engaged"] == gear) and np.allclose(result["y"], 2.0 * ratio, rtol=0, atol=0)


def test_portable_fmi3_fmu_runs_as_the_plain_one(fmus3, tmp_path):
    """``deltafmi build --portable --fmi-version 3``: the FMI 3.0 layout with the bundled
    interpreter, and in fmpy the plain build's numbers (the C host without any Python runs it in
    the binary's tests)."""
    target = tmp_path / "Oscillator.fmu"
    result = CliRunner().invoke(main, ["build", "Oscillator", "--portable", "--fmi-version", "3", "-o", str(target)])
    assert result.exit_code == 0, result.output
    with zipfile.ZipFile(target) as archive:
        names = archive.namelist()
        readme = archive.read("resources/README.txt").decode()
    assert "binaries/x86_64-linux/Oscillator.so" in names
    assert any(re.fullmatch(r"resources/python/lib/libpython3\.\d+\.so.*", n) for n in names)
    assert readme.startswith("A portable deltafmi FMU (FMI 3.0,")
    portable = _simulate(target, "CoSimulation", 2.0)
    plain = _simulate(fmus3["Oscillator"], "CoSimulation", 2.0)
    assert all(np.array_equal(portable[c], plain[c]) for c in plain)
