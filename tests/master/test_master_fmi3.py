"""FMI 3.0 FMUs in the master, next to FMI 2.0 ones: the plain-C FMI 3.0 FMUs of tests/third_party
(no Python inside) alone against ``fmpy.simulate_fmu`` and closed forms, connected to our own
FMUs built as FMI 2.0 and as FMI 3.0; array variables connected whole and by element and recorded
as ``q[1]``, ``A[1,2]``; every FMI 3.0 type through the buses; Co-Simulation event mode at the
closed-form event times; an FMU that terminates; SSP, ``deltafmi info`` and ``validate``; and the
flagship with its three FMUs built as FMI 3.0 against the FMI 2.0 flagship.
"""
from __future__ import annotations

import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from click.testing import CliRunner
from scipy.linalg import expm

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.errors import ScenarioError
from test_third_party_fmus import ball_drives_oscillator, ball_exact, first_on_grid
from third_party.build import build_fmu

INTERFACES = {"CS": "CoSimulation", "ME": "ModelExchange"}
#: StateSpace3's matrices (its modelDescription's start values, row-major)
A = np.array([[-1.0, 2.0, 0.0], [-2.0, -1.0, 0.0], [0.0, 0.0, -0.5]])
B = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
D = np.array([[0.0, 0.0], [0.0, 0.5]])
X0 = np.array([1.0, 0.0, 0.5])


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict:
    """``{model: .fmu}`` of the FMI 3.0 C models used here, compiled once."""
    out = tmp_path_factory.mktemp("third_party3")
    return {model: build_fmu(model, out) for model in ("AllTypes3", "StateSpace3", "BouncingBall3")}


def run(tmp_path: Path, text: str, name: str = "run"):
    """Run the scenario ``text`` through the master: (summary, result columns)."""
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    summary = Master(resolve_system(load_scenario(path)), result=tmp_path / f"{name}.csv").run()
    return summary, columns(tmp_path / f"{name}.csv")


def problems(tmp_path: Path, text: str) -> str:
    """The error message resolving the scenario ``text`` gives."""
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as caught:
        resolve_system(load_scenario(path))
    return str(caught.value)


def state_space(t: np.ndarray, u: np.ndarray, x0: np.ndarray = X0) -> np.ndarray:
    """x(t) of der(x) = A x + B u for a constant u, in closed form (rows: times)."""
    forced = np.linalg.solve(A, B @ u)
    return np.array([expm(A * s) @ (x0 + forced) - forced for s in t])


# --- alone: the master against fmpy and closed forms -----------------------------------------------

@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_bouncing_ball_alone_equals_fmpy_and_events_come_at_closed_form_times(fmus, tmp_path, interface):
    """BouncingBall3 alone: on the grid as fmpy.simulate_fmu (CS with event mode and early
    return, as the master instantiates it), and two rows at each impact at the closed-form
    impact times: Model Exchange through CVODE's root finding, Co-Simulation through the FMU's
    early return and the master's event mode."""
    fmu, h = fmus["BouncingBall3"], 0.01
    summary, ours = run(tmp_path, f"experiment: {{stop: 3.0, step: {h}}}\n"
                                  f"components:\n  ball: {{fmu: {fmu}, interface: {interface}, "
                                  "solver: {rtol: 1.0e-12}}\n")
    theirs = fmpy.simulate_fmu(str(fmu), fmi_type=INTERFACES[interface], stop_time=3.0, output_interval=h,
                               output=["h", "v", "bounces"], relative_tolerance=1e-12,
                               use_event_mode=interface == "CS", early_return_allowed=interface == "CS")
    grid, their_grid = first_on_grid(ours, h), first_on_grid(theirs, h)
    assert len(grid) == len(their_grid) == 301
    for name in ("h", "v", "bounces"):
        deviation = np.max(np.abs(ours[f"ball.{name}"][grid] - theirs[name][their_grid].astype(float)))
        assert deviation <= 1e-9, (name, deviation)
    exact, impacts = ball_exact(ours["time"][grid])
    np.testing.assert_allclose(ours["ball.h"][grid], exact, rtol=0, atol=1e-9)
    t = ours["time"]
    np.testing.assert_allclose(t[1:][t[1:] == t[:-1]], impacts, rtol=0, atol=1e-9)
    assert summary.events == len(impacts) == 11


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_array_state_space_alone_matches_matrix_exponential(fmus, tmp_path, interface):
    """StateSpace3 (array parameters A[3,3], B, C, D, array input u[2], state x[3], output y[2])
    with u given as a parameter list: x and y follow the matrix exponential, recorded as x[1] ...
    and as fmpy gets them; a 2-D parameter is recorded row-major as A[1,1], A[1,2], ..."""
    fmu, u = fmus["StateSpace3"], np.array([1.0, -0.5])
    _, ours = run(tmp_path, f"experiment: {{stop: 2.0, step: 0.1}}\n"
                            f"components:\n  ss: {{fmu: {fmu}, interface: {interface}, parameters: {{u: [1.0, -0.5]}}, "
                            "solver: {rtol: 1.0e-10}}\n"
                            "outputs: ['ss.x', 'ss.y', 'ss.A']\n")
    row_major = [f"ss.A[{i},{j}]" for i in (1, 2, 3) for j in (1, 2, 3)]
    assert [name for name in ours if name.startswith("ss.A")] == row_major
    np.testing.assert_array_equal([ours[name][0] for name in row_major], A.ravel())
    x = state_space(ours["time"], u)
    got = np.column_stack([ours[f"ss.x[{i}]"] for i in (1, 2, 3)])
    np.testing.assert_allclose(got, x, rtol=0, atol=1e-8)
    y = np.column_stack([ours[f"ss.y[{i}]"] for i in (1, 2)])
    np.testing.assert_allclose(y, x @ C.T + D @ u, rtol=0, atol=1e-8)
    theirs = fmpy.simulate_fmu(str(fmu), fmi_type=INTERFACES[interface], stop_time=2.0, output_interval=0.1,
                               start_values={"u": [1.0, -0.5]}, output=["x", "y"], relative_tolerance=1e-10)
    np.testing.assert_allclose(got, theirs["x"], rtol=0, atol=1e-9 if interface == "CS" else 1e-8)


# --- arrays connected: whole, by element, shapes ---------------------------------------------------

def test_arrays_connect_whole_and_by_element(fmus, tmp_path):
    """Two StateSpace3 in Co-Simulation: first.y -> second.u whole (Gauss-Seidel: second holds
    first's output at the step's end over its step), and third.u[1] from first.y[2] alone, its
    u[2] kept at the value its parameters give. Each state follows its discretization in closed
    form (the exact one-step map of a held input)."""
    fmu, h = fmus["StateSpace3"], 0.1
    u1 = np.array([1.0, -0.5])
    _, c = run(tmp_path, f"""experiment: {{stop: 1.0, step: {h}}}
components:
  first: {{fmu: {fmu}, interface: CS, parameters: {{u: [1.0, -0.5]}}}}
  second: {{fmu: {fmu}, interface: CS}}
  third: {{fmu: {fmu}, interface: CS, parameters: {{u: [0.0, 0.25]}}}}
connections:
  - {{from: first.y, to: second.u}}
  - {{from: 'first.y[2]', to: 'third.u[1]'}}
outputs: ['*.x[*]', '*.y[*]', '*.u[*]']
""")
    n = len(c["time"])
    x1 = state_space(c["time"], u1)
    y1 = x1 @ C.T + D @ u1
    Ad = expm(A * h)
    Bd = np.linalg.solve(A, (Ad - np.eye(3)) @ B)
    x2, x3 = [X0], [X0]
    for k in range(1, n):  # the inputs held over step k: first's outputs at its end
        x2.append(Ad @ x2[-1] + Bd @ y1[k])
        x3.append(Ad @ x3[-1] + Bd @ np.array([y1[k, 1], 0.25]))
    got = {name: np.column_stack([c[f"{name}.x[{i}]"] for i in (1, 2, 3)]) for name in ("first", "second", "third")}
    np.testing.assert_allclose(got["first"], x1, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got["second"], np.array(x2), rtol=0, atol=1e-9)
    np.testing.assert_allclose(got["third"], np.array(x3), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(c["third.u[2]"], 0.25)  # the element no connection drives
    np.testing.assert_allclose(c["second.u[1]"][1:], y1[1:, 0], rtol=0, atol=1e-9)


def pair(fmu: Path, source: str, target: str) -> str:
    """A scenario of two instances ``a`` and ``b`` of ``fmu`` with one connection."""
    return (f"experiment: {{stop: 0.2, step: 0.1}}\ncomponents:\n  a: {{fmu: {fmu}}}\n  b: {{fmu: {fmu}}}\n"
            f"connections:\n  - {{from: {source}, to: {target}}}\n")


def test_fixed_steps_of_fmi3_units_run_in_c_with_the_same_bits(fmus, tmp_path):
    """The C loop takes FMI 3.0 units (Float64, Int32 and Boolean values, fmi3DoStep, arrays by
    element); an event in a Co-Simulation step (early return) hands the step back to Python. Same
    rows, bit for bit, as the Python loop."""
    from deltafmi.master.stepping.c_loop import NativeLoop
    path = tmp_path / "c.yaml"
    path.write_text(f"""experiment: {{stop: 2.0, step: 0.01}}
components:
  ball: {{fmu: {fmus['BouncingBall3']}, interface: CS}}
  ss: {{fmu: {fmus['StateSpace3']}, interface: CS}}
  osc: {{source: deltafmi.models:Oscillator, fmi_version: 3, interface: CS, parameters: {{t_step: 1.0}}}}
  types: {{fmu: {fmus['AllTypes3']}, interface: CS, parameters: {{invert: true}}}}
connections:
  - {{from: ball.h, to: 'ss.u[2]'}}
  - {{from: osc.force_on, to: types.u_bool}}
outputs: [ball.h, ball.bounces, 'ss.x[*]', 'ss.y[*]', osc.force_on, types.y_bool]
""")
    rows = {}
    for native in (True, False):
        master = Master(resolve_system(load_scenario(path)), result=tmp_path / f"{native}.csv", native=native)
        if native:
            master.open()
            assert NativeLoop.fits(master.stepping_blocks(), master.sampler)
            master.close()
            master = Master(resolve_system(load_scenario(path)), result=tmp_path / f"{native}.csv", native=native)
        assert master.run().events >= 4  # the ball's impacts at 0.45, 1.08, 1.53 and 1.84 s, the oscillator's
        rows[native] = (tmp_path / f"{native}.csv").read_text()
    assert rows[True] == rows[False]
    c = columns(tmp_path / "True.csv")
    assert c["osc.force_on"][-1] == 1 and np.array_equal(c["types.y_bool"][1:], 1 - c["osc.force_on"][1:])


def test_array_shapes_must_agree(fmus, tmp_path):
    message = problems(tmp_path, pair(fmus["StateSpace3"], "a.x", "b.u"))
    assert "the arrays differ in shape: 'a.x' is [3] but 'b.u' is [2]" in message


# --- every FMI 3.0 type through the buses ----------------------------------------------------------

EXTREMES = {"u_f32": 0.1, "u_f64": -1.5e300, "u_i8": -128, "u_u8": 255, "u_i16": -32768, "u_u16": 65535,
            "u_i32": -2 ** 31, "u_u32": 2 ** 32 - 1, "u_i64": -2 ** 63, "u_u64": 2 ** 64 - 1, "u_bool": True,
            "u_str": "naïve, \"quoted\"", "u_color": "blue"}


def test_every_type_passes_through_the_buses_exactly(fmus, tmp_path):
    """AllTypes3 passes each input through to an output: source's outputs drive sink's inputs,
    one connection per FMI 3.0 type. Every value arrives exactly: the 64-bit extremes (Int64,
    UInt64 travel on 64-bit buses), a Float32 as its float32 rounding, the Enumeration's item."""
    fmu = fmus["AllTypes3"]
    values = ", ".join(f"{k}: {v!r}" if not isinstance(v, bool) else f"{k}: true" for k, v in EXTREMES.items())
    connections = "\n".join(f"  - {{from: source.y_{name[2:]}, to: sink.u_{name[2:]}}}" for name in EXTREMES)
    path = tmp_path / "types.yaml"
    path.write_text(f"""experiment: {{stop: 0.2, step: 0.1}}
components:
  source: {{fmu: {fmu}, parameters: {{{values}, prefix: ''}}}}
  sink: {{fmu: {fmu}, parameters: {{prefix: ''}}}}
connections:
{connections}
outputs: ['sink.y_*']
""")
    master = Master(resolve_system(load_scenario(path)), result=tmp_path / "types.csv")
    master.open()
    try:
        master.step_all(master.stepping_blocks(), 0.0, 0.1)
        sink = master._by_name["sink"]
        ports = {p.name: p for p in master.system.recorded}
        got = {name: sink.get_value(ports[f"y_{name[2:]}"]) for name in EXTREMES}
    finally:
        master.close()
    expected = dict(EXTREMES, u_f32=float(np.float32(0.1)), u_color=3)
    assert got == expected
    assert got["u_f32"] != 0.1


def with_clocks(fmu: Path, out: Path) -> Path:
    """A copy of ``fmu`` whose modelDescription also declares an input and an output Clock."""
    clocks = ('<Clock name="tick" valueReference="100" causality="input" intervalVariability="constant" '
              'intervalDecimal="0.001"/>\n<Clock name="tock" valueReference="101" causality="output" '
              'intervalVariability="triggered"/>\n</ModelVariables>')
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(out, "w") as copy:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                data = data.decode().replace("</ModelVariables>", clocks).encode()
            copy.writestr(item, data)
    return out


def test_binary_and_clock_variables_are_not_connected(fmus, tmp_path):
    message = problems(tmp_path, pair(fmus["AllTypes3"], "a.y_bin", "b.u_bin"))
    assert "'a.y_bin' is a Binary variable, which the master does not exchange" in message
    clocked = with_clocks(fmus["StateSpace3"], tmp_path / "Clocked.fmu")
    message = problems(tmp_path, pair(clocked, "a.tock", "b.tick"))
    assert "'a.tock' is a Clock variable, which the master does not exchange" in message


def test_types_must_match_across_fmi_versions(fmus, tmp_path):
    """FMI 2.0's Real is FMI 3.0's Float64 (our oscillator's energy drives StateSpace3's u[1]);
    a Float32 is not a Real."""
    _, c = run(tmp_path, f"""experiment: {{stop: 0.2, step: 0.1}}
components:
  osc: {{source: deltafmi.models:Oscillator, interface: CS}}
  ss: {{fmu: {fmus['StateSpace3']}, interface: CS}}
connections:
  - {{from: osc.energy, to: 'ss.u[1]'}}
outputs: ['ss.u[1]', osc.energy]
""")
    np.testing.assert_array_equal(c["ss.u[1]"][1:], c["osc.energy"][1:])
    message = problems(tmp_path, f"""experiment: {{stop: 0.2, step: 0.1}}
components:
  osc: {{source: deltafmi.models:Oscillator}}
  types: {{fmu: {fmus['AllTypes3']}}}
connections:
  - {{from: osc.energy, to: types.u_f32}}
""")
    assert "type mismatch: 'osc.energy' is Real but 'types.u_f32' is Float32" in message


# --- connected to our own FMUs, built as FMI 2.0 and as FMI 3.0 ------------------------------------

@pytest.mark.parametrize("ours", [2, 3])
@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_bouncing_ball_pushes_our_oscillator(fmus, tmp_path, interface, ours):
    """BouncingBall3's height, through a 2 N/m spring, is the force on our oscillator (built as
    FMI 2.0 or 3.0): each step the oscillator sees a constant force, so it follows the
    closed-form damped oscillation step by step with the force it recorded."""
    h = 0.01
    _, c = run(tmp_path, f"""experiment: {{stop: 2.0, step: {h}}}
components:
  ball: {{fmu: {fmus['BouncingBall3']}, interface: {interface}, solver: {{rtol: 1.0e-12}}}}
  osc: {{source: deltafmi.models:Oscillator, fmi_version: {ours}, interface: CS,
         parameters: {{wall: -100.0, t_step: 100.0}}, solver: {{rtol: 1.0e-12}}}}
connections:
  - {{from: ball.h, to: osc.F, factor: 2.0}}
outputs: [ball.h, osc.F, osc.x, osc.v]
""")
    assert ball_drives_oscillator(c, h) <= 1e-9


FOLLOWER = '''"""Follows a gear given as an Enumeration input."""
import enum

from deltafmi.component import Component, Experiment, Input, Output


class Gear(enum.IntEnum):
    LOW = 1
    HIGH = 2
    REVERSE = 3


class Follower(Component):
    default_experiment = Experiment(stop=0.3, step=0.1)
    gear = Input(Gear.LOW, description="The gear to follow")
    ratio = Output(unit="1")
    seen = Output(type=Gear)
    direct_feedthrough = {"ratio": ["gear"], "seen": ["gear"]}

    def outputs(self, t):
        self.ratio = {Gear.LOW: 1.0, Gear.HIGH: 3.0, Gear.REVERSE: -1.0}[Gear(self.gear)]
        self.seen = self.gear
'''


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_enumerations_travel_as_int64_between_our_fmi3_fmus(tmp_path, interface):
    """Gearbox (FMI 3.0) in gear REVERSE from the scenario's parameters: y = -1 * u; its
    Enumeration output engaged drives the Enumeration input of a follower (FMI 3.0), which sees
    REVERSE (3) and its ratio -1: set and got with fmi3Set/GetInt64, as FMI 3.0 defines them."""
    (tmp_path / "follower.py").write_text(FOLLOWER)
    gearbox = Path(__file__).parents[1] / "components" / "gearbox" / "model.py"
    _, c = run(tmp_path, f"""experiment: {{stop: 0.3, step: 0.1}}
components:
  box: {{source: {gearbox}, fmi_version: 3, interface: {interface}, parameters: {{gear: REVERSE, u: 2.5}}}}
  f: {{source: {tmp_path / 'follower.py'}, fmi_version: 3, interface: {interface}}}
connections:
  - {{from: box.engaged, to: f.gear}}
outputs: [box.y, box.engaged, f.gear, f.seen, f.ratio]
""")
    assert len(c["time"]) == 4
    for name, value in {"box.y": -2.5, "box.engaged": 3, "f.gear": 3, "f.seen": 3, "f.ratio": -1.0}.items():
        assert list(c[name]) == [value] * 4, name


# --- the flagship built as FMI 3.0 ---------------------------------------------------------------

def flagship_of(scenario, **options) -> dict:
    """The wrist position, torques and controller status of a run of ``scenario``: {column: values}."""
    from deltafmi import simulate
    result = simulate(scenario, record=["plant.z[*]", "controller.u[*]", "controller.status"], **options)
    return {name: np.asarray(result[name]) for name in ["time", *result.names]}


def flagship(**options) -> dict:
    """The flagship's (delta_tracking) wrist position, torques and controller status."""
    return flagship_of("delta_tracking", **options)


def test_flagship_built_as_fmi3_equals_fmi2():
    """delta_tracking with its three FMUs built as FMI 3.0 (arrays connected whole: trajectory.r
    -> controller.r, controller.u -> plant.u, ...) equals the FMI 2.0 flagship to 1e-9 m."""
    fmi2 = flagship()
    fmi3 = flagship(fmi_version=3)
    assert list(fmi2) == list(fmi3) and len(fmi3["time"]) == 3501
    for i in (1, 2, 3):
        assert np.max(np.abs(fmi3[f"plant.z[{i}]"] - fmi2[f"plant.z[{i}]"])) <= 1e-9
    assert np.array_equal(fmi3["controller.status"], fmi2["controller.status"])


def test_fmi3_and_fmi2_components_connect_array_to_array():
    """The flagship with only the plant built as FMI 3.0: its array outputs y, yd drive the FMI 2.0
    controller's scalarized arrays and the controller's u drives the plant's array input; the
    same run as the FMI 2.0 flagship."""
    from dataclasses import replace

    from deltafmi.master.scenario.spec import load_scenario as load
    scenario = load("delta_tracking")
    mixed = replace(scenario, components=tuple(replace(spec, fmi_version=3) if spec.name == "plant" else spec
                                               for spec in scenario.components))
    fmi2, ours = flagship(), flagship_of(mixed)
    for i in (1, 2, 3):
        assert np.max(np.abs(ours[f"plant.z[{i}]"] - fmi2[f"plant.z[{i}]"])) <= 1e-9


# --- an FMU that ends the simulation, one that reads its resources ---------------------------------

@pytest.fixture(scope="module")
def more_fmus(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("third_party3_more")
    return {model: build_fmu(model, out) for model in ("Stopper3", "Table3")}


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_terminating_fmu_ends_the_run_at_its_time(more_fmus, tmp_path, interface):
    """Stopper3 samples our oscillator's energy (FMI 3.0 build) every 0.25 s and sets terminateSimulation at
    its stop_time 1.55 s (a time event inside a communication step): the run ends cleanly there,
    its last row at 1.55 s with the sample taken at 1.5 s (held since)."""
    summary, c = run(tmp_path, f"""experiment: {{stop: 3.0, step: 0.1}}
components:
  osc: {{source: deltafmi.models:Oscillator, fmi_version: 3, interface: CS}}
  stop: {{fmu: {more_fmus['Stopper3']}, interface: {interface}}}
connections:
  - {{from: osc.energy, to: stop.u}}
outputs: [osc.energy, stop.held, stop.samples, stop.stopped]
""")
    assert summary.terminated is not None
    assert (summary.terminated.component, summary.terminated.time) == ("stop", pytest.approx(1.55, abs=1e-12))
    assert c["time"][-1] == pytest.approx(1.55, abs=1e-12)
    at = np.flatnonzero(np.abs(c["time"] - 1.5) < 1e-9)[0]
    assert c["stop.held"][-1] == c["osc.energy"][at]
    assert c["stop.samples"][-1] - c["stop.samples"][0] == 6  # sampled at t = 0.25, 0.5, ..., 1.5
    assert c["stop.stopped"][-1] == 1


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_an_event_an_ulp_after_a_grid_point_is_recorded_at_it(more_fmus, tmp_path, interface):
    """Stopper3 samples every 0.07 s: its third sample time 3 * 0.07 = 0.21000000000000002 is one
    ulp after the grid point 0.21 (and the step from 0.2 ends at 0.2 + 0.01, that same ulp
    late). The rows never go back in time: the sample's rows (before, after) are at 0.21."""
    _, c = run(tmp_path, f"""experiment: {{stop: 0.3, step: 0.01}}
components:
  stop: {{fmu: {more_fmus['Stopper3']}, interface: {interface}, parameters: {{period: 0.07, stop_time: 10.0}}}}
outputs: [stop.samples]
""")
    assert 3 * 0.07 == np.nextafter(0.21, 1.0)
    assert np.all(np.diff(c["time"]) >= 0)
    rows = np.flatnonzero(np.abs(c["time"] - 0.21) < 1e-12)
    assert list(c["time"][rows]) == [0.21, 0.21] and list(c["stop.samples"][rows]) == [2, 3]


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_event_rows_of_units_in_one_step_come_in_time_order(fmus, tmp_path, interface):
    """Two balls dropped from 1 m and 0.98 m hit the ground at 0.4515 s and 0.4470 s, in one
    0.1 s step; the ball stepped first bounces later. The rows come in time order, each ball's
    impact rows (before, after) at its closed-form time. (The other ball's column in an event
    row shows it as it is then in the step: a unit steps whole, one after the other.)"""
    _, c = run(tmp_path, f"""experiment: {{stop: 0.6, step: 0.1}}
master: {{algorithm: jacobi}}
components:
  a: {{fmu: {fmus['BouncingBall3']}, interface: {interface}, solver: {{rtol: 1.0e-12}}}}
  b: {{fmu: {fmus['BouncingBall3']}, interface: {interface}, solver: {{rtol: 1.0e-12}}, parameters: {{h: 0.98}}}}
outputs: [a.bounces, b.bounces]
""")
    assert np.all(np.diff(c["time"]) >= 0)
    for ball, height in (("a", 1.0), ("b", 0.98)):
        rows = np.flatnonzero(np.abs(c["time"] - np.sqrt(2 * height / 9.81)) < 1e-9)
        assert list(c[f"{ball}.bounces"][rows]) == [0, 1]


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_table_reads_its_resources_driven_by_ours(more_fmus, tmp_path, interface):
    """Table3 interpolates the table it read from its resources at instantiation; our oscillator
    (FMI 2.0 build) drives it: y = table(energy / 2) at every communication point."""
    table = np.loadtxt(Path(__file__).parents[1] / "third_party" / "Table3" / "resources" / "table.txt")
    _, c = run(tmp_path, f"""experiment: {{stop: 1.0, step: 0.1}}
components:
  osc: {{source: deltafmi.models:Oscillator, interface: CS}}
  table: {{fmu: {more_fmus['Table3']}, interface: {interface}}}
connections:
  - {{from: osc.energy, to: table.u, factor: 0.5}}
outputs: [osc.energy, table.y]
""")
    np.testing.assert_allclose(c["table.y"][1:], np.interp(0.5 * c["osc.energy"][1:], table[:, 0], table[:, 1]),
                               rtol=0, atol=1e-12)


# --- SSP, info, validate, the scenario's fmi_version -----------------------------------------------

def cli(*args: str) -> str:
    result = CliRunner().invoke(main, list(args), catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result.output


def test_ssp_carries_fmi3_components(fmus, tmp_path):
    """export-ssp of a scenario with FMI 3.0 components (an array connected whole and by
    element, a component built from source as FMI 3.0), run back: the same results."""
    scenario = tmp_path / "arrays.yaml"
    scenario.write_text(f"""experiment: {{stop: 0.5, step: 0.1}}
components:
  first: {{fmu: {fmus['StateSpace3']}, interface: ME, parameters: {{u: [1.0, -0.5]}}}}
  second: {{fmu: {fmus['StateSpace3']}, interface: CS}}
  osc: {{source: deltafmi.models:Oscillator, fmi_version: 3, interface: CS}}
connections:
  - {{from: first.y, to: second.u}}
  - {{from: 'second.y[2]', to: osc.F, factor: 1.0}}
outputs: ['second.x[*]', osc.x]
""")
    cli("run", str(scenario), "-q", "-o", str(tmp_path / "direct.csv"))
    cli("export-ssp", str(scenario), "-o", str(tmp_path / "arrays.ssp"))
    cli("run", str(tmp_path / "arrays.ssp"), "-q", "-o", str(tmp_path / "ssp.csv"))
    direct, back = columns(tmp_path / "direct.csv"), columns(tmp_path / "ssp.csv")
    assert list(direct) == list(back)
    for name in direct:
        np.testing.assert_array_equal(back[name], direct[name])


def test_info_and_validate_handle_fmi3(fmus, tmp_path):
    shown = cli("info", str(fmus["StateSpace3"]))
    assert "(FMI 3.0, Model Exchange, Co-Simulation)" in shown
    assert "Float64[3,3]" in shown and "Float64[2]" in shown
    assert cli("validate", str(fmus["StateSpace3"])).splitlines()[-1].endswith("OK (instantiated and freed once)")
    shown = cli("info", str(with_clocks(fmus["StateSpace3"], tmp_path / "Clocked.fmu")))
    assert "clocks: tick (input, constant, interval 0.001 s), tock (output, triggered)" in shown
    assert "\ntick " not in shown  # listed as a clock, not as a variable
    scenario = tmp_path / "s.yaml"
    scenario.write_text(pair(fmus["StateSpace3"], "a.y", "b.u"))
    assert "2 components, 2 scalar connections" in cli("validate", str(scenario))


def test_fmi_version_of_a_given_fmu_is_checked(fmus, tmp_path):
    message = problems(tmp_path, f"""experiment: {{stop: 0.2, step: 0.1}}
components:
  ss: {{fmu: {fmus['StateSpace3']}, fmi_version: 2}}
""")
    assert "FMU 'StateSpace3.fmu' is an FMI 3.0 FMU, not FMI 2.0 as its fmi_version says" in message


def test_run_builds_sources_as_fmi3_on_request(tmp_path):
    """`deltafmi run --fmi-version 3` builds a scenario's source: components as FMI 3.0 FMUs."""
    scenario = tmp_path / "osc.yaml"
    scenario.write_text("experiment: {stop: 0.1, step: 0.01}\n"
                        "components:\n  osc: {source: deltafmi.models:Oscillator, interface: CS}\n")
    system = resolve_system(load_scenario(scenario))
    assert system.components[0].info.md.fmiVersion == "2.0"
    from deltafmi.master.scenario.overrides import with_overrides
    system = resolve_system(with_overrides(load_scenario(scenario), fmi_version=3))
    assert system.components[0].info.md.fmiVersion == "3.0"
    assert "osc: CS Oscillator, FMI 3.0 (" in cli("validate", str(scenario), "--fmi-version", "3")
    cli("run", str(scenario), "--fmi-version", "3", "-q", "-o", str(tmp_path / "osc3.csv"))
    cli("run", str(scenario), "-q", "-o", str(tmp_path / "osc2.csv"))
    three, two = columns(tmp_path / "osc3.csv"), columns(tmp_path / "osc2.csv")
    np.testing.assert_allclose(three["osc.energy"], two["osc.energy"], rtol=0, atol=1e-9)
