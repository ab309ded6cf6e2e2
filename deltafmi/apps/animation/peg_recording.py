"""The wrist and the peg-in-hole insertion of a result, by what they mean (column names:
:mod:`.columns`): the tool's pose per row, the hole, the insertion's outputs."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from deltafmi.errors import BadInput
from deltafmi.physics.peg import Hole
from deltafmi.physics.wrist.kinematics import tool_rotation
from .columns import PEG, WRIST, Columns

__all__ = ["HoleTrack", "WristTrack", "load_hole", "load_wrist"]


@dataclass
class WristTrack:
    """The tool per row: rotation (n, 3, 3) world <- tool (column 3 the tool axis, pointing from
    the wrist centre to the tip), wrist centre and tip (n, 3); the peg's radius and length (m)."""

    rotation: np.ndarray
    centre: np.ndarray
    tip: np.ndarray
    radius: float
    length: float


@dataclass
class HoleTrack:
    """The hole and what the insertion recorded per row (None where a column is not recorded)."""

    hole: Hole
    depth: Optional[np.ndarray] = None
    force: Optional[np.ndarray] = None     #: (n, 3) contact force on the peg, world (N)
    moment: Optional[np.ndarray] = None    #: (n, 3) its moment about the tip, world (N m)
    lateral: Optional[np.ndarray] = None
    angular: Optional[np.ndarray] = None
    success: Optional[np.ndarray] = None


def _wanted(columns: Columns, variables) -> str:
    """'p.a[*]' or 'p.b' ... for the (variable, size) pairs ``variables``."""
    return " or ".join(f"'{columns.plant}.{v}{'[*]' if n > 1 else ''}'" for v, n in variables)


def load_wrist(columns: Columns, plates: Callable[[], np.ndarray], required: bool,
               defaults: list[str]) -> Optional[WristTrack]:
    """The wrist of ``columns`` (``plates()``: the plate centres (n, 3) from the servo angles): the rotation
    from ``R[1..9]``, else from the wrist angles ``qw[1..3]``; the centre from ``centre[*]``, else
    plate + mount; the tip from ``tip[*]``, else centre + tool_tip R e_z. None when the result holds
    no rotation and no wrist angles, BadInput if ``required`` then."""
    flat = columns.series("rotation", WRIST)
    if flat is not None:
        rotation = flat.reshape(-1, 3, 3)
    else:
        angles = columns.series("angles", WRIST)
        if angles is None:
            if required:
                wanted = _wanted(columns, (WRIST["rotation"], WRIST["angles"]))
                raise BadInput(f"{columns.result}: no wrist: no columns {wanted} (record the tool rotation or the "
                               "wrist angles)")
            return None
        rotation = np.array([tool_rotation(q) for q in angles])
    centre = columns.series("centre", WRIST)
    if centre is None:
        centre = plates() + columns.parameter("mount", defaults)
    tip = columns.series("tip", WRIST)
    if tip is None:
        tip = centre + rotation[:, :, 2] * columns.parameter("tool_tip", defaults)[0]
    return WristTrack(rotation, centre, tip, float(columns.parameter("tool_radius", defaults)[0]),
                      float(columns.parameter("tool_length", defaults)[0]))


def load_hole(columns: Columns, required: bool, defaults: list[str]) -> Optional[HoleTrack]:
    """The hole of ``columns``: present when the result records any insertion output of
    :data:`~.columns.PEG` or the hole's position (or ``required``: then the hole's position must be
    recorded or given with --set). None when absent and not required."""
    outputs = {meaning: columns.series(meaning, PEG) for meaning in PEG}
    recorded = any(v is not None for v in outputs.values()) or columns.has("hole_position", 3)
    if not recorded and not required:
        return None
    if not recorded and "hole_position" not in columns.settings:
        raise BadInput(f"{columns.result}: no hole: no columns {_wanted(columns, PEG.values())} "
                       f"or '{columns.plant}.hole_position[*]' (or pass --set hole_position=x,y,z)")
    x, y, z = columns.parameter("hole_position", defaults)
    tilt_x, tilt_y = columns.parameter("hole_tilt", defaults)
    sizes = [float(columns.parameter(k, defaults)[0]) for k in ("bore_radius", "chamfer_width", "chamfer_angle",
                                                                 "hole_depth")]
    return HoleTrack(Hole(x, y, z, tilt_x, tilt_y, *sizes), **outputs)
