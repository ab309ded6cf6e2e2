"""Third-party FMUs in our master: the plain-C FMUs of tests/third_party (no Python inside, ME and
CS in one binary, in the style of the FMI Reference FMUs) pass fmpy's validation, run through the
master alone and connected to our own FMUs, and agree with ``fmpy.simulate_fmu`` on the same grid
(1e-9, events at the same times). A Co-Simulation FMU that ends the simulation (fmi2Discard with
fmi2Terminated) and a Model Exchange FMU that sets terminateSimulation both end the run cleanly.
String and Enumeration variables work as parameters, connections and recorded columns.
"""
from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import fmpy
import numpy as np
import pytest
from click.testing import CliRunner
from fmpy.validation import validate_fmu

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns
from deltafmi.master.results.progress import Termination
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from oscillator_analytic import _free
from third_party.build import MODELS, build_all

INTERFACES = {"CS": "CoSimulation", "ME": "ModelExchange"}
TABLE = np.loadtxt(Path(__file__).parents[1] / "third_party" / "LookupTable" / "resources" / "table.txt")


@pytest.fixture(scope="session")
def third_party(tmp_path_factory) -> dict:
    """``{model: .fmu}`` of every C model, compiled once per session."""
    return build_all(tmp_path_factory.mktemp("third_party"))


def run(tmp_path: Path, text: str, name: str = "run"):
    """Run the scenario ``text`` through the master: (summary, result columns)."""
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    summary = Master(resolve_system(load_scenario(path)), result=tmp_path / f"{name}.csv").run()
    return summary, columns(tmp_path / f"{name}.csv")


def first_on_grid(c: dict, step: float) -> np.ndarray:
    """Row indices of the communication points: the first row at each multiple of ``step``
    (later rows at that time, up to round-off, are events found during the next step)."""
    t = c["time"]
    on_grid = np.abs(t / step - np.round(t / step)) < 1e-9
    first = np.r_[True, np.diff(t) > 1e-12]
    return np.nonzero(on_grid & first)[0]


# --- the FMUs themselves ------------------------------------------------------------------------

@pytest.mark.parametrize("model", MODELS)
def test_fmus_are_valid_plain_c(third_party, tmp_path, model):
    fmu = third_party[model]
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    assert md.modelExchange is not None and md.coSimulation is not None
    binary = Path(fmpy.extract(str(fmu), unzipdir=str(tmp_path))) / "binaries" / "linux64" / f"{model}.so"
    exported = subprocess.run(["nm", "-D", "--defined-only", binary], capture_output=True, text=True,
                              check=True).stdout.split()
    functions = [name for kind, name in zip(exported[1::3], exported[2::3]) if kind == "T"]
    assert functions and all(name.startswith("fmi2") for name in functions)
    linked = subprocess.run(["ldd", binary], capture_output=True, text=True, check=True).stdout
    assert "python" not in linked


def test_units_and_me_integrator_do_not_import_each_other():
    code = ("import sys, deltafmi.master.stepping.me_integrator; "
            "assert 'deltafmi.master.stepping.units' not in sys.modules, 'me_integrator imports units'")
    subprocess.run([sys.executable, "-c", code], check=True)
    source = (Path(__file__).parents[2] / "deltafmi" / "master" / "stepping" / "unit_base.py").read_text()
    assert "me_integrator" not in source.split('"""', 2)[2]


# --- alone: the master against fmpy.simulate_fmu --------------------------------------------------

ALONE = {
    # model: (stop, step, parameters, recorded outputs, ME rtol)
    "AllTypes": (1.0, 0.1, {"gain": 3.0, "u": 1.5, "offset": 4, "u_int": 7, "invert": True,
                            "tint": 3, "u_color": 2}, ["y", "x", "y_int", "y_bool", "y_color"], 1e-10),
    "Ticker": (3.0, 0.1, {"u": 0.25, "period": 0.35, "max_ticks": 5}, ["held", "phase", "ticks"], 1e-10),
    "LookupTable": (0.5, 0.1, {"u": 0.3}, ["y", "rows"], 1e-10),
    # state events: CVODE finds them to within its tolerance, in fmpy and in the master
    "BouncingBall": (3.0, 0.01, {"e": 0.7}, ["h", "v", "bounces"], 1e-12),
    "Oscillator": (2.0, 0.01, {"k": 4.0, "c": 0.3, "F": 0.5}, ["x", "v"], 1e-12),
}


def _yaml_value(value) -> str:
    return str(value).lower() if isinstance(value, bool) else repr(value)


@pytest.mark.parametrize("interface", ["CS", "ME"])
@pytest.mark.parametrize("model", MODELS)
def test_alone_agrees_with_fmpy(third_party, tmp_path, model, interface):
    stop, step, parameters, outputs, rtol = ALONE[model]
    fmu = third_party[model]
    values = ", ".join(f"{k}: {_yaml_value(v)}" for k, v in parameters.items())
    summary, ours = run(tmp_path, f"experiment: {{stop: {stop}, step: {step}}}\n"
                                  f"components:\n  m: {{fmu: {fmu}, interface: {interface}, "
                                  f"parameters: {{{values}}}, solver: {{rtol: {rtol}}}}}\n"
                                  f"outputs: [{', '.join('m.' + o for o in outputs)}]\n")
    theirs = fmpy.simulate_fmu(str(fmu), fmi_type=INTERFACES[interface], stop_time=stop, output_interval=step,
                               start_values=parameters, output=outputs, relative_tolerance=rtol)
    n = len(theirs)
    extra = 0
    if model == "Ticker":
        # the master ends at the terminating tick with a last row of the values it left there;
        # under ME fmpy records the row before that event and stops
        assert summary.terminated == Termination("m", 1.75)
        assert ours["time"][-1] == 1.75 and ours["m.ticks"][-1] == 5 and ours["m.phase"][-1] == 0.0
        extra = interface == "ME"
    assert len(ours["time"]) == n + extra
    # the same rows: events (two rows at one time) at the same times
    np.testing.assert_allclose(ours["time"][:n], theirs["time"], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(np.diff(ours["time"][:n]) == 0, np.diff(theirs["time"]) == 0)
    for name in outputs:
        deviation = np.max(np.abs(ours[f"m.{name}"][:n] - theirs[name].astype(float)))
        print(f"{model} {interface} {name}: max deviation from fmpy {deviation:.2e}")
        assert deviation <= 1e-9, name


def ball_exact(times: np.ndarray, h0: float = 1.0, g: float = 9.81, e: float = 0.7, v_min: float = 0.1):
    """Height of the bouncing ball in closed form (parabolas between impacts) and impact times."""
    impacts, t, v = [], np.sqrt(2 * h0 / g), np.sqrt(2 * g * h0)
    while True:
        impacts.append(t)
        v *= e
        if v < v_min:
            break
        t += 2 * v / g
    h = np.zeros_like(times)
    h[times < impacts[0]] = h0 - 0.5 * g * times[times < impacts[0]] ** 2
    speed = np.sqrt(2 * g * h0)
    for start, end in zip(impacts, impacts[1:]):
        speed *= e
        inside = (times >= start) & (times < end)
        tau = times[inside] - start
        h[inside] = speed * tau - 0.5 * g * tau ** 2
    return h, impacts


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_bouncing_ball_matches_closed_form(third_party, tmp_path, interface):
    _, c = run(tmp_path, f"experiment: {{stop: 3.0, step: 0.01}}\n"
                         f"components:\n  ball: {{fmu: {third_party['BouncingBall']}, interface: {interface}, "
                         "solver: {rtol: 1.0e-12}}\n")
    h, impacts = ball_exact(c["time"])
    np.testing.assert_allclose(c["ball.h"], h, rtol=0, atol=1e-9)
    assert c["ball.bounces"][-1] == len(impacts) == 11  # at rest after the 11th
    if interface == "ME":  # each impact is an event: two rows at its time
        t = c["time"]
        np.testing.assert_allclose(t[1:][t[1:] == t[:-1]], impacts, rtol=0, atol=1e-9)


# --- connected to our own FMUs ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def oscillator(build_fmu_from_src) -> Path:
    return build_fmu_from_src("oscillator.py")


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_all_types_driven_by_our_oscillator(third_party, oscillator, tmp_path, interface):
    """Real, Integer and Boolean outputs of our oscillator drive AllTypes: y = gain energy on every
    row, y_int = impacts + offset and y_bool = force_on xor invert at every communication point,
    and its state integrates the held input exactly (a right Riemann sum of the energy)."""
    h, gain = 0.01, -2.0
    summary, c = run(tmp_path, f"""experiment: {{stop: 3.0, step: {h}}}
components:
  osc: {{fmu: {oscillator}, interface: CS}}
  mt: {{fmu: {third_party['AllTypes']}, interface: {interface}, parameters: {{gain: {gain}, offset: 10, invert: true}},
        solver: {{rtol: 1.0e-12}}}}
connections:
  - {{from: osc.energy, to: mt.u}}
  - {{from: osc.impacts, to: mt.u_int}}
  - {{from: osc.force_on, to: mt.u_bool}}
outputs: [osc.energy, osc.impacts, osc.force_on, mt.y, mt.x, mt.y_int, mt.y_bool]
""")
    grid = first_on_grid(c, h)
    np.testing.assert_array_equal(c["mt.y"][grid], gain * c["osc.energy"][grid])
    # an event row between shows the oscillator as of its step's start (no row shows a later time's
    # value) and AllTypes with the input it took: the oscillator's energy then, or at the step's end
    # (Gauss-Seidel stepped the oscillator first): the next communication point's row
    for i in np.setdiff1d(np.arange(len(c["time"])), grid):
        after = grid[np.searchsorted(grid, i)] if i < grid[-1] else i
        assert c["mt.y"][i] in (gain * c["osc.energy"][i], gain * c["osc.energy"][after]), i
    assert len(grid) == 301
    assert c["osc.impacts"][-1] >= 2 and c["osc.force_on"][-1] == 1  # both change during the run
    np.testing.assert_array_equal(c["mt.y_int"][grid], c["osc.impacts"][grid] + 10)
    np.testing.assert_array_equal(c["mt.y_bool"][grid], 1 - c["osc.force_on"][grid])
    riemann = np.r_[0.0, np.cumsum(h * gain * c["osc.energy"][grid][1:])]
    deviation = np.max(np.abs(c["mt.x"][grid] - riemann))
    print(f"AllTypes {interface} driven by the oscillator: integral vs Riemann sum {deviation:.1e}")
    assert deviation <= 1e-9
    # discrete inputs change in event mode under ME: one event per change of impacts or force_on
    changes = np.count_nonzero(np.diff(c["osc.impacts"][grid])) + np.count_nonzero(np.diff(c["osc.force_on"][grid]))
    assert summary.events == (changes if interface == "ME" else 0)


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_lookup_table_of_our_oscillator(third_party, oscillator, tmp_path, interface):
    _, c = run(tmp_path, f"""experiment: {{stop: 2.0, step: 0.01}}
components:
  osc: {{fmu: {oscillator}, interface: CS}}
  table: {{fmu: {third_party['LookupTable']}, interface: {interface}}}
connections:
  - {{from: osc.energy, to: table.u, factor: 0.2, offset: -1.5}}
outputs: [osc.energy, table.u, table.y, table.rows]
""")
    assert np.all(c["table.rows"] == len(TABLE))
    np.testing.assert_allclose(c["table.u"], 0.2 * c["osc.energy"] - 1.5, rtol=1e-15, atol=1e-15)
    assert c["table.u"].min() < 0 and c["table.u"].max() > 1  # sweeps the table and beyond its end
    np.testing.assert_allclose(c["table.y"], np.interp(c["table.u"], TABLE[:, 0], TABLE[:, 1]), rtol=0, atol=1e-12)


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_ticker_samples_our_oscillator_and_ends_the_run(third_party, oscillator, tmp_path, interface):
    """The ticker holds the oscillator's energy at each tick: Gauss-Seidel steps the oscillator
    first, so a tick inside a step sees the energy at the end of that step. It ends the run at its
    5th tick."""
    h, period = 0.1, 0.35
    summary, c = run(tmp_path, f"""experiment: {{stop: 3.0, step: {h}}}
components:
  osc: {{fmu: {oscillator}, interface: CS}}
  ticker: {{fmu: {third_party['Ticker']}, interface: {interface}, parameters: {{period: {period}}}}}
connections:
  - {{from: osc.energy, to: ticker.u}}
outputs: [osc.energy, ticker.held, ticker.ticks]
""")
    assert summary.terminated == Termination("ticker", 5 * period)
    assert c["time"][-1] == 5 * period and c["ticker.ticks"][-1] == 5
    for tick in range(1, 6):
        row = np.argmax(c["ticker.ticks"] == tick)  # the first row after the tick
        # CS shows a tick at the end of its step, ME at its time (an event); the last row is
        # at the time the ticker terminated, in both
        at_step_end = interface == "CS" and tick < 5
        seen = np.ceil(tick * period / h - 1e-9) * h if at_step_end else tick * period
        assert abs(c["time"][row] - seen) < 1e-12
        # the energy the ticker took is the oscillator's at the end of the step (Gauss-Seidel stepped
        # it first); an event row inside a step shows the oscillator as of the step's start (no row
        # shows a later time's value), so that energy is in the row at the step's end
        step_end = np.ceil(tick * period / h - 1e-9) * h if tick < 5 else tick * period
        end_row = np.flatnonzero(np.abs(c["time"] - step_end) < 1e-12)[-1]
        assert c["ticker.held"][row] == c["osc.energy"][end_row]


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_bouncing_ball_pushes_our_oscillator(third_party, oscillator, tmp_path, interface):
    """The ball's height, through a 2 N/m spring (factor: m -> N), is the force on our oscillator
    (no wall, no force step): each communication step the oscillator sees a constant force, so
    it must follow the closed-form damped oscillation step by step with the force it recorded."""
    h = 0.01
    _, c = run(tmp_path, f"""experiment: {{stop: 2.0, step: {h}}}
components:
  ball: {{fmu: {third_party['BouncingBall']}, interface: {interface}, solver: {{rtol: 1.0e-12}}}}
  osc: {{fmu: {oscillator}, interface: CS, parameters: {{wall: -100.0, t_step: 100.0}}, solver: {{rtol: 1.0e-12}}}}
connections:
  - {{from: ball.h, to: osc.F, factor: 2.0}}
outputs: [ball.h, osc.F, osc.x, osc.v]
""")
    deviation = ball_drives_oscillator(c, h)
    print(f"oscillator driven by the ball ({interface}): relative deviation from the closed form {deviation:.1e}")
    assert deviation <= 1e-9


def ball_drives_oscillator(c: dict, h: float) -> float:
    """Check ``osc.F`` = 2 N/m times the ball's closed-form height at every communication point;
    return how far ``osc.x`` and ``osc.v`` are from the closed-form damped oscillation driven by
    that force held over each step (relative to their amplitudes)."""
    grid = first_on_grid(c, h)
    force, x_master, v_master = c["osc.F"][grid], c["osc.x"][grid], c["osc.v"][grid]
    np.testing.assert_allclose(force[1:], 2.0 * ball_exact(c["time"][grid][1:])[0], rtol=0, atol=1e-9)
    x, v = [1.0], [0.0]  # the oscillator starts at rest at x = 1 m
    for k in range(1, len(grid)):  # force[k]: set before the step that ends at row k
        xk, vk = _free(x[-1], v[-1], force[k], h)
        x.append(xk)
        v.append(vk)
    # relative to the amplitudes (|x| <= 1 m, |v| <= 6.3 m/s): our oscillator integrates with
    # CVODE at rtol 1e-12, restarted at every step (its input jumps), over 200 steps
    return max(np.max(np.abs(x_master - x)) / np.max(np.abs(x)), np.max(np.abs(v_master - v)) / np.max(np.abs(v)))


# --- String and Enumeration variables -------------------------------------------------------------

QUOTED = 'He said "stop, now", '


@pytest.mark.parametrize("interfaces", [("CS", "ME"), ("ME", "CS")])
def test_strings_and_enumerations_as_parameters_connections_and_columns(third_party, tmp_path, interfaces):
    """Parameters (a string with a comma and quotes; enumerations by item name and by value),
    String -> String and Enumeration -> Enumeration connections, and CSV columns: strings quoted
    by the csv module's rules, enumerations as integers."""
    fmu = third_party["AllTypes"]
    _, c = run(tmp_path, f"""experiment: {{stop: 0.3, step: 0.1}}
components:
  a: {{fmu: {fmu}, interface: {interfaces[0]}, parameters: {{prefix: '{QUOTED}', u_str: x, tint: green, u_color: 3}}}}
  b: {{fmu: {fmu}, interface: {interfaces[1]}, parameters: {{prefix: '', tint: blue}}}}
connections:
  - {{from: a.y_str, to: b.u_str}}
  - {{from: a.y_color, to: b.u_color}}
outputs: [a.prefix, a.y_str, a.y_color, b.u_str, b.y_str, b.u_color, b.y_color]
""")
    assert len(c["time"]) == 4
    for name, value in {"a.prefix": QUOTED, "a.y_str": QUOTED + "x", "b.u_str": QUOTED + "x",
                        "b.y_str": QUOTED + "x"}.items():
        assert list(c[name]) == [value] * 4, name
    # Color: red 1, green 2, blue 3; tint turns the wheel (red: not at all)
    assert list(c["a.y_color"]) == [1] * 4 and list(c["b.u_color"]) == [1] * 4  # blue turned by green
    assert list(c["b.y_color"]) == [3] * 4  # red turned by blue
    lines = (tmp_path / "run.csv").read_text().splitlines()
    assert lines[0] == "time,a.prefix,a.y_str,a.y_color,b.u_str,b.y_str,b.u_color,b.y_color"
    assert lines[1] == '0.0,"He said ""stop, now"", ","He said ""stop, now"", x",1,' \
                       '"He said ""stop, now"", x","He said ""stop, now"", x",1,3'
    with open(tmp_path / "run.csv", newline="") as file:
        assert list(csv.reader(file))[2][2] == QUOTED + "x"


def test_strings_agree_with_fmpy(third_party, tmp_path):
    """fmpy does not record strings: read y_str after each of its steps and compare."""
    fmu = third_party["AllTypes"]
    _, ours = run(tmp_path, f"experiment: {{stop: 0.3, step: 0.1}}\ncomponents:\n"
                            f"  a: {{fmu: {fmu}, parameters: {{prefix: '{QUOTED}', u_str: 'y,z', tint: 2}}}}\n"
                            "outputs: [a.y_str, a.y_color]\n")
    seen = []

    def read_string(time, recorder):
        seen.append(recorder.fmu.getString([32])[0].decode())  # y_str
        return True

    theirs = fmpy.simulate_fmu(str(fmu), stop_time=0.3, output_interval=0.1, output=["y_color"],
                               start_values={"prefix": QUOTED, "u_str": "y,z", "tint": 2}, step_finished=read_string)
    assert list(ours["a.y_str"][1:]) == seen == [QUOTED + "y,z"] * 3
    np.testing.assert_array_equal(ours["a.y_color"], theirs["y_color"])


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_discrete_inputs_reach_model_exchange_in_event_mode(third_party, oscillator, tmp_path, interface):
    """The ticker's label ("tick n") and held value (a discrete Real, scaled on the way) drive
    AllTypes' String and discrete Real inputs: under ME the master sets them in event mode (the
    FMU rejects them otherwise), one event per tick."""
    summary, c = run(tmp_path, f"""experiment: {{stop: 1.0, step: 0.1}}
components:
  osc: {{fmu: {oscillator}, interface: CS}}
  ticker: {{fmu: {third_party['Ticker']}, interface: CS, parameters: {{period: 0.25}}}}
  mt: {{fmu: {third_party['AllTypes']}, interface: {interface}, parameters: {{prefix: 'seen: ', gain: 3.0}}}}
connections:
  - {{from: osc.energy, to: ticker.u}}
  - {{from: ticker.label, to: mt.u_str}}
  - {{from: ticker.held, to: mt.u_discrete, factor: 2.0}}
outputs: [ticker.label, ticker.held, mt.y_str, mt.y_discrete]
""")
    grid = first_on_grid(c, 0.1)
    assert list(c["mt.y_str"][grid]) == ["seen: " + label for label in c["ticker.label"][grid]]
    np.testing.assert_allclose(c["mt.y_discrete"][grid], 3.0 * 2.0 * c["ticker.held"][grid], rtol=1e-15)
    assert c["ticker.label"][-1] == "tick 4" and len(set(c["ticker.held"])) == 5
    assert summary.events == (4 if interface == "ME" else 0)


def test_type_errors_name_file_and_line(third_party, tmp_path):
    fmu = third_party["AllTypes"]
    path = tmp_path / "bad.yaml"
    path.write_text(f"""experiment: {{stop: 1.0, step: 0.1}}
components:
  a: {{fmu: {fmu}, parameters: {{tint: gren}}}}
  b: {{fmu: {fmu}, parameters: {{tint: 7, u_color: true}}}}
connections:
  - {{from: a.y_str, to: b.u}}
  - {{from: a.y_color, to: b.u_int}}
  - {{from: a.y_int, to: b.u_color}}
  - {{from: a.y_str, to: b.u_str, factor: 2.0}}
""")
    result = CliRunner().invoke(main, ["run", str(path)])
    assert result.exit_code == 2 and "Traceback" not in result.output
    expected = [
        "bad.yaml:3: error: component 'a': parameter 'tint': 'tint' is Enumeration 'Color', which has no "
        "item 'gren' (its items: red = 1, green = 2, blue = 3) (did you mean 'green'?)",
        "bad.yaml:4: error: component 'b': parameter 'tint': 'tint' is Enumeration 'Color': give an item name "
        "or its value (red = 1, green = 2, blue = 3), not 7",
        "bad.yaml:4: error: component 'b': parameter 'u_color': 'u_color' is Enumeration 'Color': give an item "
        "name or its value (red = 1, green = 2, blue = 3), not True",
        "bad.yaml:6: error: type mismatch: 'a.y_str' is String but 'b.u' is Real",
        "bad.yaml:7: error: type mismatch: 'a.y_color' is Enumeration 'Color' but 'b.u_int' is Integer",
        "bad.yaml:8: error: type mismatch: 'a.y_int' is Integer but 'b.u_color' is Enumeration 'Color'",
        "bad.yaml:9: error: factor/offset need Real variables; 'a.y_str' is String",
    ]
    for message in expected:
        assert f"{path.parent}/{message}" in result.output, message


# --- ending the run: FMUs that terminate, and one that discards a step ------------------------------

@pytest.mark.parametrize("adaptive", [False, True])
@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_terminating_fmu_ends_the_run_cleanly(third_party, oscillator, tmp_path, interface, adaptive):
    """Through ``deltafmi run``: exit 0, the last row at the time the ticker terminated, and the
    summary names it; also with an adaptive step (every unit can roll back)."""
    path = tmp_path / "ticker.yaml"
    path.write_text(f"""experiment: {{stop: 3.0, step: 0.1}}
master: {{adaptive: {{enabled: {str(adaptive).lower()}}}}}
components:
  osc: {{fmu: {oscillator}, interface: CS}}
  ticker: {{fmu: {third_party['Ticker']}, interface: {interface}}}
connections:
  - {{from: osc.energy, to: ticker.u}}
result: {{file: ticker.csv}}
""")
    result = CliRunner().invoke(main, ["run", str(path)])
    assert result.exit_code == 0, result.output
    assert "warning: adaptive step needs" not in result.output
    assert result.stdout.strip().splitlines()[-1].endswith(
        "; ended early: ticker terminated the simulation at t = 1.75 s")
    c = columns(tmp_path / "ticker.csv")
    assert c["time"][-1] == 1.75 and c["ticker.ticks"][-1] == 5 and c["ticker.label"][-1] == "tick 5"
    assert np.all(np.diff(c["time"]) >= 0)


def test_discard_without_termination_is_a_failure(third_party, tmp_path):
    """A Co-Simulation FMU that discards a step but does not terminate cannot go on: exit 1, the
    FMU's reason, the rows so far kept."""
    path = tmp_path / "ball.yaml"
    path.write_text(f"experiment: {{stop: 1.0, step: 0.01}}\ncomponents:\n"
                    f"  ball: {{fmu: {third_party['BouncingBall']}, interface: CS, parameters: {{max_step: 0.005}}}}\n")
    out = tmp_path / "ball.csv"
    result = CliRunner().invoke(main, ["run", str(path), "-o", str(out)])
    assert result.exit_code == 1
    assert result.output.strip().splitlines()[-1] == (
        "Error: simulation failed at t = 0 s: ball: fmi2DoStep failed with status 2 (discard): fmi2DoStep: a step "
        f"of 0.01 s is longer than the 0.005 s this FMU can take (results up to the failure in "
        f"{tmp_path / 'ball.failed.csv'})")
    assert list(columns(tmp_path / "ball.failed.csv")["time"]) == [0.0]
