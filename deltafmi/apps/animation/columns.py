"""Which result columns the animation of the wrist and of a peg-in-hole insertion reads: the one
table of the plant variables it uses (DeltaWrist, DeltaWristPeg: deltafmi/models), and how a
parameter that the result does not hold is found (a ``--set`` value, else the model's default).

A scenario records a parameter by naming it under ``outputs:`` (``'plant.hole_position[*]'``); the
result then holds it as a constant column, which is read from its first row.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Optional, Sequence

import numpy as np

from deltafmi.errors import BadInput

__all__ = ["Columns", "PEG", "WRIST", "parse_settings"]

#: wrist outputs: meaning -> (variable, size)
WRIST = {
    "rotation": ("R", 9),        # tool rotation, world <- tool, row-major; column 3 the tool axis
    "angles": ("qw", 3),         # wrist joint angles Z-X-Y (used when R is not recorded)
    "centre": ("centre", 3),     # wrist centre O
    "tip": ("tip", 3),           # tool tip (the peg's bottom face centre)
}
#: insertion outputs (DeltaWristPeg): meaning -> (variable, size)
PEG = {
    "depth": ("depth", 1),
    "force": ("contact_force", 3),
    "moment": ("contact_moment", 3),
    "lateral": ("lateral_misalignment", 1),
    "angular": ("angular_misalignment", 1),
    "success": ("success", 1),
}
#: parameters the drawing needs: meaning -> (parameter, size, model whose default applies or None:
#: no default, it must be recorded or given)
PARAMETERS = {
    "mount": ("mount", 3, "DeltaWrist"),
    "tool_tip": ("tool_tip", 1, "DeltaWrist"),
    "tool_length": ("tool_length", 1, "DeltaWrist"),
    "tool_radius": ("tool_radius", 1, "DeltaWrist"),
    "hole_position": ("hole_position", 3, None),
    "hole_tilt": ("hole_tilt", 2, "DeltaWristPeg"),
    "bore_radius": ("bore_radius", 1, "DeltaWristPeg"),
    "chamfer_width": ("chamfer_width", 1, "DeltaWristPeg"),
    "chamfer_angle": ("chamfer_angle", 1, "DeltaWristPeg"),
    "hole_depth": ("hole_depth", 1, "DeltaWristPeg"),
}


def element_names(plant: str, variable: str, size: int) -> list[str]:
    """The column names of ``plant.variable``: ``p.v`` for a scalar, ``p.v[1]`` ... ``p.v[size]``."""
    return [f"{plant}.{variable}"] if size == 1 else [f"{plant}.{variable}[{i}]" for i in range(1, size + 1)]


def parse_settings(items: Sequence[str]) -> dict[str, list[float]]:
    """``NAME=VALUE[,VALUE...]`` strings (``--set``) as {name: values}; ``plant.`` prefixes are dropped.

    Raises BadInput (one line naming the item) for a malformed item or an unknown name."""
    known = {name for name, _, _ in PARAMETERS.values()}
    settings = {}
    for item in items:
        name, sep, text = item.partition("=")
        name = name.strip().rsplit(".", 1)[-1]
        if not sep or name not in known:
            raise BadInput(f"--set {item!r}: expected NAME=VALUE[,VALUE...] with NAME one of "
                           f"{', '.join(sorted(known))}")
        try:
            settings[name] = [float(v) for v in text.split(",")]
        except ValueError:
            raise BadInput(f"--set {item!r}: the value must be numbers separated by commas") from None
    return settings


@dataclass
class Columns:
    """One plant's columns of a result, with ``--set`` values for parameters it lacks."""

    plant: str
    column: Mapping[str, np.ndarray]
    settings: Mapping[str, list[float]]
    result: str = "result"

    def has(self, variable: str, size: int) -> bool:
        """Whether every element of ``plant.variable`` is a column."""
        return all(name in self.column for name in element_names(self.plant, variable, size))

    def series(self, meaning: str, table: Mapping[str, tuple[str, int]]) -> Optional[np.ndarray]:
        """The recorded ``meaning`` of ``table`` as (rows,) or (rows, size) floats, or None."""
        variable, size = table[meaning]
        if not self.has(variable, size):
            return None
        values = [np.asarray(self.column[n], dtype=float) for n in element_names(self.plant, variable, size)]
        return values[0] if size == 1 else np.column_stack(values)

    def parameter(self, meaning: str, defaults_used: list[str]) -> np.ndarray:
        """A parameter: its recorded column (first row), else its ``--set`` value, else the model's
        default (its name is then appended to ``defaults_used``). Raises BadInput when none is there."""
        name, size, model = PARAMETERS[meaning]
        if self.has(name, size):
            return np.array([float(self.column[n][0]) for n in element_names(self.plant, name, size)])
        if name in self.settings:
            value = self.settings[name]
            if len(value) != size:
                raise BadInput(f"--set {name}: {size} value(s) expected, got {len(value)}")
            return np.array(value)
        if model is None:
            raise BadInput(f"{self.result}: no '{self.plant}.{name}{'[*]' if size > 1 else ''}' (record it under "
                           f"the scenario's outputs: or pass --set {name}=...)")
        from deltafmi import models

        default = np.array(getattr(getattr(models, model), name).start, dtype=float)
        defaults_used.append(f"{name}={','.join(f'{v:g}' for v in default)}")
        return default
