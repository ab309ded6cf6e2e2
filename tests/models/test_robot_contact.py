"""The delta robot touching a plane: the contact model, the impedance law and the closed loop,
against numbers derived without the simulation (statics, the minimal-coordinate model's inertia,
the collision law's restitution)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.physics import delta as d
from deltafmi.physics.contact import CompliantMaterial, Mode
from hybrid_sim import simulate
from deltafmi.physics.delta import control_law
from deltafmi.physics.delta.contact import DeltaToolModel, Plane, make_robot_contact, robot_start_state
from delta_reference import MinimalModel

ROOT = Path(__file__).resolve().parents[2]
K_SURFACE, C_SURFACE = 2.0e5, 2.0e3   # N/m, N s/m: the scenarios' contact
G = 9.81


def wrist_inertia_along(p, z, n) -> float:
    """1 / (n^T Lambda^-1 n) from the servo-coordinate model: Lambda^-1 = Jc My^-1 Jc^T."""
    y = d.inverse_kinematics(p, z)[0::3]
    model = MinimalModel(p, np.zeros(3), np.zeros(3))
    My = model.mass(y[None])[0]
    _, Jc = model.jac_and_z(y[None])
    n = np.asarray(n, float) / np.linalg.norm(n)
    return 1.0 / float(n @ Jc[0] @ np.linalg.solve(My, Jc[0].T) @ n)


# --- the model ---------------------------------------------------------------------------------

def test_gap_and_its_jacobian_are_the_tool_tip_against_the_plane():
    p, plane, tool = d.RL5, Plane(-1.2, (0.1, -0.05, 1.0)), (0.01, -0.02, -0.1)
    model = DeltaToolModel(p, plane, tool)
    n = np.array(plane.normal)
    for z in ([0.05, -0.02, -1.02], [-0.2, 0.1, -0.9]):
        q = d.inverse_kinematics(p, z)
        tip = d.wrist_position(p, q) + np.array(tool)
        assert model.gaps(q)[0] == pytest.approx(n @ (tip - [0.0, 0.0, -1.2]), abs=1e-15)
        np.testing.assert_allclose(model.gap_jacobian(q)[0], n @ d.virtual_jacobian(p, q), atol=1e-15)


@pytest.mark.parametrize("z, normal", [([0.0, 0.0, -1.0], (0, 0, 1)), ([0.12, -0.05, -1.05], (0.2, 0.1, 1.0))])
def test_impact_inertia_is_the_wrist_inertia_with_the_loops_closed(z, normal):
    """The effective mass frozen at an impact is 1 / (H Y) with Y the DAE's response; the minimal
    model in the three servo angles gives the same inertia without any joint angle q_i2, q_i3."""
    p = replace(d.RL5, payload=0.7)
    model = DeltaToolModel(p, Plane(-1.3, normal))
    assert model.effective_mass(d.inverse_kinematics(p, z)) == pytest.approx(
        wrist_inertia_along(p, z, normal), rel=1e-9)


@pytest.mark.parametrize("e", [0.3, 0.8])
def test_impact_rebounds_with_the_restitution(e):
    """The unactuated robot (no gravity) coasts into the plane at v: it leaves at e v, and the
    impact dissipates (1 - e^2) m_eff v^2 / 2 with m_eff the minimal model's wrist inertia.
    (No capture: an unloaded impact; the capture estimate would take a slow rebound for CONTACT.)"""
    p, v = replace(d.RL5, g=0.0), 0.2
    system = make_robot_contact(p, Plane(-1.15), CompliantMaterial(K_SURFACE, C_SURFACE, restitution=e),
                                capture_speed=0.0)
    x0 = robot_start_state(p, [0.0, 0.0, -1.049], [0.0, 0.0, -v])
    result = simulate(system, (0.0, 0.06), x0, rtol=1e-10, atol=1e-12)
    changes = [(ev.modes_before, ev.modes_after) for ev in result.events if ev.modes_before != ev.modes_after]
    assert changes == [((0,), (1,)), ((1,), (0,))]  # FREE -> COLLISION -> FREE
    after = np.flatnonzero(result.t == result.events[-1].t)[-1]  # the row after the update
    rebound = float(system.model.gap_jacobian(result.x[after][:9])[0] @ result.x[after][9:])
    assert rebound == pytest.approx(e * v, rel=1e-2)
    assert rebound == pytest.approx(e * v, rel=1e-3)  # what the model does: 2.4e-4
    m_eff = wrist_inertia_along(p, [0.0, 0.0, -1.05], (0, 0, 1))
    lost = result.energy[0] - result.energy[after]
    assert lost == pytest.approx((1.0 - e * e) * 0.5 * m_eff * v * v, rel=1e-2)


def test_impedance_torques_hold_the_robot_against_exactly_the_commanded_wrist_force():
    """At rest, the impedance law's torques balance the wrist force W = K (r - z) + D (rd - zd) +
    f_cmd: the plant with those torques and an external force -W on the wrist does not move."""
    p = d.RL5
    z = np.array([0.08, -0.05, -1.05])
    q = d.inverse_kinematics(p, z)
    law = control_law.make_law(p, impedance=True, stiffness=(3000.0, 2000.0, 500.0),
                               task_damping=(100.0, 120.0, 80.0), fk="closed")
    r, rd, f_cmd = z + [0.001, -0.002, 0.01], np.array([0.01, 0.0, -0.02]), np.array([1.0, 2.0, -10.0])
    out = control_law.evaluate(law, q[0::3], np.zeros(3), r, rd, np.zeros(3), force=f_cmd)
    W = np.array([3000.0, 2000.0, 500.0]) * (r - z) + np.array([100.0, 120.0, 80.0]) * rd + f_cmd
    vdot, _ = d.accelerations(p, q, np.zeros(9), out.u, -W)
    assert np.max(np.abs(vdot)) < 1e-10
    assert out.integral == (0.0, 0.0, 0.0)  # no PID in impedance mode


# --- the plant FMU -----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def plant(build_fmu_from_src):
    return build_fmu_from_src("delta_robot_contact.py")


def test_plant_validates(plant):
    assert validate_fmu(str(plant)) == []
    md = fmpy.read_model_description(str(plant))
    assert md.numberOfContinuousStates == 18 and md.numberOfEventIndicators == 2
    names = {v.name for v in md.modelVariables}
    assert {"mode", "fn", "normal_force[3]", "gap", "penetration", "tip[3]", "surface_normal[3]"} <= names


@pytest.mark.parametrize("fmi_type", ["ModelExchange", "CoSimulation"])
def test_plant_fmu_impact_rebounds_with_the_restitution(plant, fmi_type):
    """Through fmpy's CVODE (ME: events from the indicators, modes in fmi2NewDiscreteStates) and
    through the FMU's own CVODE (CS: events inside fmi2DoStep)."""
    v, e = 0.2, 0.5
    r = fmpy.simulate_fmu(str(plant), fmi_type=fmi_type, stop_time=0.05, output_interval=1e-3,
                          relative_tolerance=1e-10, output=["mode", "zd[3]", "fn", "residual"],
                          start_values={"g": 0.0, "z0[3]": -1.049, "zd0[3]": -v, "restitution": e})
    assert set(r["mode"]) == {0, 1} and r["mode"][-1] == Mode.FREE
    assert r["zd[3]"][-1] == pytest.approx(e * v, rel=1e-2)
    assert r["fn"].max() > 0.0 and r["fn"][-1] == 0.0
    assert np.max(np.abs(r["residual"])) < 1e-7


def test_plant_refuses_to_start_below_the_surface(plant, capfd):
    with pytest.raises(Exception):
        fmpy.simulate_fmu(str(plant), fmi_type="CoSimulation", stop_time=0.01,
                          start_values={"surface_height": -1.05})
    log = "".join(capfd.readouterr())
    assert "the tool tip starts 0.05 m below the surface (tip at (0, 0, -1.1) m" in log


# --- the closed loop through the master ---------------------------------------------------------

def scenario_variant(name: str, folder: Path, stop: float | None = None, **changes: dict) -> Path:
    """A copy of scenarios/<name>.yaml with ``changes[component]`` merged into that component
    (its ``parameters`` merged key by key)."""
    import yaml

    spec = yaml.safe_load((ROOT / "scenarios" / f"{name}.yaml").read_text())
    for component, change in changes.items():
        change = dict(change)
        spec["components"][component].setdefault("parameters", {}).update(change.pop("parameters", {}))
        spec["components"][component].update(change)
    if stop is not None:
        spec["experiment"]["stop"] = stop
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def run(path: Path) -> dict:
    out = path.with_suffix(".csv")
    Master(resolve_system(load_scenario(path)), result=out).run()
    return columns(out)


def test_pressing_force_is_the_push_plus_the_uncancelled_weight(tmp_path):
    """contact_press.yaml: impedance mode, commanded push F = 20 N, stiffness K = 1000 N/m along z,
    a 0.5 kg payload the controller's model lacks, reference at the touching height. Statics:
    lambda = F + m g - K delta with delta = lambda / k, so lambda = (F + m g) / (1 + K / k)."""
    c = run(scenario_variant("contact_press", tmp_path))
    t, fn, pen = c["time"], c["plant.fn"], c["plant.penetration"]
    F, m, K = 20.0, 0.5, 1000.0
    assert fn[-1] == pytest.approx(F + m * G, rel=1e-2)
    assert fn[-1] == pytest.approx((F + m * G) / (1.0 + K / K_SURFACE), rel=1e-6)
    assert c["plant.mode"][-1] == Mode.CONTACT
    static = CompliantMaterial(K_SURFACE, C_SURFACE).static_penetration(fn[-1])
    assert pen[-1] == pytest.approx(static, rel=1e-2)
    assert pen[-1] == pytest.approx((F + m * G) / (K_SURFACE + K), rel=1e-6)
    # the approach at the set speed (10 mm/s) and its impact never push in beyond that
    rz = c["trajectory.r[3]"]
    step = np.diff(t) > 0
    cruise = np.flatnonzero(step & (np.abs(np.diff(rz) / np.where(step, np.diff(t), 1.0) + 0.01) < 1e-9))
    touch = np.argmax(c["plant.mode"] > 0)
    assert c["plant.zd[3]"][touch] == pytest.approx(-0.01, rel=1e-2)  # it touched at the set speed
    assert t[cruise[0]] < t[touch] < t[cruise[-1]] - 1.0
    assert pen[:cruise[-1]].max() < static


def test_impedance_stiffness_times_distance_is_the_force(tmp_path):
    """contact_approach.yaml: K = 1000 N/m along z, no commanded force, reference d = 1 cm below
    the touching height: the robot rests pressing with K d (less K / k, the spring's give)."""
    c = run(scenario_variant("contact_approach", tmp_path))
    K, dist = 1000.0, 0.01
    assert c["plant.fn"][-1] == pytest.approx(K * dist, rel=1e-2)
    assert c["plant.fn"][-1] == pytest.approx(K * dist / (1.0 + K / K_SURFACE), rel=1e-6)


@pytest.mark.parametrize("interface, solver", [("ME", {"rtol": 1e-8}), ("CS", {})])
def test_resting_force_with_the_plant_in_either_interface(tmp_path, interface, solver):
    """A 1 s press from 1 mm above the table with no stiffness along z, the plant integrated by
    the master's CVODE (ME) or by its own CVODE inside fmi2DoStep (CS): the table carries exactly
    the commanded push plus the weight the controller does not know."""
    F, m = 15.0, 0.3
    path = scenario_variant(
        "contact_press", tmp_path, stop=1.0,
        trajectory={"parameters": {"n_waypoints": 1, "wp_z": [-1.0] * 8}},
        controller={"parameters": {"force": [0.0, 0.0, -F], "stiffness": [5000.0, 5000.0, 0.0]}},
        plant={"interface": interface, "solver": solver,
               "parameters": {"z0": [0.0, 0.0, -1.0], "payload": m, "surface_height": -1.101}})
    c = run(path)
    assert c["plant.mode"][-1] == Mode.CONTACT
    assert c["plant.fn"][-1] == pytest.approx(F + m * G, rel=1e-6)
    assert c["plant.penetration"][-1] == pytest.approx((F + m * G) / K_SURFACE, rel=1e-6)


@pytest.mark.parametrize("name", sorted(p.stem for p in (ROOT / "scenarios").glob("contact_*.yaml")))
def test_contact_scenario_runs_from_the_cli(tmp_path, name, monkeypatch):
    """Each shipped contact scenario starts and runs through ``deltafmi run`` (first 0.3 s)."""
    from click.testing import CliRunner

    from deltafmi.apps.cli import main

    monkeypatch.chdir(tmp_path)  # a shipped example runs by name from any folder
    out = tmp_path / f"{name}.csv"
    result = CliRunner().invoke(main, ["run", name, "-o", str(out), "--stop", "0.3", "-q"])
    assert result.exit_code == 0, result.output
    c = columns(out)
    gaps = [values for name, values in c.items() if name.startswith("plant.gap")]
    assert c["time"][-1] == pytest.approx(0.3) and gaps and np.all(np.isfinite(gaps))


# --- the robot, a movable box and the table (the talk's cartoon) --------------------------------

def test_box_plant_validates(build_fmu_from_src):
    fmu = build_fmu_from_src("delta_robot_box.py")
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    assert md.numberOfContinuousStates == 24 and md.numberOfEventIndicators == 12
    assert {"mode[6]", "fn[6]", "gap[6]", "penetration[6]", "box[3]", "normal_force[3]"} <= {v.name for v in md.modelVariables}


def test_box_dropped_on_the_table_rests_on_two_corners():
    """The box falls tilted, its corners collide in turn and it comes to rest on the two bottom
    corners in CONTACT, each carrying half its weight; the robot, held by its gravity torques far
    above, does not move. The gap Jacobian matches finite differences of the gaps."""
    from deltafmi.physics.delta.box import make_robot_box_contact
    from deltafmi.physics.delta.control import gravity_torque
    from deltafmi.physics.contact_problems.box_on_table import BoxModel

    p, box = d.RL5, BoxModel(mass=2.0, width=0.2, height=0.1)
    system = make_robot_box_contact(p, -1.15, box, CompliantMaterial(K_SURFACE, C_SURFACE),
                                    CompliantMaterial(1e6, 4e3, restitution=0.3))
    robot = robot_start_state(p, [0.0, 0.0, -0.9])
    system.model.u = list(gravity_torque(p, robot[[0, 3, 6]]))
    angle = 0.05
    lift = 0.02 - float(np.min(box.rotated_corners(angle)[:, 1]))
    x0 = np.concatenate([robot[:9], [0.0, lift, angle], robot[9:], np.zeros(3)])
    q = x0[:12] + np.concatenate([np.full(9, 0.01), [0.01, 0.0, 0.1]])
    numeric = np.array([(system.model.gaps(q + 1e-7 * e) - system.model.gaps(q - 1e-7 * e)) / 2e-7
                        for e in np.eye(12)]).T
    np.testing.assert_allclose(system.model.gap_jacobian(q), numeric, atol=1e-8)
    result = simulate(system, (0.0, 0.6), x0, rtol=1e-7, atol=1e-10)
    corner_impacts = [ev.t for ev in result.events if ev.modes_before[2:4] == (0, 0) and 1 in ev.modes_after[2:4]]
    assert len(corner_impacts) >= 2  # it bounced
    assert list(result.modes[-1]) == [0, 0, 2, 2, 0, 0]
    np.testing.assert_allclose(result.forces[-1][2:4], [box.mass * G / 2] * 2, rtol=1e-6)
    np.testing.assert_allclose(d.wrist_position(p, result.x[-1][:9]), [0.0, 0.0, -0.9], atol=1e-9)


def test_robot_presses_a_box_off_centre(tmp_path):
    """contact_box.yaml with the box at rest and the tool 1 cm above it: pressing with F = 20 N at
    a = 3 cm from the box's centre, the corners carry (F + m g)/2 -+ a F / w (moment balance on the
    box, with the tool force and lever arm the run gives), the tool force is F less the 1000 N/m
    impedance's share of the sag (< 1 %)."""
    path = scenario_variant("contact_box", tmp_path, stop=1.0,
                            trajectory={"parameters": {"n_waypoints": 1, "wp_z": [-1.05] * 8}},
                            plant={"parameters": {"z0": [0.0, 0.0, -1.04], "box_drop": 0.0, "box_angle": 0.0}})
    c = run(path)
    assert [c[f"plant.mode[{i}]"][-1] for i in range(1, 7)] == [0, 2, 2, 2, 0, 0]
    tool, left, right = (c[f"plant.fn[{i}]"][-1] for i in (2, 3, 4))
    m, w, F = 2.0, 0.2, 20.0
    a = c["plant.tip[1]"][-1] - c["plant.box[1]"][-1]
    assert a == pytest.approx(0.03, abs=1e-3)
    assert tool == pytest.approx(F, rel=1e-2)
    assert left == pytest.approx((tool + m * G) / 2 - a * tool / w, rel=1e-4)
    assert right == pytest.approx((tool + m * G) / 2 + a * tool / w, rel=1e-4)
