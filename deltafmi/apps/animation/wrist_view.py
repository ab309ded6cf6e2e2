"""The spherical wrist and its peg in the robot's 3D view (and the hole's rim, when there is one)."""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .peg_geometry import hole_matrix, rim_points
from .peg_recording import HoleTrack, WristTrack

__all__ = ["WristArtists"]


class WristArtists:
    """The spherical wrist in the 3D view: the mount from the plate to the wrist centre, the centre,
    the peg as a cylinder outline (both rims, four side lines) along the tool axis; the hole's
    chamfer rim, when there is a hole."""

    def __init__(self, ax, wrist: WristTrack, hole: Optional[HoleTrack]) -> None:
        self.track = wrist
        self.angles = np.linspace(0.0, 2.0 * math.pi, 33)
        self.mount, = ax.plot([], [], [], color="0.2", lw=2)
        self.centre, = ax.plot([], [], [], "o", color="0.2", ms=4)
        self.rims = [ax.plot([], [], [], color="k", lw=1.2)[0] for _ in range(2)]
        self.sides, = ax.plot([], [], [], color="k", lw=1.2)
        if hole is not None:
            h = hole.hole
            frame = hole_matrix(h)
            outer = h.bore_radius + h.chamfer_width
            ring = [h.x, h.y, h.z] + outer * (np.outer(np.cos(self.angles), frame[:, 0])
                                             + np.outer(np.sin(self.angles), frame[:, 1]))
            ax.plot(*ring.T, color="saddlebrown", lw=1.5)

    def draw(self, plate: np.ndarray, row: int, touching: bool) -> list:
        """Show row ``row`` with the plate centre at ``plate``; red rims while the peg touches."""
        w = self.track
        centre, tip, rotation = w.centre[row], w.tip[row], w.rotation[row]
        self.mount.set_data_3d(*np.array([plate, centre]).T)
        self.centre.set_data_3d([centre[0]], [centre[1]], [centre[2]])
        rims = [rim_points(tip, rotation, w.radius, h, self.angles) for h in (0.0, w.length)]
        for line, rim in zip(self.rims, rims):
            line.set_data_3d(*rim.T)
            line.set_color("tab:red" if touching else "k")
        # four side lines, a quarter turn apart, separated by NaN (one line object)
        sides = np.vstack([[rims[0][i], rims[1][i], [np.nan] * 3] for i in range(0, 32, 8)])
        self.sides.set_data_3d(*sides.T)
        return [self.mount, self.centre, *self.rims, self.sides]
