"""``deltafmi animate``: the robot drawn from recorded servo angles, written as a GIF."""
from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from deltafmi.apps.cli import main
from deltafmi.physics import delta as d
from deltafmi.apps.animation.animate import frame_rows, load_recording, robot_points


@pytest.fixture
def result(tmp_path):
    """A result file of a wrist moving down 5 cm over 1 s onto a plane, as the master writes it."""
    t = np.linspace(0.0, 1.0, 101)
    wrists = np.column_stack([0.02 * t, np.zeros_like(t), -1.0 - 0.05 * t])
    servo = np.array([d.inverse_kinematics(d.RL5, z)[0::3] for z in wrists])
    header = ["time", "plant.y[1]", "plant.y[2]", "plant.y[3]", "plant.fn", "plant.mode",
              "plant.surface_height", "plant.surface_normal[1]", "plant.surface_normal[2]",
              "plant.surface_normal[3]", "plant.tool[1]", "plant.tool[2]", "plant.tool[3]"]
    fn = np.where(t > 0.8, 10.0, 0.0)
    rows = np.column_stack([t, servo, fn, (fn > 0) * 2, np.full_like(t, -1.15), np.zeros_like(t),
                            np.zeros_like(t), np.ones_like(t), np.zeros_like(t), np.zeros_like(t),
                            np.full_like(t, -0.1)])
    path = tmp_path / "run.csv"
    np.savetxt(path, rows, delimiter=",", header=",".join(header), comments="")
    return path, wrists


def test_drawn_robot_is_the_recorded_one(result):
    """The drawing's arms close their loops: every forearm, elbow to wrist joint, is l2 long, and
    the plate sits at the wrist the servo angles were computed from."""
    path, wrists = result
    rec = load_recording(path)
    assert rec.plant == "plant" and rec.surface[0] == -1.15 and list(rec.tool) == [0.0, 0.0, -0.1]
    for servo, wrist in zip(rec.servo[::10], wrists[::10]):
        arms = robot_points(rec.params, servo)
        for rotation, (base, elbow, joint) in zip(d.ARM_ROTATIONS, arms):
            assert np.linalg.norm(elbow - base) == pytest.approx(d.RL5.l1, rel=1e-12)
            assert np.linalg.norm(joint - elbow) == pytest.approx(d.RL5.l2, rel=1e-9)
            np.testing.assert_allclose(joint - rotation @ [0.0, d.RL5.l3, 0.0], wrist, atol=1e-9)


def test_frames_take_the_last_row_at_each_instant():
    time = np.array([0.0, 0.1, 0.2, 0.2, 0.3])  # an event: two rows at 0.2
    assert list(frame_rows(time, fps=10.0, speed=1.0)) == [0, 1, 3, 4]
    assert list(frame_rows(time, fps=10.0, speed=2.0)) == [0, 3]


def test_animate_writes_a_gif(result, tmp_path):
    path, _ = result
    out = tmp_path / "robot.gif"
    run = CliRunner().invoke(main, ["animate", str(path), "-o", str(out), "--fps", "10", "--size", "4"])
    assert run.exit_code == 0, run.output
    with Image.open(out) as gif:
        assert gif.n_frames == 11 and gif.size == (320, 160)


def test_animate_without_servo_angles_is_bad_input(tmp_path):
    path = tmp_path / "other.csv"
    path.write_text("time,osc.x\n0.0,1.0\n0.1,0.9\n")
    run = CliRunner().invoke(main, ["animate", str(path), "-o", str(tmp_path / "x.gif")])
    assert run.exit_code == 2
    assert run.output.strip() == (f"Error: {path}: no columns <plant>.y[1..3] (servo angles: record "
                                  "'plant.y[*]')")
    run = CliRunner().invoke(main, ["animate", str(path), "-o", str(tmp_path / "x.png")])
    assert run.exit_code == 2 and "written as .gif or .mp4" in run.output


@pytest.mark.parametrize("suffix", [".parquet", ".mat"])
def test_animate_reads_every_result_format(result, tmp_path, suffix):
    """A .parquet or .mat result gives the robot the .csv gives (it was read as UTF-8 text)."""
    from deltafmi.master.results.result import read_result

    path, _ = result
    other = read_result(path).save(tmp_path / f"run{suffix}")
    text, binary = load_recording(path), load_recording(other)
    assert np.array_equal(binary.servo, text.servo) and np.array_equal(binary.time, text.time)
    assert binary.surface[0] == text.surface[0] and np.array_equal(binary.force, text.force)
    assert np.array_equal(binary.mode, text.mode) and np.array_equal(binary.tool, text.tool)
    out = tmp_path / "robot.gif"
    run = CliRunner().invoke(main, ["animate", str(other), "-o", str(out), "--fps", "2", "--size", "4"])
    assert run.exit_code == 0, run.output
    with Image.open(out) as gif:
        assert gif.n_frames == 3


def test_animate_a_result_without_rows_is_bad_input(tmp_path):
    path = tmp_path / "empty.csv"
    path.write_text("time,plant.y[1],plant.y[2],plant.y[3]\n")
    run = CliRunner().invoke(main, ["animate", str(path), "-o", str(tmp_path / "x.gif")])
    assert run.exit_code == 2 and run.output.strip() == f"Error: {path} has no rows"
