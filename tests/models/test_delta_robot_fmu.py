"""The DeltaRobot FMU (ME through fmpy's CVODE, and CS) against the minimal-coordinate model."""
from __future__ import annotations

from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu
from scipy.integrate import solve_ivp

from deltafmi.physics import delta as d
from conftest import start_model_exchange
from delta_reference import CASES, SERVO, MinimalModel, fk_minimal

T_END = 0.5
Q = [f"q[{i}]" for i in range(1, 10)]
V = [f"v[{i}]" for i in range(1, 10)]
OUTPUTS = ["z[1]", "z[2]", "z[3]", "y[1]", "y[2]", "y[3]", "residual", "energy"] + Q + V


@pytest.fixture(scope="module")
def robot(build_fmu_from_src):
    return build_fmu_from_src("delta_robot.py")


# CS projects onto the closed loops after every step of its own CVODE. In ME fmpy's CVODE
# integrates the 18 states, and the loops drift by its local errors: about 5e-8 m at rtol 1e-8.
RESIDUAL = {"CoSimulation": 1e-9, "ModelExchange": 1e-7}


def _run(fmu, fmi_type, z0, u, f, **start_values):
    start = {"payload": 1.0, **start_values}
    start.update({f"z0[{i + 1}]": z0[i] for i in range(3)})
    start.update({f"u[{i + 1}]": u[i] for i in range(3)})
    start.update({f"f[{i + 1}]": f[i] for i in range(3)})
    return fmpy.simulate_fmu(str(fmu), fmi_type=fmi_type, start_values=start, stop_time=T_END,
                             output_interval=0.01, relative_tolerance=1e-8, output=OUTPUTS)


def test_validates_with_zero_problems(robot):
    assert validate_fmu(str(robot)) == []
    md = fmpy.read_model_description(str(robot))
    assert md.numberOfContinuousStates == 18
    assert md.modelExchange.needsCompletedIntegratorStep  # for loop_tolerance's step events
    names = {v.name for v in md.modelVariables}
    assert {"lambda[6]", "z0[3]", "der(v[9])", "residual", "energy"} <= names


@pytest.mark.parametrize("fmi_type", ["ModelExchange", "CoSimulation"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_matches_minimal_coordinate_model(robot, fmi_type, case):
    z0, u, f = CASES[case]
    r = _run(robot, fmi_type, z0, u, f)
    assert _wrist_error(r, z0, u, f) < 1e-6
    assert np.max(np.abs(r["residual"])) < RESIDUAL[fmi_type]
    z_fmu = np.column_stack([r["z[1]"], r["z[2]"], r["z[3]"]])
    # energy balance under constant loads: E(t) - E(0) = u . (y - y0) + f . (z - z0)
    y = np.column_stack([r["y[1]"], r["y[2]"], r["y[3]"]])
    work = (y - y[0]) @ np.asarray(u) + (z_fmu - z_fmu[0]) @ np.asarray(f)
    # relative to the peak kinetic energy (the potential's zero is arbitrary)
    assert np.max(np.abs(r["energy"] - r["energy"][0] - work)) < 1e-6 * _peak_kinetic_energy(r)


def test_model_exchange_step_events_close_the_loops(robot):
    """With loop_tolerance the FMU asks for a step event whenever |h| exceeds it after an
    integrator step (fmpy asks at every output point) and projects there: every row on the
    output grid closes the loops, the trajectory is unchanged, and the projections themselves
    move the energy by next to nothing."""
    z0, u, f = CASES["fall-offset"]
    r = _run(robot, "ModelExchange", z0, u, f, loop_tolerance=1e-10)
    t = r["time"]
    before_event = np.append(np.diff(t) == 0, False)  # fmpy records a row before and after an event
    assert before_event.sum() >= 10
    assert np.max(np.abs(r["residual"][~before_event])) < 1e-9
    assert np.max(np.abs(r["residual"][before_event])) > 1e-9  # the importer's drift, projected away
    assert _wrist_error(r, z0, u, f) < 1e-6
    jumps = np.diff(r["energy"])[before_event[:-1]]
    assert np.sum(np.abs(jumps)) < 1e-7 * _peak_kinetic_energy(r)


def test_the_compiled_drift_check_asks_for_the_step_events_the_python_one_does(robot, monkeypatch):
    """fmi2CompletedIntegratorStep runs the drift check compiled from dynamics.loop_drifted (the
    FMU carries it); on its Python methods (DELTAFMI_NATIVE=0) the FMU asks needs_projection():
    the same step events at the same times and the same numbers, bit for bit."""
    import json
    import zipfile

    with zipfile.ZipFile(robot) as archive:
        assert "drift" in json.loads(archive.read("resources/native_kernels.json"))["kernels"]
        source = archive.read("sources/DeltaRobot_kernels.c").decode()
    assert "dfmi_kernel_drift" in source and "loop_drifted" in source
    z0, u, f = CASES["fall-offset"]
    compiled = _run(robot, "ModelExchange", z0, u, f, loop_tolerance=1e-10)
    monkeypatch.setenv("DELTAFMI_NATIVE", "0")
    python = _run(robot, "ModelExchange", z0, u, f, loop_tolerance=1e-10)
    assert np.sum(np.diff(compiled["time"]) == 0) >= 10  # the step events' rows (before and after)
    for name in ("time", "residual", *Q, *V):
        assert np.array_equal(compiled[name], python[name]), name


@pytest.mark.parametrize("loop_tolerance", [0.0, 1e-10])
def test_master_answers_the_step_events(tmp_path, loop_tolerance):
    """The master asks fmi2CompletedIntegratorStep after every communication step of its own
    CVODE: with loop_tolerance the row after each step event closes the loops; without, they drift."""
    from click.testing import CliRunner

    from deltafmi.apps.cli import main
    from deltafmi.master.results.csv_file import columns

    source = Path(__file__).resolve().parents[2] / "fmu_src" / "delta_robot.py"
    scenario = tmp_path / "fall.yaml"
    scenario.write_text(f"""experiment: {{start: 0.0, stop: 0.3, step: 2.0e-3}}
components:
  plant:
    source: {source}
    interface: ME
    parameters: {{z0: [0.2, -0.1, -0.9], loop_tolerance: {loop_tolerance}}}
    solver: {{rtol: 1.0e-8}}
outputs: [plant.residual, 'plant.z[*]']
""")
    out = tmp_path / "fall.csv"
    result = CliRunner().invoke(main, ["run", str(scenario), "-o", str(out), "-q"])
    assert result.exit_code == 0, result.output
    r = columns(out)
    last_at_time = np.append(np.diff(r["time"]) > 0, True)  # an event records a row before and after
    residual = np.max(np.abs(r["plant.residual"][last_at_time]))
    assert residual < 1e-9 if loop_tolerance else residual > 1e-9


def _peak_kinetic_energy(r) -> float:
    p = d.DeltaParams(payload=1.0)
    q, v = np.column_stack([r[n] for n in Q]), np.column_stack([r[n] for n in V])
    return max(0.5 * vi @ d.mass_matrix(p, qi) @ vi for qi, vi in zip(q, v))


def _wrist_error(r, z0, u, f) -> float:
    """Largest distance (m) between the FMU's wrist and the minimal-coordinate model's."""
    t = r["time"]
    grid, row = np.unique(t, return_inverse=True)  # event rows share their time
    p = d.DeltaParams(payload=1.0)
    y0 = d.inverse_kinematics(p, z0)[SERVO]
    mini = solve_ivp(MinimalModel(p, u, f).rhs, (0, T_END), np.concatenate([y0, np.zeros(3)]),
                     method="DOP853", rtol=1e-10, atol=1e-12, t_eval=grid)
    z_fmu = np.column_stack([r["z[1]"], r["z[2]"], r["z[3]"]])
    return float(np.max(np.linalg.norm(z_fmu - fk_minimal(p, mini.y[:3].T)[row], axis=1)))


def test_unreachable_start_is_a_clear_initialization_error(robot, capfd):
    with pytest.raises(Exception):
        _run(robot, "CoSimulation", (0.0, 0.0, -1.6), (0, 0, 0), (0, 0, 0))
    log = "".join(capfd.readouterr())
    assert "out of reach" in log and "-1.6" in log


def test_singularity_scenario_passes_through_the_stretched_pose(tmp_path, monkeypatch):
    """The seed's 'simulation through kinematic singularity', as the shipped scenario runs it."""
    from click.testing import CliRunner

    from deltafmi.apps.cli import main
    from deltafmi.master.results.csv_file import columns

    root = Path(__file__).resolve().parents[2]
    monkeypatch.chdir(root)  # the scenario names its source relative to the project
    out = tmp_path / "singularity.csv"
    result = CliRunner().invoke(main, ["run", "scenarios/delta_singularity.yaml", "-o", str(out), "-q"])
    assert result.exit_code == 0, result.output
    r = columns(out)
    z = r["plant.z[3]"]
    stretched = d.stretched_height(d.RL5)
    assert abs(z.min() - stretched) < 5e-5  # sampled every 1 ms around the turning point
    assert r["time"][np.argmin(z)] == pytest.approx(0.464, abs=2e-3)
    assert z[-1] > z.min() + 0.01  # it came back up: the elbows folded through
    assert np.max(np.abs(r["plant.residual"])) < 1e-9
    assert np.ptp(r["plant.energy"]) < 1e-6 * 40.0  # 40 J: the order of the kinetic energy reached


def test_fmu_kernels_are_compiled_and_agree_with_the_library(robot, tmp_path):
    """The FMU carries the compiled kernels (C generated from the dynamics, called by its C layer);
    through FMI they give the library's derivatives (same float operations, so agreement to round-off)."""
    import ctypes
    import zipfile

    from fmpy.fmi2 import FMU2Model

    names = zipfile.ZipFile(robot).namelist()
    assert "binaries/linux64/DeltaRobot_kernels.so" in names and "resources/native_kernels.json" in names
    md = fmpy.read_model_description(str(robot))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(robot), str(tmp_path / "robot")),
                    modelIdentifier="DeltaRobot")
    start_model_exchange(fmu)
    p = d.RL5
    rng = np.random.default_rng(3)
    u = np.array([40.0, -25.0, 10.0])
    fmu.setReal([vr[f"u[{i}]"] for i in (1, 2, 3)], list(u))
    for z in ([0.1, -0.2, -0.9], [0.0, 0.3, -1.2]):
        x = np.concatenate([d.inverse_kinematics(p, z), rng.normal(0.0, 1.0, 9)])
        dx = np.zeros(18)
        fmu.setContinuousStates(x.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 18)
        fmu.getDerivatives(dx.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 18)
        np.testing.assert_allclose(dx, d.state_derivative(p, x, u, np.zeros(3)), rtol=1e-12, atol=1e-12)
    fmu.terminate()
    fmu.freeInstance()
