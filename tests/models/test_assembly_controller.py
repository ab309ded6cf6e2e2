"""The AssemblyController FMU in closed loop with the 6-DOF plant FMUs (DeltaWrist, DeltaWristPeg):
pose tracking (examples/wrist_pose_tracking.yaml) and peg-in-hole insertion (examples/peg_in_hole.yaml)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu

import deltafmi
from deltafmi.builder import build_cached
from deltafmi.shipped import SCENARIOS_DIR
from deltafmi.physics.assembly.rotation import TOOL_DOWN, orientation_reference, rotation_vector

T = 1e-3  # controller sample period (s)
ASSEMBLY_DOC = Path(__file__).resolve().parents[2] / "docs" / "assembly.md"


def _documented(figure: str) -> None:
    """The run's figure, as docs/assembly.md quotes it, is there: a changed result fails until the
    doc says it (benchmarks/docs_figures.py lists where every figure of the doc comes from)."""
    assert figure in " ".join(ASSEMBLY_DOC.read_text().split()), f"docs/assembly.md does not say {figure!r}"


def _columns(result, name: str, n: int) -> np.ndarray:
    return np.column_stack([result[f"{name}[{i}]"] for i in range(1, n + 1)])


def _snap(distance: float, duration: float) -> float:
    """Largest fourth derivative of a rest-to-rest minimum-jerk move: d (360 - 720 s) / T^4 at s = 0."""
    return 360.0 * distance / duration ** 4


def test_the_six_dof_loop_tracks_a_tip_path_and_a_tilt_path():
    res = deltafmi.simulate("wrist_pose_tracking")
    tip, r = _columns(res, "plant.tip", 3), _columns(res, "tip_path.r", 3)
    R = _columns(res, "plant.R", 9)
    phi = _columns(res, "tilt_path.r", 2)
    # the paths really move the tool: 5 cm and 0.2 rad
    assert np.ptp(r[:, 0]) == pytest.approx(0.05) and np.ptp(phi[:, 0]) == pytest.approx(0.2)
    # the true orientation error from the plant's R against R_ref = exp([phi]) R_down
    rot_err = np.array([rotation_vector(tuple((Rk.reshape(3, 3) @ np.array(
        orientation_reference((p[0], p[1], 0.0), (0.0,) * 3, (0.0,) * 3, TOOL_DOWN)[0]).reshape(3, 3).T).ravel()))
        for Rk, p in zip(R, phi)])
    # Bound: with the model exact, what remains is the zero-order hold. The half-sample lead
    # makes the held torque's mean second-order accurate, leaving an acceleration error of order
    # T^2 times the reference's snap; the error dynamics pass it with their static gain 1 / wn^2
    # (wn = 31.6 rad/s): |e| <= T^2 snap_max / wn^2 (7.0e-7 m for 5 cm in 0.4 s, 2.8e-6 rad for
    # 0.2 rad in 0.4 s).
    wn2 = 5000.0 / 5.0
    print(f"\ntracking: tip {np.abs(tip - r).max():.1e} m, orientation {np.abs(rot_err).max():.1e} rad")
    assert np.abs(tip - r).max() <= T ** 2 * _snap(0.05, 0.4) / wn2
    assert np.abs(rot_err).max() <= T ** 2 * _snap(0.2, 0.4) / wn2
    # the controller's estimate (Newton forward kinematics of the measured angles, recorded in the
    # row of the plant's outputs it read) is the plant's tip: Newton stops at a 1e-12 m loop
    # residual, which the forward kinematics' conditioning (cond(Jc) ~ 10) turns into ~1e-11 m
    assert np.abs(_columns(res, "controller.tip_est", 3) - tip).max() < 1e-11
    assert set(res["controller.status"]) == {0} and res["plant.residual"].max() < 1e-9


@pytest.mark.parametrize("scenario, stop", [("wrist_pose_tracking", 0.3), ("peg_in_hole", 1.3)])
def test_compiled_kernels_equal_the_python_methods(monkeypatch, scenario, stop):
    # the FMUs' C kernels (the controller's step generated from controller_step) against their
    # Python methods, on the same closed loop (reference inputs; the program into contact): every
    # recorded controller variable bit for bit
    results = {}
    for native in ("1", "0"):
        monkeypatch.setenv("DELTAFMI_NATIVE", native)
        results[native] = deltafmi.simulate(scenario, stop=stop, record=["controller.*"])
    for name in results["1"].names:
        assert np.array_equal(results["1"][name], results["0"][name]), name


@pytest.mark.parametrize("start, message", [
    ({"mass[2]": 0.0}, "mass (5.0, 0.0, 10.0) and inertia (0.02, 0.02, 0.02) must be > 0"),
    ({"push_force": 0.0}, "push_force must be > 0, got 0.0"),
])
def test_bad_parameters_fail_initialization_with_a_clear_message(start, message, capfd):
    with pytest.raises(Exception, match="fmi2ExitInitializationMode failed"):
        simulate_fmu(str(build_cached("AssemblyController")), fmi_type="CoSimulation", start_values=start)
    messages = "".join(capfd.readouterr()).splitlines()
    assert any(message in m for m in messages), messages


# the shipped peg_in_hole.yaml's geometry: peg d = 20 mm in a bore D = 20.2 mm whose 2 mm, 45-degree
# chamfer puts the bore edge (the chamfer/bore ring, the second point of two-point contact) 2 mm
# below the hole's top
D_PEG, D_BORE, BORE_EDGE = 0.020, 0.0202, 0.002
PEG = "peg_in_hole"


def _insert(**parameters):
    res = deltafmi.simulate(PEG, parameters=parameters)
    return res, res["plant.depth"], res["plant.lateral_misalignment"], res["plant.angular_misalignment"]


def test_the_peg_goes_into_a_hole_off_by_two_mm_and_one_degree():
    # The controller knows the hole only nominally (1.8 mm off, 1 degree tilted): the chamfer
    # centres the peg against the soft lateral impedance and the bore's contacts align it against
    # the soft rotational one (about the tip). At the end the misalignments are what a rigid peg in
    # the bore allows: the tip within the clearance c = (D - d)/2 of the axis and the tilt within
    # (D - d) / l for the engaged length l below the bore edge (d cos th + l sin th = D), each plus the
    # penalty contacts' deflection (|f_n| / k < 0.1 mm / 33 mm here: the 1e-5 margins).
    res, depth, lateral, angular = _insert()
    # at the start the tip is 2.1 mm off the true axis (1.8 mm at the top, 0.5 mm more 3 cm above it)
    assert lateral[0] > 20 * (D_BORE - D_PEG) / 2 and angular[0] == pytest.approx(0.01745)
    assert res["plant.success"][-1] == 1 and depth[-1] >= 0.03
    engaged = depth[-1] - BORE_EDGE
    print(f"\nmisalignment: lateral {lateral[0]:.3e} -> {lateral[-1]:.3e} m, angular {angular[0]:.5f} -> "
          f"{angular[-1]:.5f} rad (docs/assembly.md)")
    assert lateral[-1] <= (D_BORE - D_PEG) / 2 + 1e-5
    assert angular[-1] <= (D_BORE - D_PEG) / engaged + 1e-4
    _documented(f"lateral misalignment {lateral[0] * 1e3:.1f} mm -> {lateral[-1] * 1e3:.2f} mm (the clearance), "
                f"angular {angular[0]:.4f} -> {angular[-1]:.4f} rad")
    assert set(res["controller.phase"]) == {1, 2, 3} and set(res["controller.status"]) == {0}


def test_a_stiff_wrist_wedges_where_a_compliant_one_inserts():
    # Same plant, mu = 0.5, the hole tilted 3 degrees. Compliant about the tip (1 N m/rad) the
    # peg turns into the bore and goes in. Held stiffly (500 N m/rad) it keeps its 3 degrees and
    # meets the bore at two points: rigid geometry puts the second contact l = (D - d cos th) /
    # sin th = 4.3 mm below the bore edge, where l / d = 0.22 < mu (Whitney's wedging condition,
    # deltafmi/physics/friction/peg.py): it must stay wedged, short of l = mu d below the bore edge,
    # while the program pushes with its full 20 N (the tip 13 mm behind the reference).
    tilted = {"plant.mu": 0.5, "plant.hole_tilt": [0.0524, 0.0]}
    res, depth, _, angular = _insert(**tilted)
    assert res["plant.success"][-1] == 1 and angular[-1] < 0.01
    res, depth, _, angular = _insert(**tilted, **{"controller.rot_stiffness": [500.0] * 3,
                                                  "controller.inertia": [0.05] * 3})
    assert res["plant.success"][-1] == 0
    print(f"\nwedged: {depth[-1] * 1e3:.2f} mm below the top at the end (docs/assembly.md)")
    _documented(f"{depth[-1] * 1e3:.1f} mm below the top at {res['time'][-1]:g} s")
    assert depth[-1] - BORE_EDGE < 0.5 * D_PEG and angular[-1] > 0.05
    assert res["controller.depth_ref"][-1] - depth[-1] == pytest.approx(20.0 / 1500.0, rel=0.05)
    # and the fixture takes that push: the contact force along the (3-degree) hole axis is K e = 20 N
    axis = np.array([0.0, -np.sin(0.0524), np.cos(0.0524)])  # Ry(0) Rx(0.0524) e_z
    assert _columns(res, "plant.contact_force", 3)[-1] @ axis == pytest.approx(20.0, rel=0.05)


def test_model_exchange_samples_at_time_events_like_co_simulation(tmp_path):
    # the controller as Model Exchange: its samples are time events (the compiled update kernel)
    # at the same instants, with the same inputs, as Co-Simulation's doStep: the same loop, up to
    # the rounding of the instants (k h against sums of h) in the plant's integration
    source = SCENARIOS_DIR / "wrist_pose_tracking.yaml"
    text = source.read_text().replace("source: deltafmi.models:AssemblyController\n    interface: CS",
                                      "source: deltafmi.models:AssemblyController\n    interface: ME")
    assert "interface: ME" in text.split("controller:")[1].split("plant:")[0]
    (tmp_path / "me.yaml").write_text(text)
    cs = deltafmi.simulate("wrist_pose_tracking", stop=0.5)
    me = deltafmi.simulate(tmp_path / "me.yaml", stop=0.5)
    assert len(me.time) > len(cs.time)  # the events add rows
    for name in ("plant.tip", "controller.u", "controller.tau"):
        a, b = _columns(me, name, 3)[-1], _columns(cs, name, 3)[-1]
        assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max(), name   # measured: 2e-16 (tip), 7e-14 (u)
