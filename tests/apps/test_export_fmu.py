"""A scenario exported as one Co-Simulation FMU (``deltafmi export-fmu``): its outputs equal
``deltafmi run`` of the scenario bit for bit on the scenario's grid, in fmpy (FMI 2.0 and 3.0),
in a C host with no Python in the process, and as a unit of a bigger scenario in our own master;
with a third-party C FMU among its units; its parameters and inputs act as the scenario's start
values; FMU states and reset repeat a run exactly; its units' messages name the unit; a scenario
that cannot run inside an FMU is refused with one line."""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from click.testing import CliRunner
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

import deltafmi
from deltafmi.apps.cli import main
from deltafmi.apps.export_fmu import export_fmu
from deltafmi.builder.requirements import runtime_requirement
from third_party.build import build_all

ROOT = Path(__file__).resolve().parents[2]
TRACKED = ["plant.z[1]", "plant.z[2]", "plant.z[3]", "controller.u[1]", "controller.status", "plant.residual"]


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """``exported(scenario, fmi_version) -> Path`` of the system FMU, built once per module."""
    folder = tmp_path_factory.mktemp("system_fmus")
    built: dict = {}

    def export(scenario: str, fmi_version: int = 2) -> Path:
        key = (scenario, fmi_version)
        if key not in built:
            name = Path(scenario).stem.replace("_", "")
            built[key] = export_fmu(scenario, folder / f"{name}{fmi_version}.fmu", fmi_version=fmi_version)
        return built[key]

    return export


def test_the_hint_for_a_portable_copy_names_a_shipped_scenario_as_it_is_given(exported):
    """`deltafmi export-fmu delta_tracking.yaml` works only beside such a file: the hint names the example."""
    line = next(text for text in runtime_requirement(exported("delta_tracking")).describe() if "--portable" in text)
    assert "`deltafmi export-fmu delta_tracking --portable`" in line, line


def grid_rows(result, step: float) -> np.ndarray:
    """The rows of a run on its communication grid: an event inside a step adds rows between."""
    t = np.asarray(result["time"])
    on_grid = np.abs(t - np.round(t / step) * step) <= 1e-12
    last_at_time = np.r_[np.diff(t) > 0, True]
    return np.flatnonzero(on_grid & last_at_time)


def assert_same(system_result, run_result, names, step):
    rows = grid_rows(run_result, step)
    assert len(rows) == len(system_result)
    np.testing.assert_array_equal(np.asarray(system_result["time"]), np.asarray(run_result["time"])[rows])
    for name in names:
        np.testing.assert_array_equal(np.asarray(system_result[name], float),
                                      np.asarray(run_result[name], float)[rows], err_msg=name)


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_the_flagship_as_one_fmu_equals_its_run_in_fmpy(exported, fmi_version):
    fmu = exported("delta_tracking", fmi_version)
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    assert md.modelExchange is None and md.coSimulation is not None
    variables = {v.name: v for v in md.modelVariables}
    assert variables["plant.z[1]"].causality == "output" and variables["plant.z[1]"].unit == "m"
    assert variables["plant.f[3]"].causality == "input"  # unconnected in the scenario
    assert variables["controller.sample_period"].causality == "parameter"  # set by the scenario
    assert md.defaultExperiment.stopTime == "3.5" and md.defaultExperiment.stepSize == "0.001"
    system = fmpy.simulate_fmu(str(fmu), output=TRACKED, output_interval=1e-3)
    run = deltafmi.simulate("delta_tracking")
    assert_same(system, run, TRACKED, 1e-3)
    assert abs(system["plant.z[3]"][-1] - -1.0) < 1e-6  # back home at rest: the loop did close


def test_a_c_host_without_python_gets_the_same_rows(exported, c_host, tmp_path):
    fmu = exported("delta_tracking")
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(tmp_path)
    md = fmpy.read_model_description(str(fmu))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    out = subprocess.run([str(c_host), str(tmp_path), md.coSimulation.modelIdentifier, md.guid, "cs", "3.5", "0.001",
                          *(str(vrs[n]) for n in TRACKED[:3])], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    rows = np.loadtxt(out.stdout.splitlines(), delimiter=",")
    run = deltafmi.simulate("delta_tracking")
    assert rows.shape == (3501, 4)
    for i, name in enumerate(TRACKED[:3]):
        np.testing.assert_array_equal(rows[:, 1 + i], np.asarray(run[name]), err_msg=name)


def test_events_inside_the_system_leave_its_grid_rows_equal(exported):
    names = ["talk.q", "talk.v", "restitution.q", "restitution.v", "restitution.mode", "talk.energy"]
    system = fmpy.simulate_fmu(str(exported("bouncing_ball")), output=names, output_interval=1e-3)
    run = deltafmi.simulate("bouncing_ball")
    assert len(run["time"]) > 3001  # the run has event rows between its grid rows
    assert_same(system, run, names, 1e-3)


def test_parameters_and_inputs_are_the_scenarios_start_values(exported):
    fmu = exported("delta_tracking")
    payload_force = np.array([(0.0, -20.0)], dtype=[("time", float), ("plant.f[3]", float)])
    system = fmpy.simulate_fmu(str(fmu), output=TRACKED[:3], output_interval=1e-3, stop_time=1.0,
                               start_values={"controller.feedforward": False}, input=payload_force)
    run = deltafmi.simulate("delta_tracking", stop=1.0,
                            parameters={"controller.feedforward": False, "plant.f[3]": -20.0})
    assert_same(system, run, TRACKED[:3], 1e-3)
    plain = deltafmi.simulate("delta_tracking", stop=1.0)
    assert np.max(np.abs(np.asarray(plain["plant.z[3]"]) - np.asarray(system["plant.z[3]"]))) > 1e-6


@pytest.fixture(scope="module")
def third_party(tmp_path_factory) -> dict:
    return build_all(tmp_path_factory.mktemp("third_party"))


def test_a_third_party_c_fmu_among_the_units(third_party, tmp_path):
    scenario = tmp_path / "ball_table.yaml"
    scenario.write_text(f"""experiment: {{stop: 2.0, step: 1.0e-2}}
components:
  ball: {{fmu: {third_party['BouncingBall']}, interface: ME}}
  table: {{fmu: {third_party['LookupTable']}, interface: CS}}
  osc: {{source: deltafmi.models:Oscillator, interface: CS}}
connections:
  - {{from: ball.h, to: table.u, factor: 2.0, offset: -0.5}}
outputs: [ball.h, ball.v, table.y, osc.x, osc.energy]
""")
    fmu = export_fmu(scenario, tmp_path / "BallTable.fmu")
    assert validate_fmu(str(fmu)) == []
    names = ["ball.h", "ball.v", "table.y", "osc.x", "osc.energy"]
    system = fmpy.simulate_fmu(str(fmu), output=names, output_interval=1e-2)
    run = deltafmi.simulate(scenario)
    assert_same(system, run, names, 1e-2)
    assert np.min(system["ball.h"]) < 0.05  # the ball did bounce within the run


def test_the_system_fmu_as_a_unit_of_a_bigger_scenario(exported, tmp_path):
    fmu = exported("delta_tracking")
    scenario = tmp_path / "outer.yaml"
    scenario.write_text(f"""experiment: {{stop: 0.5, step: 1.0e-3}}
components:
  cell: {{fmu: {fmu}, interface: CS}}
outputs: ['cell.plant.z[*]', 'cell.controller.u[1]']
""")
    outer = deltafmi.simulate(scenario)
    run = deltafmi.simulate("delta_tracking", stop=0.5)
    for name in ("plant.z[1]", "plant.z[3]", "controller.u[1]"):
        np.testing.assert_array_equal(np.asarray(outer[f"cell.{name}"]), np.asarray(run[name]), err_msg=name)


def test_fmu_states_and_reset_repeat_the_run_exactly(exported, tmp_path):
    fmu = exported("delta_tracking")
    md = fmpy.read_model_description(str(fmu))
    vrs = [v.valueReference for v in md.modelVariables if v.name in TRACKED[:3]]
    unzipped = fmpy.extract(str(fmu), str(tmp_path / "x"))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier)
    slave.instantiate()

    def start():
        slave.setupExperiment(startTime=0.0, stopTime=3.5)
        slave.enterInitializationMode()
        slave.exitInitializationMode()

    def steps(k0, n):
        rows = []
        for k in range(k0, k0 + n):
            slave.doStep(k * 1e-3, 1e-3)
            rows.append(slave.getReal(vrs))
        return np.array(rows)

    start()
    first = steps(0, 400)
    state = slave.getFMUstate()
    ahead = steps(400, 300)
    slave.setFMUstate(state)
    again = steps(400, 300)
    np.testing.assert_array_equal(again, ahead)
    slave.setFMUstate(state)  # a state stays valid for another restore
    np.testing.assert_array_equal(steps(400, 300), ahead)
    slave.freeFMUstate(state)
    slave.reset()
    start()
    np.testing.assert_array_equal(steps(0, 400), first)
    with pytest.raises(fmpy.fmi1.FMICallException):  # a step that is no multiple of the scenario's
        slave.doStep(0.4, 1.5e-3)
    slave.freeInstance()  # the FMU is in its error state: only freeing is allowed


def test_messages_name_the_unit_that_spoke(tmp_path):
    source = tmp_path / "talker.py"
    source.write_text('''"""A unit that says something at every step."""
from deltafmi.component import Component, Output


class Talker(Component):
    """Counts steps and says so."""

    n = Output(0, type=int, description="steps taken")

    def do_step(self, t, h):
        self.n += 1
        if self.n == 3:
            self.log("third step done", "warning")
''')
    scenario = tmp_path / "talk.yaml"
    scenario.write_text(f"""experiment: {{stop: 0.01, step: 1.0e-3}}
components:
  chatty: {{source: {source}, interface: CS}}
outputs: [chatty.n]
""")
    fmu = export_fmu(scenario, tmp_path / "Talk.fmu")
    outer = tmp_path / "outer.yaml"  # the system FMU as a unit of our master, which hands on what units log
    outer.write_text(f"""experiment: {{stop: 0.01, step: 1.0e-3}}
components:
  cell: {{fmu: {fmu}, interface: CS}}
outputs: [cell.chatty.n]
""")
    heard = []
    # (not fmpy.simulate_fmu(logger=...): fmpy's logger proxy keeps that callback process-wide after
    # the run, and a later FMU's message in this process would call it freed)
    result = deltafmi.simulate(outer, on_message=lambda unit, status, category, text: heard.append((unit, text)))
    assert result["cell.chatty.n"][-1] == 10
    assert ("cell", "chatty: third step done") in heard, heard


def test_a_scenario_that_cannot_run_inside_an_fmu_is_refused_with_one_line(tmp_path):
    joystick = ROOT / "scenarios" / "joystick_tracking.yaml"
    out = CliRunner().invoke(main, ["export-fmu", str(joystick), "-o", str(tmp_path / "J.fmu")])
    assert out.exit_code == 2, out.output
    assert "live sources" in out.output and "Traceback" not in out.output
    bad = tmp_path / "bad_exports.yaml"
    bad.write_text("""experiment: {stop: 1.0, step: 1.0e-2}
components:
  osc: {source: deltafmi.models:Oscillator, interface: CS}
exports:
  parameters: [osc.x]
""")
    out = CliRunner().invoke(main, ["export-fmu", str(bad), "-o", str(tmp_path / "B.fmu")])
    assert out.exit_code == 2, out.output
    assert f"{bad}:5" in out.output and "osc.x" in out.output and "not a parameter" in out.output
    assert not (tmp_path / "B.fmu").exists()


def test_the_portable_system_fmu_in_a_c_host_with_no_python(c_host, tmp_path_factory):
    """``--portable``: the system FMU carries CPython and every package its master imports; where
    no Python can be found (hide_python.sh in a mount namespace), a C host gets the rows of
    ``deltafmi run``. The units are non-portable FMUs of ours: they run in the interpreter the
    system FMU brought."""
    from test_portable_fmus import no_python as _  # noqa: F401  (the fixture's module must load)
    import test_portable_fmus as portable

    if not portable.shutil.which("unshare") or subprocess.run(["unshare", "-m", "true"]).returncode != 0:
        pytest.skip("cannot make a mount namespace to hide Python")
    work = tmp_path_factory.mktemp("portable_system")
    scenario = work / "spring.yaml"
    scenario.write_text("""experiment: {stop: 3.0, step: 1.0e-2}
components:
  osc: {source: deltafmi.models:Oscillator, interface: CS}
  table: {source: deltafmi.models:Trajectory, interface: CS}
outputs: [osc.x, osc.v, osc.energy]
""")
    fmu = export_fmu(scenario, work / "Spring.fmu", portable=True)
    names = zipfile.ZipFile(fmu).namelist()
    # its doStep goes from C to C: the step's C is prebuilt in the bundle
    assert any("/_prebuilt/" in n and n.endswith("/system_step.so") for n in names)
    # what only a run from the command line imports (plots, data frames, Parquet and MAT files) stays
    # out, and the loop solver's scipy where the scenario has no algebraic loop
    carried = {n.split("/")[3] for n in names if n.startswith("resources/python/site-packages/")}
    assert {"numpy", "fmpy", "yaml"} <= carried
    assert not carried & {"matplotlib", "pandas", "pyarrow", "PIL", "scipy"}, sorted(carried)
    unpacked = work / "unpacked"  # outside every hidden folder
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(unpacked)
    md = fmpy.read_model_description(str(fmu))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    command = ["unshare", "-m", "bash", str(portable.HIDE), *map(str, portable.hidden_paths()), "--",
               str(c_host), str(unpacked), md.coSimulation.modelIdentifier, md.guid, "cs", "3.0", "0.01",
               str(vrs["osc.x"]), str(vrs["osc.v"])]
    out = subprocess.run(command, capture_output=True, text=True, timeout=600,
                         env=portable.clean_env(PATH="/usr/local/bin:/usr/bin:/bin"))
    assert out.returncode == 0, out.stderr[-3000:]
    rows = np.loadtxt(out.stdout.splitlines(), delimiter=",")
    run = deltafmi.simulate(scenario)
    grid = grid_rows(run, 1e-2)
    np.testing.assert_array_equal(rows[:, 1], np.asarray(run["osc.x"])[grid])
    np.testing.assert_array_equal(rows[:, 2], np.asarray(run["osc.v"])[grid])


def _third_party_master(name):
    try:
        return __import__(name)
    except ImportError as exc:
        pytest.skip(f"{name} is not usable here ({exc}); install it with pip install {name}")
    except OSError as exc:  # ecospy needs Debian's libtbb12
        pytest.skip(f"{name} cannot load its native library ({exc}); apt-get install libtbb12")


def test_libcosim_and_ecos_step_the_system_fmu_from_their_threads(exported):
    """Two C++ masters (OSP libcosim, Ecos) step the system FMU from their own threads, with no
    stop time: the same rows as ``deltafmi run``."""
    fmu = str(exported("delta_tracking"))
    md = fmpy.read_model_description(fmu)
    vrs = [v.valueReference for v in md.modelVariables if v.name in TRACKED[:3]]
    run = deltafmi.simulate("delta_tracking", stop=0.5)
    expected = np.column_stack([np.asarray(run[n]) for n in TRACKED[:3]])[1:]

    _third_party_master("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    execution = CosimExecution.from_step_size(step_size=1_000_000)  # 1 ms in nanoseconds
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=fmu, instance_name="cell"))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    rows = []
    for _ in range(500):
        assert execution.step()
        rows.append(observer.last_real_values(index, vrs))
    np.testing.assert_array_equal(np.array(rows), expected)

    ecospy = _third_party_master("ecospy")
    structure = ecospy.EcosSimulationStructure()
    structure.add_model("cell", fmu)
    rows = []
    with ecospy.EcosSimulation(structure=structure, step_size=1e-3) as sim:
        sim.init()
        for _ in range(500):
            sim.step()
            rows.append([sim.get_real(f"cell::{n}") for n in TRACKED[:3]])
        sim.terminate()
    np.testing.assert_array_equal(np.array(rows), expected)


def _python_steps(slave, steps):
    """Run ``steps`` (a callable) and count the calls of the system component's Python ``do_step``
    it made in this thread (the FMU runs in this interpreter: fmpy calls it from this thread)."""
    calls = []

    def profile(frame, event, arg):
        code = frame.f_code
        if event == "call" and code.co_name == "do_step" and code.co_filename.endswith("system_fmu/inside.py"):
            calls.append(frame.f_locals.get("t"))

    sys.setprofile(profile)
    try:
        rows = steps()
    finally:
        sys.setprofile(None)
    return rows, len(calls)


def test_the_c_step_runs_no_python_and_hands_back_what_it_cannot_take(exported, tmp_path, monkeypatch):
    """doStep goes from the FMU's C layer into the master's C loop with no Python call, and gives
    the rows of the same FMU stepped through its Python layer bit for bit: single and multiple
    master steps, an input the importer changes (set on its unit in C), an FMU state restored;
    a step off the master's grid goes to Python, which says what is wrong."""
    fmu = exported("delta_tracking")
    md = fmpy.read_model_description(str(fmu))
    vrs = [v.valueReference for v in md.modelVariables if v.name in TRACKED[:3]]
    force = next(v.valueReference for v in md.modelVariables if v.name == "plant.f[3]")
    unzipped = fmpy.extract(str(fmu), str(tmp_path / "x"))

    def started(c_step: bool):
        if c_step:
            monkeypatch.delenv("DELTAFMI_SYSTEM_C_STEP", raising=False)
        else:
            monkeypatch.setenv("DELTAFMI_SYSTEM_C_STEP", "0")  # read when the instance is made
        slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
                          instanceName=f"cell{int(c_step)}")
        slave.instantiate()
        slave.setupExperiment(startTime=0.0, stopTime=3.5)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        return slave

    def script(slave):
        rows = []
        for k in range(200):  # one master step per doStep
            slave.doStep(k * 1e-3, 1e-3)
            rows.append(slave.getReal(vrs))
        for k in range(200, 400, 5):  # five
            slave.doStep(k * 1e-3, 5e-3)
            rows.append(slave.getReal(vrs))
        for k in range(400, 450):  # the payload lands, with a force the importer changes every step
            slave.setReal([force], [-20.0 - 0.1 * (k - 400)])
            slave.doStep(k * 1e-3, 1e-3)
            rows.append(slave.getReal(vrs))
        state = slave.getFMUstate()
        for k in range(450, 500):
            slave.doStep(k * 1e-3, 1e-3)
            rows.append(slave.getReal(vrs))
        slave.setFMUstate(state)
        slave.freeFMUstate(state)
        rows.append(slave.getReal(vrs))  # the outputs as of the state
        for k in range(450, 500):
            slave.doStep(k * 1e-3, 1e-3)
            rows.append(slave.getReal(vrs))
        with pytest.raises(fmpy.fmi1.FMICallException):  # a step that is no multiple of the scenario's
            slave.doStep(0.5, 1.5e-3)
        return np.array(rows)

    reference = started(c_step=False)
    expected, python_calls = _python_steps(reference, lambda: script(reference))
    reference.freeInstance()
    direct = started(c_step=True)
    rows, c_calls = _python_steps(direct, lambda: script(direct))
    direct.freeInstance()
    assert python_calls == 200 + 40 + 50 + 50 + 50 + 1
    assert c_calls == 1  # the step off the grid
    np.testing.assert_array_equal(rows, expected)


def test_the_c_step_hands_each_step_with_an_event_to_python(tmp_path):
    """Two balls on a fixed-step Runge-Kutta method fit the master's C loop: the C step takes
    every communication step but those with an impact inside, which Python finishes exactly as
    the master's own loop does (one Python doStep per such step); the rows equal ``deltafmi run``."""
    scenario = tmp_path / "balls.yaml"
    scenario.write_text("""experiment: {start: 0.0, stop: 3.0, step: 1.0e-3}
components:
  talk: {source: deltafmi.models:BouncingBall, interface: ME, solver: {method: rk4}}
  restitution:
    source: deltafmi.models:BouncingBallRestitution
    interface: ME
    solver: {method: rk4}
    parameters: {e: 0.8, F: 0.0}
outputs: ['*.q', '*.v', talk.contact, restitution.mode]
""")
    fmu = export_fmu(scenario, tmp_path / "Balls.fmu")
    md = fmpy.read_model_description(str(fmu))
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    slave = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu), str(tmp_path / "x")),
                      modelIdentifier=md.coSimulation.modelIdentifier)
    slave.instantiate()
    slave.setupExperiment(startTime=0.0, stopTime=3.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    reals = [v.valueReference for v in outputs if v.type == "Real"]
    others = [v.valueReference for v in outputs if v.type != "Real"]

    def steps():
        rows = []
        for k in range(3000):
            slave.doStep(k * 1e-3, 1e-3)
            rows.append(slave.getReal(reals) + [float(x) for x in slave.getInteger(others)])
        return np.array(rows)

    rows, python_calls = _python_steps(slave, steps)
    slave.freeInstance()
    run = deltafmi.simulate(scenario)
    t = np.asarray(run["time"])
    grid = grid_rows(run, 1e-3)
    names = [v.name for v in outputs if v.type == "Real"] + [v.name for v in outputs if v.type != "Real"]
    for i, name in enumerate(names):
        np.testing.assert_array_equal(rows[:, i], np.asarray(run[name], float)[grid[1:]], err_msg=name)
    off_grid = np.setdiff1d(np.arange(len(t)), grid)
    event_steps = set(np.floor(t[off_grid] / 1e-3 + 1e-9).astype(int))
    assert len(event_steps) > 10  # both balls bounce
    assert python_calls == len(event_steps)
