"""The insertion's close-up panels (millimetres, hole frame, origin the hole's top centre): a side
section through the hole axis (fixture cut, chamfer, bore, the peg's outline, the contact force)
and a top view (bore and chamfer circles, the peg's bottom rim, the section line)."""
from __future__ import annotations

import math

import numpy as np

from .peg_geometry import (action_point, fixture_section, hole_matrix, peg_silhouette, rim_points,
                           section_direction, to_hole_frame)
from .peg_recording import HoleTrack, WristTrack

__all__ = ["HoleSectionView", "HoleTopView"]

MM = 1e3
#: the largest contact force of the run is drawn this long (mm); an arrow shows the force's component
#: in the section plane at that scale
ARROW_MM = 15.0


class HoleSectionView:
    """Side section in the plane of the hole axis and the tip's first lateral offset: s across,
    h up the hole axis (mm). ``peg`` is the peg's outline patch, ``arrow`` the force (or None)."""

    def __init__(self, ax, wrist: WristTrack, track: HoleTrack, rows: np.ndarray) -> None:
        self.ax, self.track, self.wrist, hole = ax, track, wrist, track.hole
        self.tips = to_hole_frame(hole, wrist.tip)                                # (n, 3), hole frame
        self.rotations = np.einsum("ji,njk->nik", hole_matrix(hole), wrist.rotation)   # R_h^T R
        self.direction = section_direction(self.tips[rows[0]])
        outer = hole.bore_radius + hole.chamfer_width
        half = max(2.5 * outer, 1.2 * (abs(self.tips[rows[0]] @ self.direction) + outer))
        ax.fill(*(fixture_section(hole, half, 0.15 * hole.depth) * MM).T, facecolor="0.75", edgecolor="0.3",
                hatch="///", lw=1.0)
        ax.axvline(0.0, color="0.4", lw=0.8, ls="-.")
        top = max(half, 0.6 * hole.depth)
        ax.set(xlim=(-half * MM, half * MM), ylim=(-1.15 * hole.depth * MM, top * MM), aspect="equal",
               xlabel="across the hole [mm]", ylabel="along the hole axis [mm]")
        ax.tick_params(labelsize="x-small")
        self.trace, = ax.plot([], [], color="tab:blue", lw=0.8, alpha=0.6)
        self.peg = ax.fill([], [], facecolor="tab:blue", edgecolor="k", alpha=0.55, lw=1.0)[0]
        force = self.hole_force(np.arange(len(self.tips)))
        peak = float(np.max(np.linalg.norm(force, axis=1))) if force is not None else 0.0
        self.scale = ARROW_MM / peak if peak > 0.0 else 0.0            # mm per N
        self.arrow = None
        # the numbers above the panel: inside it they would hide the peg deep in the bore
        self.label = ax.set_title("\n", fontsize="x-small", family="monospace", loc="left")
        self.badge = ax.text(0.98, 0.98, "", transform=ax.transAxes, va="top", ha="right", fontsize="small",
                             fontweight="bold")

    def section(self, points: np.ndarray) -> np.ndarray:
        """Hole-frame points (..., 3) in section coordinates (s, h), mm."""
        return np.stack([points @ self.direction, points[..., 2]], axis=-1) * MM

    def hole_force(self, rows: np.ndarray):
        """The contact force in the hole frame at ``rows``, (len, 3), or None when not recorded."""
        if self.track.force is None:
            return None
        return self.track.force[rows] @ hole_matrix(self.track.hole)

    def draw(self, k: int, row: int, first: int) -> list:
        tip, rotation = self.tips[row], self.rotations[row]
        self.peg.set_xy(peg_silhouette(tip, rotation, self.wrist.radius, self.wrist.length, self.direction) * MM)
        self.trace.set_data(*self.section(self.tips[first:row + 1]).T)
        if self.arrow is not None:
            self.arrow.remove()
            self.arrow = None
        force = self.hole_force(np.array([row]))
        if force is not None and self.scale > 0.0 and np.any(force[0]):
            moment = self.track.moment[row] @ hole_matrix(self.track.hole) if self.track.moment is not None \
                else np.zeros(3)
            point = tip + action_point(force[0], moment, -rotation[:, 2], self.wrist.radius, self.wrist.length)
            head = self.section(point)
            tail = head - self.section(force[0]) / MM * self.scale
            # the fixture pushing the peg: an arrow ending where the force acts
            self.arrow = self.ax.annotate("", xy=head, xytext=tail,
                                          arrowprops=dict(arrowstyle="->", color="tab:red", lw=2))
        self.label.set_text(self._numbers(row, tip))
        if self.track.success is not None:
            done = bool(self.track.success[row])
            self.badge.set_text("inserted" if done else "not inserted")
            self.badge.set_color("tab:green" if done else "0.45")
        drawn = [self.peg, self.trace, self.label, self.badge]
        return drawn + ([self.arrow] if self.arrow is not None else [])

    def _numbers(self, row: int, tip: np.ndarray) -> str:
        """Depth, misalignments, force: recorded, else from the drawn pose (tip in the hole frame)."""
        track = self.track
        depth = track.depth[row] if track.depth is not None else -tip[2]
        lateral = track.lateral[row] if track.lateral is not None else math.hypot(tip[0], tip[1])
        angular = track.angular[row] if track.angular is not None else \
            math.acos(min(1.0, max(-1.0, -self.rotations[row][2, 2])))
        lines = [f"depth {depth * MM:7.2f} mm", f"lateral {lateral * MM:6.3f} mm",
                 f"angle {math.degrees(angular):6.3f} deg"]
        if track.force is not None:
            lines.append(f"|F| {np.linalg.norm(track.force[row]):6.1f} N")
        return "   ".join(lines[:2]) + "\n" + "   ".join(lines[2:])


class HoleTopView:
    """Looking down the hole axis (mm): bore and chamfer circles, the peg's bottom rim, the
    section line."""

    def __init__(self, ax, section: HoleSectionView) -> None:
        self.section = section
        hole = section.track.hole
        angles = np.linspace(0.0, 2.0 * math.pi, 129)
        for radius in (hole.bore_radius, hole.bore_radius + hole.chamfer_width):
            ax.plot(radius * MM * np.cos(angles), radius * MM * np.sin(angles), color="0.3", lw=1.0)
        reach = 1.6 * (hole.bore_radius + hole.chamfer_width) * MM
        d = section.direction
        ax.plot([-reach * d[0], reach * d[0]], [-reach * d[1], reach * d[1]], color="0.5", lw=0.8, ls="--")
        ax.set(xlim=(-reach, reach), ylim=(-reach, reach), aspect="equal", xlabel="x_hole [mm]",
               ylabel="y_hole [mm]")
        ax.tick_params(labelsize="x-small")
        self.angles = angles
        self.rim, = ax.plot([], [], color="tab:blue", lw=1.5)
        self.tip, = ax.plot([], [], "+", color="tab:blue")

    def draw(self, k: int, row: int, first: int) -> list:
        s = self.section
        rim = rim_points(s.tips[row], s.rotations[row], s.wrist.radius, 0.0, self.angles) * MM
        self.rim.set_data(rim[:, 0], rim[:, 1])
        self.tip.set_data([s.tips[row][0] * MM], [s.tips[row][1] * MM])
        return [self.rim, self.tip]
