"""``deltafmi animate`` of the spherical wrist and of a peg-in-hole insertion: the drawn peg, hole,
force and wrist against closed-form geometry (a synthetic result with known peg poses) and against
a real DeltaWrist FMU run (fmpy, Co-Simulation)."""
from __future__ import annotations

import math

import fmpy
import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image
from scipy.spatial.transform import Rotation

from deltafmi.apps.cli import main
from deltafmi.builder import build_cached
from deltafmi.physics import delta as d
from deltafmi.physics.delta.kinematics import forward_kinematics
from deltafmi.apps.animation.animate import Scene, load_recording
from deltafmi.apps.animation.peg_geometry import RIM_SAMPLES, action_point, peg_silhouette

R_PEG, L_PEG, TIP_DIST, MOUNT = 0.01, 0.1, 0.13, np.array([0.0, 0.0, -0.05])
HOLE_AT, TILT = np.array([0.01, -0.02, -1.2]), (0.04, -0.03)          # tilt about world x, then world y
BORE, CHAMFER, ANGLE, DEPTH = 0.0102, 0.003, math.radians(30.0), 0.035
THETA = 0.05                                                           # rad, the peg's tilt in the section plane
#: the sampled rims' support deficit: at most r (1 - cos(pi / N)) (a chord's sagitta), 3.0e-4 r at N = 128
SAGITTA = R_PEG * (1.0 - math.cos(math.pi / RIM_SAMPLES))


def rot(axis: int, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about basis axis ``axis`` (scipy's, independent of deltafmi's)."""
    return Rotation.from_rotvec(angle * np.eye(3)[axis]).as_matrix()


R_HOLE = rot(1, TILT[1]) @ rot(0, TILT[0])   # hole frame -> world
TOOL_DOWN = rot(0, math.pi)                  # tool z pointing down


def poses():
    """Hole-frame peg poses at t = 0, 0.1, ... 1.0: the tip from 4 mm off the axis (along -x) and
    20 mm above the top down to 15 mm deep, the peg tilted THETA about the hole's y axis (its axis in
    the section plane x-z); the last row tilted out of that plane too (0.1 rad about the hole's x)."""
    t = np.linspace(0.0, 1.0, 11)
    tips = np.column_stack([-0.004 * (1.0 - t), np.zeros_like(t), 0.02 - 0.035 * t])
    rotations = np.array([rot(1, THETA) @ TOOL_DOWN] * len(t))
    rotations[-1] = rot(0, 0.1) @ rot(2, 0.3) @ rot(1, THETA) @ TOOL_DOWN
    return t, tips, rotations


def contact(tip_h: np.ndarray, rotation_h: np.ndarray):
    """A force at the peg's rim point along its tool x axis, normal to the 30 deg chamfer (hole
    frame), and its moment about the tip: (force, moment, contact point)."""
    point = tip_h + R_PEG * rotation_h[:, 0]
    rho = np.array([point[0], point[1], 0.0]) / math.hypot(point[0], point[1])
    force = 40.0 * (-math.sin(ANGLE) * rho + np.array([0.0, 0.0, math.cos(ANGLE)]))
    return force, np.cross(point - tip_h, force), point


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """A DeltaWristPeg-like result: servo angles of the plate that puts the peg at each pose, R,
    centre, tip (world), the contact force of :func:`contact` from t = 0.5 on, and the hole's
    parameters recorded as columns (not the model's defaults)."""
    t, tips_h, rot_h = poses()
    tips = HOLE_AT + tips_h @ R_HOLE.T
    rotations = np.einsum("ij,njk->nik", R_HOLE, rot_h)
    centres = tips - rotations[:, :, 2] * TIP_DIST
    servo = np.array([d.inverse_kinematics(d.RL5, c - MOUNT)[0::3] for c in centres])
    forces, moments = np.zeros((len(t), 3)), np.zeros((len(t), 3))
    for k in np.flatnonzero(t >= 0.5):
        f, m, _ = contact(tips_h[k], rot_h[k])
        forces[k], moments[k] = R_HOLE @ f, R_HOLE @ m
    cols = {"time": t}
    cols.update({f"plant.y[{i + 1}]": servo[:, i] for i in range(3)})
    cols.update({f"plant.R[{i + 1}]": rotations[:, i // 3, i % 3] for i in range(9)})
    for name, values in (("centre", centres), ("tip", tips), ("contact_force", forces), ("contact_moment", moments)):
        cols.update({f"plant.{name}[{i + 1}]": values[:, i] for i in range(3)})
    constants = {"hole_position[1]": HOLE_AT[0], "hole_position[2]": HOLE_AT[1], "hole_position[3]": HOLE_AT[2],
                 "hole_tilt[1]": TILT[0], "hole_tilt[2]": TILT[1], "bore_radius": BORE, "chamfer_width": CHAMFER,
                 "chamfer_angle": ANGLE, "hole_depth": DEPTH, "tool_radius": R_PEG, "tool_length": L_PEG}
    cols.update({f"plant.{k}": np.full_like(t, v) for k, v in constants.items()})
    cols["plant.depth"] = -tips_h[:, 2]
    cols["plant.success"] = (-tips_h[:, 2] >= 0.01).astype(float)
    path = tmp_path_factory.mktemp("peg") / "peg.csv"
    np.savetxt(path, np.column_stack(list(cols.values())), delimiter=",", header=",".join(cols), comments="")
    return path, tips_h, rot_h


@pytest.fixture(scope="module")
def scene(synthetic):
    path, _, _ = synthetic
    drawn = Scene(load_recording(path), fps=10.0, size=8.0)   # frame k = row k
    yield drawn
    drawn.close()


def in_section(p: np.ndarray) -> np.ndarray:
    """Section coordinates (mm) of hole-frame points: the first tip is off the axis along -x, so
    the section plane is x-z with s = -x."""
    return np.stack([-p[..., 0], p[..., 2]], axis=-1) * 1e3


def test_parameters_come_from_the_result(scene):
    rec = scene.rec
    hole = rec.hole.hole
    assert rec.defaults == () and (hole.bore_radius, hole.depth, hole.tilt_y) == (BORE, DEPTH, TILT[1])
    assert (rec.wrist.radius, rec.wrist.length) == (R_PEG, L_PEG)
    # the drawn fixture: chamfer from (R_b + w, 0) to (R_b, -w tan 30 deg), bore down to -depth (mm)
    outline = scene.section.ax.patches[0].get_xy()
    for corner in [(BORE + CHAMFER, 0.0), (BORE, -CHAMFER * math.tan(ANGLE)), (BORE, -DEPTH)]:
        for side in (1.0, -1.0):
            assert np.min(np.linalg.norm(outline - [side * corner[0] * 1e3, corner[1] * 1e3], axis=1)) < 1e-9


@pytest.mark.parametrize("k", [0, 4, 7])
def test_peg_outline_in_the_plane_is_its_rectangle(scene, synthetic, k):
    """The peg's axis in the section plane: its outline is the rectangle tip +- r e, tip + L a +- r e
    (a: the axis upward, e normal to it in the plane), to rounding (1e-9 mm)."""
    _, tips, _ = synthetic
    scene.draw(k)
    tip = in_section(tips[k])
    a, e = np.array([-math.sin(THETA), math.cos(THETA)]), np.array([math.cos(THETA), math.sin(THETA)])
    corners = [tip + sign * R_PEG * 1e3 * e + up * L_PEG * 1e3 * a for sign in (1, -1) for up in (0, 1)]
    drawn = scene.section.peg.get_xy()[:-1]
    assert len(drawn) == 4
    for corner in corners:
        assert np.min(np.linalg.norm(drawn - corner, axis=1)) < 1e-9


def test_peg_outline_out_of_the_plane_has_the_cylinders_support(scene, synthetic):
    """The last pose turns the axis out of the plane. A cylinder's projection has the support
    function h(w) = max(w.tip, w.top) + r sqrt(1 - (w3 . a)^2) (w3: the plane direction w in 3D,
    a the unit axis: a disk's support); the drawn outline must match it to within the sagitta of
    the sampled rims, r (1 - cos(pi / N)) = 3 um, in every direction."""
    _, tips, rotations = synthetic
    k = len(tips) - 1
    scene.draw(k)
    drawn = scene.section.peg.get_xy()
    axis = -rotations[k][:, 2]
    for phi in np.linspace(0.0, 2.0 * math.pi, 73):
        w = np.array([math.cos(phi), math.sin(phi)])
        w3 = np.array([-w[0], 0.0, w[1]])   # s = -x, h = z
        ends = [tips[k], tips[k] + L_PEG * axis]
        support = max(w3 @ p for p in ends) + R_PEG * math.sqrt(max(0.0, 1.0 - (w3 @ axis) ** 2))
        assert np.max(drawn @ w) == pytest.approx(support * 1e3, abs=SAGITTA * 1e3 + 1e-9)


def test_peg_is_painted_where_its_outline_is(scene, synthetic):
    """Rendered pixels: 10 mm up the peg's axis is the peg's blue, the bore 10 mm under and 5 mm beside
    the tip is white, the fixture beside the bore is grey."""
    _, tips, _ = synthetic
    scene.draw(7)
    fig, ax = scene.figure, scene.section.ax
    fig.canvas.draw()
    image = np.asarray(fig.canvas.buffer_rgba())[:, :, :3].astype(int)

    def pixel(point_mm):
        x, y = ax.transData.transform(point_mm)
        return image[int(round(image.shape[0] - y)), int(round(x))]

    tip = in_section(tips[7])
    inside = tip + 10.0 * np.array([-math.sin(THETA), math.cos(THETA)])
    peg, bore, fixture = pixel(inside), pixel(tip + [5.0, -10.0]), pixel([(BORE + 0.008) * 1e3, -DEPTH * 500.0])
    assert peg[2] - peg[0] > 60                         # blue: tab:blue at alpha 0.55 over white
    assert np.all(bore > 245)
    assert np.all(np.abs(fixture - fixture[0]) < 40) and fixture[0] < 225


def test_force_arrow_ends_at_the_contact(scene, synthetic):
    """The arrow ends where the force's line of action enters the peg, here the rim point the force
    acts at (to 1e-9 mm), points along F, and the largest force is 15 mm long."""
    _, tips, rotations = synthetic
    peak = max(np.linalg.norm(contact(tips[j], rotations[j])[0]) for j in range(5, 11))
    for k in (6, 9):
        scene.draw(k)
        force, _, point = contact(tips[k], rotations[k])
        arrow = scene.section.arrow
        head, tail = np.array(arrow.xy), np.array(arrow.xyann)
        np.testing.assert_allclose(head, in_section(point), atol=1e-9)
        np.testing.assert_allclose(head - tail, in_section(force) / 1e3 / peak * 15.0, atol=1e-9)
    scene.draw(2)
    assert scene.section.arrow is None


@pytest.mark.parametrize("point, force, expected", [
    ((R_PEG, 0.0, 0.005), (-3.0, 0.0, 0.0), (R_PEG, 0.0, 0.005)),      # on the side, pushed across
    ((0.003, 0.0, 0.0), (0.0, 0.0, 7.0), (0.003, 0.0, 0.0)),          # on the bottom face, pushed up
    ((0.0, 0.0, 0.02), (1.0, 0.0, 0.0), (-R_PEG, 0.0, 0.02)),         # given on the axis: enters at -r
])
def test_action_point_is_where_the_line_of_action_enters_the_peg(point, force, expected):
    """Upright peg (axis +z from the tip at 0): a force F at p (moment p x F about the tip) is drawn
    where its line p + t F enters the cylinder (closed forms on the right; rounding only)."""
    p, f = np.array(point), np.array(force)
    drawn = action_point(f, np.cross(p, f), np.array([0.0, 0.0, 1.0]), R_PEG, L_PEG)
    np.testing.assert_allclose(drawn, expected, atol=1e-15)


def test_action_point_of_a_couple_falls_back_to_the_tip():
    """A near couple (small F, large M): its central axis r0 = F x M / |F|^2 lies 5 km above the tip
    and misses the peg: drawn at the tip."""
    drawn = action_point(np.array([1e-3, 0.0, 0.0]), np.array([0.0, 5.0, 0.0]), np.array([0.0, 0.0, 1.0]),
                         R_PEG, L_PEG)
    assert np.array_equal(drawn, np.zeros(3))


def test_top_view_shows_the_bottom_rim(scene, synthetic):
    """Tilted THETA about y, the bottom rim seen down the hole axis is the ellipse with semi-axes
    r cos(THETA) (x) and r (y) about the tip."""
    _, tips, _ = synthetic
    scene.draw(4)
    x, y = (np.asarray(v) / 1e3 for v in scene.top.rim.get_data())
    ellipse = ((x - tips[4][0]) / (R_PEG * math.cos(THETA))) ** 2 + ((y - tips[4][1]) / R_PEG) ** 2
    np.testing.assert_allclose(ellipse, 1.0, atol=1e-9)


def test_success_badge_and_numbers(scene):
    scene.draw(3)
    assert scene.section.badge.get_text() == "not inserted" and "depth   -9.50 mm" in scene.section.label.get_text()
    scene.draw(9)
    assert scene.section.badge.get_text() == "inserted" and "depth   11.50 mm" in scene.section.label.get_text()


def test_peg_gif_and_bad_input(synthetic, tmp_path):
    path, _, _ = synthetic
    out = tmp_path / "peg.gif"
    run = CliRunner().invoke(main, ["animate", str(path), "-o", str(out), "--fps", "5", "--size", "6"])
    assert run.exit_code == 0, run.output
    assert "defaults" not in run.output
    with Image.open(out) as gif:
        assert gif.n_frames == 6 and gif.size == (480, 192)
    bad = tmp_path / "robot.csv"
    bad.write_text("time,plant.y[1],plant.y[2],plant.y[3],plant.tip[1]\n0.0,0.1,0.1,0.1,0.0\n")
    run = CliRunner().invoke(main, ["animate", str(bad), "-o", str(out), "--wrist"])
    assert run.exit_code == 2
    assert run.output.strip() == (f"Error: {bad}: no wrist: no columns 'plant.R[*]' or 'plant.qw[*]' (record the "
                                  "tool rotation or the wrist angles)")
    run = CliRunner().invoke(main, ["animate", str(bad), "-o", str(out), "--hole"])
    assert run.exit_code == 2 and "no wrist" in run.output
    wrist_only = tmp_path / "wrist.csv"
    wrist_only.write_text("time,plant.y[1],plant.y[2],plant.y[3],plant.qw[1],plant.qw[2],plant.qw[3]\n"
                          "0.0,0.1,0.1,0.1,0.0,0.0,0.0\n")
    run = CliRunner().invoke(main, ["animate", str(wrist_only), "-o", str(out), "--hole"])
    assert run.exit_code == 2 and run.output.strip().startswith(f"Error: {wrist_only}: no hole: no columns "
                                                                "'plant.depth' or 'plant.contact_force[*]'")
    for setting, message in (("radius=1", "expected NAME=VALUE"), ("hole_position=1,2", "3 value(s) expected"),
                             ("bore_radius=wide", "numbers separated by commas")):
        run = CliRunner().invoke(main, ["animate", str(wrist_only), "-o", str(out), "--hole", "--set", setting])
        assert run.exit_code == 2 and message in run.output and len(run.output.strip().splitlines()) == 1


def test_missing_geometry_is_taken_from_set_then_the_models_defaults(tmp_path):
    """A result with the wrist angles and the depth only: the hole position from --set, the rest the
    models' defaults, named in the output."""
    path = tmp_path / "bare.csv"
    servo = d.inverse_kinematics(d.RL5, [0.0, 0.0, -1.0])[0::3]
    path.write_text("time,plant.y[1],plant.y[2],plant.y[3],plant.qw[1],plant.qw[2],plant.qw[3],plant.depth\n"
                    + "".join(f"{t},{servo[0]},{servo[1]},{servo[2]},0.0,0.1,0.0,0.0\n" for t in (0.0, 0.5)))
    out = tmp_path / "bare.gif"
    run = CliRunner().invoke(main, ["animate", str(path), "-o", str(out), "--fps", "2", "--size", "5",
                                    "--set", "plant.hole_position=0,0,-1.2", "--set", "bore_radius=0.0105"])
    assert run.exit_code == 0, run.output
    assert run.output.splitlines()[0] == ("not in the result, drawn with the model's defaults: mount=0,0,-0.05 "
                                          "tool_tip=0.13 tool_radius=0.01 tool_length=0.1 hole_tilt=0,0 "
                                          "chamfer_width=0.002 chamfer_angle=0.785398 hole_depth=0.04")
    run = CliRunner().invoke(main, ["animate", str(path), "-o", str(out)])
    assert run.exit_code == 2 and "no 'plant.hole_position[*]'" in run.output


def test_real_delta_wrist_run(tmp_path):
    """A DeltaWrist FMU released at rest with zero torques and a tilted tool (fmpy CS, 0.3 s: it falls
    and the tool swings): the drawn plate (forward
    kinematics of the recorded servo angles) is the plant's plate centre z to 1e-9 m (its loops are
    projected closed after each step: residual ~1e-15 m, the FK's own rounding ~1e-12 m); the drawn
    peg's axis runs from the recorded wrist centre through the recorded tip (R's third column,
    tool_tip = 0.13 m away); from the wrist angles alone (R and centre not recorded) the same
    rotation to 1e-12 and centre to 1e-9 m; and the command writes the GIF."""
    names = ([f"{v}[{i}]" for v in ("y", "centre", "tip", "z", "qw") for i in (1, 2, 3)]
             + [f"R[{i}]" for i in range(1, 10)] + ["tool_radius", "tool_length", "mount[1]", "mount[2]", "mount[3]",
                                                    "tool_tip"])
    run = fmpy.simulate_fmu(build_cached("DeltaWrist"), fmi_type="CoSimulation", stop_time=0.3, output_interval=0.01,
                            start_values={"qw0[1]": 0.3, "qw0[2]": 0.6, "qw0[3]": -0.4, "tip0[1]": 0.05},
                            output=names)
    path = tmp_path / "wrist.csv"
    np.savetxt(path, np.column_stack([run["time"]] + [run[n] for n in names]), delimiter=",",
               header=",".join(["time"] + [f"plant.{n}" for n in names]), comments="")
    rec = load_recording(path)
    assert rec.hole is None and rec.defaults == ()
    plates = np.column_stack([run[f"z[{i}]"] for i in (1, 2, 3)])
    np.testing.assert_allclose([forward_kinematics(rec.params, q) for q in rec.servo], plates, atol=1e-9)
    scene = Scene(rec, fps=10.0, size=5.0)
    try:
        for k in (0, 3):
            scene.draw(k)
            row = scene.rows[k]
            bottom, top = (np.array(line.get_data_3d()).T for line in scene.robot.wrist.rims)
            np.testing.assert_allclose(bottom[:-1].mean(axis=0), rec.wrist.tip[row], atol=1e-12)
            axis = (bottom[:-1].mean(axis=0) - top[:-1].mean(axis=0)) / L_PEG
            centre_to_tip = rec.wrist.tip[row] - rec.wrist.centre[row]
            np.testing.assert_allclose(centre_to_tip, TIP_DIST * axis, atol=1e-9)
            np.testing.assert_allclose(np.linalg.norm(bottom - rec.wrist.tip[row], axis=1), R_PEG, rtol=1e-12)
    finally:
        scene.close()
    kept = [i for i, n in enumerate(names) if not n.startswith(("R[", "centre[", "tip["))]
    bare = tmp_path / "angles.csv"
    np.savetxt(bare, np.column_stack([run["time"]] + [run[names[i]] for i in kept]), delimiter=",",
               header=",".join(["time"] + [f"plant.{names[i]}" for i in kept]), comments="")
    from_angles = load_recording(bare)
    np.testing.assert_allclose(from_angles.wrist.rotation, rec.wrist.rotation, atol=1e-12)
    np.testing.assert_allclose(from_angles.wrist.centre, rec.wrist.centre, atol=1e-9)
    np.testing.assert_allclose(from_angles.wrist.tip, rec.wrist.tip, atol=1e-9)
    out = tmp_path / "wrist.gif"
    cli = CliRunner().invoke(main, ["animate", str(path), "-o", str(out), "--fps", "10", "--size", "4", "--wrist"])
    assert cli.exit_code == 0, cli.output
    with Image.open(out) as gif:
        assert gif.n_frames == 4


def test_silhouette_of_an_upright_peg_is_exact():
    """Upright peg (axis along the hole axis): the outline is the 2r x L rectangle."""
    outline = peg_silhouette(np.array([0.001, 0.0, -0.01]), TOOL_DOWN, R_PEG, L_PEG, np.array([1.0, 0.0, 0.0]))
    s, h = outline[:-1].T
    assert (s.min(), s.max(), h.min(), h.max()) == pytest.approx((-0.009, 0.011, -0.01, 0.09), abs=1e-15)
