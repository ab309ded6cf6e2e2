"""Draw the delta robot from a result file: the three arms, the travelling plate, the tool and the
surface it touches, one frame per instant, written as a GIF (Pillow) or MP4 (ffmpeg).

Only the recorded servo angles ``<plant>.y[1..3]`` are needed: the wrist follows from the
closed-form forward kinematics and each elbow from its servo angle. Whatever else the result
holds is used when present: the robot's geometry (``<plant>.l0`` ... ``l3``, else RL5), the tool
offset (``<plant>.tool[1..3]``), the plane (``<plant>.surface_height``,
``<plant>.surface_normal[1..3]``), the contact (``<plant>.fn``, ``<plant>.mode``, or the magnitude
of ``<plant>.normal_force[1..3]``) and a box on the table (``<plant>.box[1..3]``: x, height of its
centre above the table, rotation; ``<plant>.box_width``, ``<plant>.box_height``).

A robot with a spherical wrist (``<plant>.R[1..9]`` or ``<plant>.qw[1..3]``: DeltaWrist) is drawn
with its wrist centre and the peg as a cylinder along the tool axis; a result that records a
peg-in-hole insertion (DeltaWristPeg's ``depth``, ``contact_force`` ..., or ``hole_position``)
adds a close-up: a side section through the hole axis and a top view (:mod:`.peg_view`). Which
columns and parameters are read: :mod:`.columns`.
"""
from __future__ import annotations

import math
import re
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from deltafmi.master.results.result import read_result
from deltafmi.errors import BadInput, did_you_mean
from deltafmi.physics.delta.kinematics import forward_kinematics
from deltafmi.physics.delta.params import ARM_ROTATIONS, RL5, DeltaParams
from .columns import Columns
from .peg_recording import HoleTrack, WristTrack, load_hole, load_wrist
from .peg_view import HoleSectionView, HoleTopView
from .wrist_view import WristArtists

__all__ = ["Scene", "check_output", "frame_rows", "load_recording", "robot_points", "write_animation"]

_MODES = ("free", "collision", "contact")


@dataclass
class Recording:
    """The columns of one robot in a result file, by what they mean."""

    plant: str
    time: np.ndarray
    servo: np.ndarray                   #: (n, 3) servo angles
    params: DeltaParams
    tool: np.ndarray                    #: (3,) tool tip from the plate centre
    surface: Optional[tuple[float, np.ndarray]]   #: (height, unit normal) or None
    force: Optional[np.ndarray]         #: normal force on the tool, or None
    mode: Optional[np.ndarray]          #: contact mode, or None
    box: Optional[tuple[np.ndarray, float, float]] = None   #: (poses (n, 3), width, height), or None
    wrist: Optional[WristTrack] = None  #: the spherical wrist's tool, or None
    hole: Optional[HoleTrack] = None    #: the peg-in-hole insertion, or None
    defaults: tuple[str, ...] = ()      #: parameters not in the result, drawn with the model's default

    def box_outline(self, row: int) -> np.ndarray:
        """The box's corners (x, z), world, closed polygon (5 x 2) at ``row``."""
        assert self.box is not None
        poses, width, height = self.box
        x, lift, theta = poses[row]
        c, s = math.cos(theta), math.sin(theta)
        local = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]]) * [width / 2, height / 2]
        base = self.surface[0] if self.surface is not None else 0.0
        return np.column_stack([x + c * local[:, 0] - s * local[:, 1], base + lift + s * local[:, 0] + c * local[:, 1]])


def find_plants(names: Sequence[str]) -> list[str]:
    """Components whose servo angles ``<name>.y[1..3]`` are all in the result."""
    found = []
    for name in names:
        match = re.fullmatch(r"(.+)\.y\[1\]", name)
        if match and {f"{match.group(1)}.y[2]", f"{match.group(1)}.y[3]"} <= set(names):
            found.append(match.group(1))
    return found


def load_recording(result: str | Path, plant: Optional[str] = None, settings: Optional[dict] = None,
                   wrist: Optional[bool] = None, hole: Optional[bool] = None) -> Recording:
    """The robot ``plant`` (found automatically when the result holds one robot) of ``result``
    (a ``.csv``, ``.parquet`` or ``.mat`` result file). ``settings``: parameter values the result
    does not record ({name: values}, :func:`.columns.parse_settings`). ``wrist``, ``hole``: True
    requires the wrist / the insertion (BadInput naming the missing columns), False ignores it,
    None takes it when the result has it."""
    recorded = read_result(result)
    if not len(recorded):
        raise BadInput(f"{result} has no rows")
    plants = find_plants(recorded.names)
    if plant is None:
        if len(plants) != 1:
            what = "no columns <plant>.y[1..3] (servo angles: record 'plant.y[*]')" if not plants else \
                f"several robots ({', '.join(plants)}): choose one with --plant"
            raise BadInput(f"{result}: {what}")
        plant = plants[0]
    elif plant not in plants:
        raise BadInput(f"{result}: no servo angles '{plant}.y[1..3]'{did_you_mean(plant, plants)}")
    column = {name: recorded[name] for name in recorded}

    def first(name: str, default: float) -> float:
        values = column.get(f"{plant}.{name}")
        return default if values is None else float(values[0])

    params = DeltaParams(**{k: first(k, getattr(RL5, k)) for k in ("l0", "l1", "l2", "l3")})
    tool = np.array([first(f"tool[{i}]", 0.0) for i in (1, 2, 3)])
    surface = None
    if f"{plant}.surface_height" in column:
        normal = np.array([first(f"surface_normal[{i}]", 1.0 if i == 3 else 0.0) for i in (1, 2, 3)])
        surface = (first("surface_height", 0.0), normal / np.linalg.norm(normal))
    servo = np.column_stack([column[f"{plant}.y[{i}]"] for i in (1, 2, 3)])
    force = column.get(f"{plant}.fn")
    if force is None and f"{plant}.normal_force[3]" in column:
        force = np.linalg.norm([column[f"{plant}.normal_force[{i}]"] for i in (1, 2, 3)], axis=0)
    box = None
    if f"{plant}.box[3]" in column and f"{plant}.box_width" in column:
        box = (np.column_stack([column[f"{plant}.box[{i}]"] for i in (1, 2, 3)]),
               first("box_width", 0.0), first("box_height", 0.0))
    rec = Recording(plant, column["time"], servo, params, tool, surface, force, column.get(f"{plant}.mode"), box)
    columns, defaults = Columns(plant, column, settings or {}, str(result)), []
    if hole and wrist is False:
        raise BadInput("the hole's close-up draws the peg the wrist holds: drop --no-wrist")
    if wrist is not False:
        rec.wrist = load_wrist(columns, lambda: np.array([forward_kinematics(params, q) for q in servo]),
                               bool(wrist) or bool(hole), defaults)
    if hole is not False and rec.wrist is not None:
        rec.hole = load_hole(columns, bool(hole), defaults)
    rec.defaults = tuple(defaults)
    return rec


def robot_points(params: DeltaParams, servo: Sequence[float],
                 wrist: Optional[np.ndarray] = None) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per arm: servo axis point, elbow and wrist joint (world, m) at the servo angles ``servo``;
    the wrist (plate centre) from the closed-form forward kinematics unless given."""
    z = forward_kinematics(params, servo) if wrist is None else wrist
    arms = []
    for rotation, angle in zip(ARM_ROTATIONS, servo):
        base = rotation @ np.array([0.0, params.l0, 0.0])
        elbow = rotation @ np.array([0.0, params.l0 + params.l1 * math.cos(angle), params.l1 * math.sin(angle)])
        arms.append((base, elbow, z + rotation @ np.array([0.0, params.l3, 0.0])))
    return arms


def frame_rows(time: np.ndarray, fps: float, speed: float) -> np.ndarray:
    """Row of each frame: the last sample at or before each frame instant."""
    instants = np.arange(time[0], time[-1] + 1e-12, speed / fps)
    return np.clip(np.searchsorted(time, instants, side="right") - 1, 0, len(time) - 1)


def check_output(output: str | Path, fps: float, speed: float, size: float) -> None:
    """BadInput unless ``output`` is a .gif (or an .mp4 with ffmpeg) and the numbers are > 0."""
    suffix = Path(output).suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise BadInput(f"{output}: the animation is written as .gif or .mp4")
    if suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise BadInput(f"{output}: .mp4 needs ffmpeg on the PATH; write a .gif instead")
    if not (fps > 0 and speed > 0 and size > 0):
        raise BadInput(f"fps ({fps}), speed ({speed}) and size ({size}) must be > 0")


def write_animation(rec: Recording, output: str | Path, fps: float = 20.0, speed: float = 1.0, size: float = 8.0,
                    elevation: float = 12.0, azimuth: float = -60.0) -> Path:
    """Write the animation of ``rec`` to ``output`` (checked by :func:`check_output`)."""
    from matplotlib.animation import FFMpegWriter, FuncAnimation, PillowWriter

    output = Path(output)
    scene = Scene(rec, fps, speed, size, elevation, azimuth)
    animation = FuncAnimation(scene.figure, scene.draw, frames=len(scene.rows), blit=False)
    output.parent.mkdir(parents=True, exist_ok=True)
    writer = PillowWriter(fps=fps) if output.suffix.lower() == ".gif" else FFMpegWriter(fps=fps)
    animation.save(str(output), writer=writer, dpi=80)
    scene.close()
    return output


class Scene:
    """The figure of one animation: the robot in 3D and the close-ups the recording calls for
    (``side``: the surface, ``section`` and ``top``: the hole; None where absent); ``draw(k)``
    shows frame k (row ``rows[k]`` of the recording)."""

    def __init__(self, rec: Recording, fps: float = 20.0, speed: float = 1.0, size: float = 8.0,
                 elevation: float = 12.0, azimuth: float = -60.0) -> None:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        self.rec, self.rows = rec, frame_rows(rec.time, fps, speed)
        self.wrists = np.array([forward_kinematics(rec.params, rec.servo[row]) for row in self.rows])
        ratios = [1.5] + [1.0] * (rec.surface is not None) + [1.0, 0.7] * (rec.hole is not None)
        self.figure = fig = plt.figure(figsize=(size, size * {1: 0.9, 2: 0.5}.get(len(ratios), 0.4)))
        grid = fig.add_gridspec(1, len(ratios), width_ratios=ratios)
        self.robot = _RobotView(fig.add_subplot(grid[0, 0], projection="3d"), rec, elevation, azimuth)
        self.side = self.section = self.top = None
        if rec.surface is not None:
            self.side = _SideView(fig.add_subplot(grid[0, 1]), rec, self.wrists + rec.tool)
        if rec.hole is not None:
            self.section = HoleSectionView(fig.add_subplot(grid[0, len(ratios) - 2]), rec.wrist, rec.hole, self.rows)
            self.top = HoleTopView(fig.add_subplot(grid[0, len(ratios) - 1]), self.section)
        # with the hole's close-up the title keeps left, clear of the numbers over the section
        self.title = fig.suptitle("", fontsize="medium", **({"x": 0.02, "ha": "left"} if self.section else {}))
        fig.tight_layout()

    def draw(self, k: int) -> list:
        rec, row = self.rec, self.rows[k]
        touching = rec.force[row] > 0.0 if rec.force is not None else rec.mode is not None and rec.mode[row] > 0
        if rec.hole is not None and rec.hole.force is not None:
            touching = bool(np.any(rec.hole.force[row]))
        artists = self.robot.draw(rec.servo[row], self.wrists[k], touching, row)
        for view in (self.section, self.top):
            if view is not None:
                artists += view.draw(k, row, self.rows[0])
        if self.side is not None:
            artists += self.side.draw(k, row)
        text = f"{rec.plant}   t = {rec.time[row]:.2f} s"
        if rec.force is not None:
            text += f"   contact force {rec.force[row]:.1f} N"
        if rec.mode is not None:
            mode = int(rec.mode[row])
            text += f" ({_MODES[mode] if 0 <= mode < len(_MODES) else mode})"
        self.title.set_text(text)
        return artists + [self.title]

    def close(self) -> None:
        import matplotlib.pyplot as plt

        plt.close(self.figure)


class _RobotView:
    """The robot in 3D: base, upper arms, forearms, plate, tool, surface patch."""

    def __init__(self, ax, rec: Recording, elevation: float, azimuth: float) -> None:
        self.rec, p = rec, rec.params
        reach = p.l0 + p.l1 + 0.05
        hang = max(0.0, -rec.tool[2])
        if rec.wrist is not None:  # the tip's furthest reach from the plate: mount + wrist centre to tip
            mount = np.linalg.norm(rec.wrist.centre[0] - forward_kinematics(p, rec.servo[0]))
            hang = max(hang, mount + float(np.max(np.linalg.norm(rec.wrist.tip - rec.wrist.centre, axis=1))))
        low = -(p.l1 + p.l2) - hang - 0.05
        ax.set(xlim=(-reach, reach), ylim=(-reach, reach), zlim=(low, 0.1))
        ax.set_box_aspect((2 * reach, 2 * reach, 0.1 - low))
        ax.view_init(elev=elevation, azim=azimuth)
        ax.tick_params(labelsize="x-small")
        base = np.array([rot @ np.array([0.0, p.l0, 0.0]) for rot in ARM_ROTATIONS + (ARM_ROTATIONS[0],)])
        ax.plot(*base.T, color="0.3", lw=2.5)
        if rec.surface is not None:
            height, n = rec.surface
            grid = np.linspace(-0.7 * reach, 0.7 * reach, 2)
            gx, gy = np.meshgrid(grid, grid)
            gz = height - (n[0] * gx + n[1] * gy) / n[2] if abs(n[2]) > 1e-9 else np.full_like(gx, height)
            ax.plot_surface(gx, gy, gz, color="tan", alpha=0.4, linewidth=0)
        self.boxes = [ax.plot([], [], [], color="tab:green", lw=1.5)[0] for _ in range(2)] if rec.box else []
        self.upper = [ax.plot([], [], [], color="tab:blue", lw=3)[0] for _ in range(3)]
        self.lower = [ax.plot([], [], [], color="tab:orange", lw=1.5)[0] for _ in range(3)]
        self.plate, = ax.plot([], [], [], color="0.2", lw=2)
        self.tool, = ax.plot([], [], [], color="k", lw=3)
        self.wrist = WristArtists(ax, rec.wrist, rec.hole) if rec.wrist is not None else None

    def draw(self, servo: np.ndarray, wrist: np.ndarray, touching: bool, row: int) -> list:
        for line, y in zip(self.boxes, (-0.5, 0.5)):
            outline = self.rec.box_outline(row)
            line.set_data_3d(outline[:, 0], np.full(len(outline), y * self.rec.box[1]), outline[:, 1])
        joints = []
        for up, down, (base, elbow, joint) in zip(self.upper, self.lower, robot_points(self.rec.params, servo, wrist)):
            up.set_data_3d(*np.array([base, elbow]).T)
            down.set_data_3d(*np.array([elbow, joint]).T)
            joints.append(joint)
        self.plate.set_data_3d(*np.array(joints + joints[:1]).T)
        self.tool.set_color("tab:red" if touching else "k")
        if self.wrist is not None:
            return [*self.boxes, *self.upper, *self.lower, self.plate, *self.wrist.draw(wrist, row, touching)]
        self.tool.set_data_3d(*np.array([wrist, wrist + self.rec.tool]).T)
        return [*self.boxes, *self.upper, *self.lower, self.plate, self.tool]


class _SideView:
    """Side view (x, z) around where the tool meets the surface, in millimetres."""

    def __init__(self, ax, rec: Recording, tips: np.ndarray) -> None:
        self.rec, self.tips, self.ax = rec, tips, ax
        height, n = rec.surface
        centre = tips[-1]
        self.origin = centre
        x = np.linspace(-30.0, 30.0, 2)
        # the plane's trace in the x-z plane through the final tip, relative to it (mm)
        plane_z = [(height - (n[0] * (centre[0] + xi / 1e3) + n[1] * centre[1]) / n[2] - centre[2]) * 1e3
                   for xi in x]
        ax.fill_between(x, plane_z, -20.0, color="tan", alpha=0.5)
        ax.plot(x, plane_z, color="saddlebrown")
        ax.set(xlim=(-30, 30), ylim=(-15, 45), xlabel="x - x_end [mm]", ylabel="z - z_end [mm]",
               aspect="equal")
        ax.tick_params(labelsize="x-small")
        peak = float(np.max(rec.force)) if rec.force is not None and len(rec.force) else 0.0
        self.scale = 20.0 / peak if peak > 0.0 else 0.0   # the largest force: a 20 mm arrow
        self.box = ax.fill([], [], color="tab:green", alpha=0.5)[0] if rec.box else None
        self.trace, = ax.plot([], [], color="0.6", lw=1)
        self.tool, = ax.plot([], [], color="k", lw=4, solid_capstyle="butt")
        self.arrow = None
        self.label = ax.text(0.02, 0.96, "", transform=ax.transAxes, va="top", fontsize="small")

    def draw(self, k: int, row: int) -> list:
        rel = (self.tips[:k + 1] - self.origin) * 1e3
        self.trace.set_data(rel[:, 0], rel[:, 2])
        if self.box is not None:
            self.box.set_xy((self.rec.box_outline(row) - self.origin[[0, 2]]) * 1e3)
        tip = rel[-1]
        self.tool.set_data([tip[0], tip[0]], [tip[2], tip[2] + 40.0])
        if self.arrow is not None:
            self.arrow.remove()
            self.arrow = None
        force = self.rec.force[row] if self.rec.force is not None else 0.0
        if force > 0.0 and self.scale > 0.0:
            n = self.rec.surface[1]
            length = force * self.scale
            # the surface pushing the tool: an arrow from inside the surface up to the tip
            self.arrow = self.ax.annotate("", xy=(tip[0], tip[2]),
                                          xytext=(tip[0] - n[0] * length, tip[2] - n[2] * length),
                                          arrowprops=dict(arrowstyle="->", color="tab:red", lw=2))
        gap = self.rec.surface[1] @ (self.tips[k] - np.array([0.0, 0.0, self.rec.surface[0]]))
        if self.rec.box is not None:  # the tool over the box: its gap to the box's top face
            (x, lift, theta), height = self.rec.box[0][row], self.rec.box[2]
            dx, dz = self.tips[k][0] - x, self.tips[k][2] - self.rec.surface[0] - lift
            gap = min(gap, -math.sin(theta) * dx + math.cos(theta) * dz - height / 2)
        self.label.set_text(f"gap {gap * 1e3:.3f} mm" if gap >= 0 else f"penetration {-gap * 1e3:.3f} mm")
        drawn = [self.trace, self.tool, self.label] + ([self.box] if self.box is not None else [])
        return drawn + ([self.arrow] if self.arrow is not None else [])
