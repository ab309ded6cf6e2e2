"""Co-Simulation steps taken in C (deltafmi/runtime/native/cs_step.c) against the same FMUs with
the step in Python (``DELTAFMI_NATIVE_CS=0``) and against the physics: the Oscillator's closed
form, the BouncingBall's impact time, the DeltaRobot's loop-closure residual; FMU state, reset,
FMI 3.0 event mode and plain C hosts."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from deltafmi.builder.packager import build_cached

ROOT = Path(__file__).resolve().parents[2]
FMU_SRC = ROOT / "fmu_src"
NATIVE = ROOT / "deltafmi" / "runtime" / "native"
sys.path.insert(0, str(ROOT / "tests"))
from oscillator_analytic import solution  # noqa: E402

#: what each model's rows hold after every step
RECORDED = {"oscillator.py": ["x", "v", "energy", "impacts"],
            "bouncing_ball.py": ["q", "v", "contact", "energy", "lam"],
            "delta_robot.py": [*(f"q[{k}]" for k in range(1, 10)), *(f"v[{k}]" for k in range(1, 10)),
                               "residual", "z[3]"]}


class Run:
    """One FMI 2.0 Co-Simulation instance through fmpy, the step in C or in Python."""

    def __init__(self, source: str, monkeypatch, c_step: bool, name: str = "cs") -> None:
        fmu = build_cached(FMU_SRC / source)
        monkeypatch.setenv("DELTAFMI_NATIVE_CS", "1" if c_step else "0")  # read at instantiation
        md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.types = {v.name: v.type for v in md.modelVariables}
        self.recorded = RECORDED[source]
        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)),
                               modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.slave.instantiate()
        self.start()
        self.t = 0.0

    def start(self) -> None:
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()
        self.t = 0.0

    def row(self) -> list[float]:
        reals = [n for n in self.recorded if self.types[n] == "Real"]
        ints = [n for n in self.recorded if self.types[n] != "Real"]
        values = dict(zip(reals, self.slave.getReal([self.vr[n] for n in reals])))
        values.update(zip(ints, self.slave.getInteger([self.vr[n] for n in ints]) if ints else []))
        return [self.t, *(float(values[n]) for n in self.recorded)]

    def steps(self, n: int, h: float = 1e-3, inputs=None) -> np.ndarray:
        rows = []
        for _ in range(n):
            if inputs is not None:
                for name, value in inputs(self.t).items():
                    self.slave.setReal([self.vr[name]], [value])
            self.slave.doStep(self.t, h)
            self.t += h
            rows.append(self.row())
        return np.array(rows)

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()


def _both(source: str, monkeypatch, steps: int, inputs=None) -> tuple[np.ndarray, np.ndarray]:
    rows = []
    for c_step in (True, False):
        run = Run(source, monkeypatch, c_step)
        rows.append(run.steps(steps, inputs=inputs))
        run.close()
    return rows[0], rows[1]


def _force(t: float) -> dict:
    """A zero-order-hold force: small changes every step (CVODE keeps its history over them) and a
    5 N jump every 0.4 s (it restarts there)."""
    return {"F": 0.05 * math.sin(7.0 * t) + (5.0 if int(t / 0.4) % 2 else 0.0)}


@pytest.mark.parametrize("source, steps, inputs", [("oscillator.py", 4000, None), ("oscillator.py", 3000, _force),
                                                   ("bouncing_ball.py", 3000, None), ("delta_robot.py", 600, None)],
                         ids=["oscillator", "oscillator-inputs", "bouncing_ball", "delta_robot"])
def test_the_c_step_equals_the_python_step_bit_for_bit(source, steps, inputs, monkeypatch):
    """The C loop makes the same solver calls in the same order as FmuInstance.do_step (restarts
    at events and input jumps, the history kept over small input changes, projection): every
    recorded value equals the Python loop's to the last bit."""
    c_rows, python_rows = _both(source, monkeypatch, steps, inputs)
    assert c_rows.shape == python_rows.shape == (steps, len(RECORDED[source]) + 1)
    assert np.array_equal(c_rows, python_rows)


def test_steps_between_events_call_no_python(monkeypatch):
    """Between the Oscillator's events (t in (0.1, 0.2]: no impact, no time event) a doStep in C
    calls no function of the FMU's Python runtime; with the step in Python every step does."""
    calls = {}
    for c_step in (True, False):
        run = Run("oscillator.py", monkeypatch, c_step)
        run.steps(100)
        seen: list[str] = []

        def profile(frame, event, _arg, seen=seen):
            if event == "call" and "/deltafmi/runtime/" in frame.f_code.co_filename.replace("\\", "/"):
                seen.append(frame.f_code.co_name)

        sys.setprofile(profile)
        try:
            run.steps(100)
        finally:
            sys.setprofile(None)
        run.close()
        calls[c_step] = seen
    assert calls[True] == []
    assert calls[False].count("do_step") == 100


def test_the_oscillator_follows_its_closed_form(monkeypatch):
    """Impacts on the wall and the force step at t = 2.5 s (a time event) inside the C loop: the
    trajectory stays within 1e-6 m of the closed form (CVODE at rtol 1e-8), the impacts counted."""
    run = Run("oscillator.py", monkeypatch, True)
    rows = run.steps(4000)
    run.close()
    x, v, impacts = solution(rows[:, 0])
    assert np.max(np.abs(rows[:, 1] - x)) < 1e-6
    assert np.max(np.abs(rows[:, 2] - v)) < 1e-5
    assert rows[-1, 4] == len(impacts) >= 3


def test_the_delta_robot_stays_on_its_constraint_manifold(monkeypatch):
    """CVODE's projection after every internal step runs in C with the step: the loop-closure
    residual |h(q)| stays below 1e-9 m at every communication point of a 1 s free fall."""
    run = Run("delta_robot.py", monkeypatch, True)
    rows = run.steps(1000)
    run.close()
    residual = rows[:, RECORDED["delta_robot.py"].index("residual") + 1]
    assert np.max(residual) <= 1e-9
    z = rows[:, RECORDED["delta_robot.py"].index("z[3]") + 1]
    assert z[-1] < z[0] - 0.05  # it does fall: the test is not on a robot at rest


@pytest.mark.parametrize("c_step", [True, False], ids=["c", "python"])
def test_an_fmu_state_restored_retakes_the_same_steps(c_step, monkeypatch):
    """The solver starts afresh at a saved and at a restored FMU state (get_state drops it, as
    before): the steps after a restore repeat those after the save bit for bit, across the
    BouncingBall's contact events, in either loop."""
    run = Run("bouncing_ball.py", monkeypatch, c_step)
    run.steps(300)
    saved, saved_t = run.slave.getFMUstate(), run.t
    first = run.steps(400)
    run.slave.setFMUstate(saved)
    run.t = saved_t
    again = run.steps(400)
    run.slave.freeFMUstate(saved)
    run.close()
    assert np.array_equal(first, again)
    assert set(first[:, 3]) >= {0.0, 1.0}  # a contact event inside the repeated span


def test_reset_runs_the_same_simulation_again(monkeypatch):
    run = Run("oscillator.py", monkeypatch, True)
    before = run.steps(800, inputs=_force)
    run.slave.reset()
    run.start()
    after = run.steps(800, inputs=_force)
    run.close()
    assert np.array_equal(before, after)


def test_c_hosts_with_and_without_fmi3_event_mode(tmp_path):
    """In the plain C FMI 3.0 host with eventModeUsed and early return, the C loop stops at the
    ball's first contact at the closed-form time sqrt(2 h0 / g), and at the Oscillator's wall
    impacts (closed form) and its force step (a time event); every event time and row equals the
    Python loop's. In the FMI 2.0 host the two loops print the same rows as well."""
    host3 = tmp_path / "host3"
    subprocess.run(["cc", "-O2", "-Wall", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "host3.c"),
                    "-o", str(host3), "-ldl", "-lm"], check=True)
    host2 = tmp_path / "host2"
    subprocess.run(["cc", "-O2", "-Wall", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "host.c"),
                    "-o", str(host2), "-ldl", "-lm"], check=True)
    outputs = {}
    for version, host, mode in ((3, host3, "cs-events"), (2, host2, "cs")):
        fmu = build_cached(FMU_SRC / "bouncing_ball.py", fmi_version=version)
        md = read_model_description(str(fmu))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        directory = extract(str(fmu), str(tmp_path / f"ball{version}"))
        for flag in ("1", "0"):
            done = subprocess.run([str(host), directory, md.coSimulation.modelIdentifier, md.guid, mode, "1.5",
                                   "0.01", str(vr["q"]), str(vr["v"])], capture_output=True, text=True,
                                  timeout=300, env={"PATH": "/usr/bin:/bin", "DELTAFMI_NATIVE_CS": flag})
            assert done.returncode == 0, done.stderr
            outputs[version, flag] = done.stdout.split()
    for version in (3, 2):
        assert outputs[version, "1"] == outputs[version, "0"]
        assert len([row for row in outputs[version, "1"] if not row.startswith("event")]) == 151
    events = [float(row.split(",")[1]) for row in outputs[3, "1"] if row.startswith("event")]
    assert len(events) >= 2
    assert events[0] == pytest.approx(math.sqrt(2 / 9.81), abs=1e-8)
    # the Oscillator's wall impacts and its force step (a time event at t_step = 2.5 s) in event mode
    fmu = build_cached(FMU_SRC / "oscillator.py", fmi_version=3)
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    directory = extract(str(fmu), str(tmp_path / "oscillator3"))
    rows = {}
    for flag in ("1", "0"):
        done = subprocess.run([str(host3), directory, md.coSimulation.modelIdentifier, md.guid, "cs-events", "3.0",
                               "0.01", str(vr["x"]), str(vr["v"])], capture_output=True, text=True,
                              timeout=300, env={"PATH": "/usr/bin:/bin", "DELTAFMI_NATIVE_CS": flag})
        assert done.returncode == 0, done.stderr
        rows[flag] = done.stdout.split()
    assert rows["1"] == rows["0"]
    events = [float(row.split(",")[1]) for row in rows["1"] if row.startswith("event")]
    _, _, impacts = solution(np.linspace(0.0, 3.0, 3001))
    # each impact once (its indicator crossing back a few ulp later is no second event), and the force step
    assert len(events) == len(impacts) + 1 and 2.5 in events
    assert all(t == 2.5 or min(abs(t - i) for i in impacts) < 1e-6 for t in events)
    assert all(min(abs(t - i) for t in events) < 1e-6 for i in impacts)


def _events_host(tmp_path: Path) -> Path:
    exe = tmp_path / "fmi3_cs_events"
    subprocess.run(["cc", "-O2", "-Wall", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "fmi3_cs_events.c"),
                    "-o", str(exe), "-ldl", "-lm"], check=True)
    return exe


def _event_mode_rows(host: Path, source: str, names: list[str], early_return: bool, c_step: bool,
                     directory: Path) -> list[list[str]]:
    """The rows of tests/c_host/fmi3_cs_events.c (fmusim's loop) with eventModeUsed, split at commas."""
    fmu = build_cached(FMU_SRC / source, fmi_version=3)
    md = read_model_description(str(fmu))
    variables = {v.name: v for v in md.modelVariables}
    unzipped = directory / source
    if not unzipped.exists():
        extract(str(fmu), str(unzipped))
    refs = [("i" if variables[n].type in ("Int32", "Boolean") else "") + str(variables[n].valueReference)
            for n in names]
    done = subprocess.run([str(host), str(unzipped), md.coSimulation.modelIdentifier, md.guid, "1",
                           str(int(early_return)), "3.0", "0.01", *refs], capture_output=True, text=True,
                          timeout=300, env={"PATH": "/usr/bin:/bin", "DELTAFMI_NATIVE_CS": "1" if c_step else "0"})
    assert done.returncode == 0, done.stderr
    return [line.split(",") for line in done.stdout.split()]


@pytest.mark.parametrize("early_return", [True, False], ids=["early-return", "at-step-end"])
def test_fmi3_event_modes_the_c_step_equals_the_python_step(early_return, tmp_path):
    """FMI 3.0 Co-Simulation with eventModeUsed, with and without earlyReturnAllowed, from the plain
    C host that steps as fmusim does: every row (steps, their eventHandlingNeeded and earlyReturn,
    the values after each Event Mode) of the C loop equals the Python loop's to the last digit, for
    the Oscillator (wall impacts: state events; the force step at t = 2.5 s: a time event on a
    communication point) and the BouncingBall. With early return the Oscillator's steps stop once
    at each impact, at its closed-form time (to 1e-6 s), and at the force step; without it the
    impacts are handled inside the steps and reported at the steps' ends, the force step, on a
    communication point, is left to the importer (no early return either way), and the values on
    the grid are the early-return run's."""
    host = _events_host(tmp_path)
    runs = {}
    for source, names in (("oscillator.py", ["x", "v", "impacts"]), ("bouncing_ball.py", ["q", "v", "contact"])):
        for c_step in (True, False):
            runs[source, c_step] = _event_mode_rows(host, source, names, early_return, c_step, tmp_path)
        assert runs[source, True] == runs[source, False]
    rows = runs["oscillator.py", True]
    steps = [row for row in rows if row[0] == "step"]
    events = [float(row[1]) for row in rows if row[0] == "event"]
    early = [float(row[1]) for row in steps if row[3] == "1"]
    _, _, impacts = solution(np.linspace(0.0, 3.0, 3001))
    assert len(impacts) == 3  # before the force step; none after it up to 3 s
    assert [row[2] for row in steps].count("1") == len(events)  # each eventHandlingNeeded had its Event Mode
    if early_return:
        assert len(early) == len(impacts) and 2.5 not in early
        np.testing.assert_allclose(early, impacts, rtol=0, atol=1e-6)
        assert events == sorted(early + [2.5])
    else:
        step_ends = [round(math.ceil(t / 0.01) * 0.01, 12) for t in impacts]
        assert early == [] and events == pytest.approx(sorted(step_ends + [2.5]), abs=1e-12)
        with_early_return = _event_mode_rows(host, "oscillator.py", ["x", "v", "impacts"], True, True, tmp_path)
        on_grid = [row[1:2] + row[4:] for row in with_early_return if row[0] == "step" and row[3] == "0"]
        assert [row[1:2] + row[4:] for row in steps] == on_grid
    impacts_after = [int(row[-1]) for row in rows if row[0] == "event"]
    assert impacts_after[-1] == len(impacts)  # each impact counted once


@pytest.mark.parametrize("c_step", [True, False], ids=["c", "python"])
def test_a_failing_step_is_an_error_explained_by_the_python_that_raised(c_step, monkeypatch, tmp_path):
    """tests/components/compiled: its derivatives kernel raises beyond an input limit, the Python
    method then runs and raises with the model's message. Within the limit no Python derivatives
    run after initialization; beyond it fmi2DoStep fails with that message in either loop (the C
    loop hands CVODE's failure to Python, which raises what the right-hand side raised)."""
    from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

    fmu = build_cached(ROOT / "tests" / "components" / "compiled" / "model.py")
    monkeypatch.setenv("DELTAFMI_NATIVE_CS", "1" if c_step else "0")
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    messages: list[str] = []
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(lambda env, inst, status, cat, msg: messages.append(msg.decode()))
    callbacks.allocateMemory, callbacks.freeMemory = defaultCallbacks.allocateMemory, defaultCallbacks.freeMemory
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu), str(tmp_path)),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="failing")
    slave.instantiate(callbacks=callbacks)
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    slave.setReal([vr["u"]], [0.3])
    for k in range(50):
        slave.doStep(k * 0.01, 0.01)
    calls = slave.getInteger([vr["python_calls"]])[0]
    slave.setReal([vr["u"]], [30.0])
    with pytest.raises(Exception):
        slave.doStep(0.5, 0.01)
    assert any("input 30.0 is beyond the limit 10.0" in m for m in messages), messages
    slave.freeInstance()
    assert calls <= 5  # CVODE's right-hand side is the kernel in either loop
