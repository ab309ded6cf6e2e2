"""A two-pad tactile sensor under the tool (the seed talk's touch sensor): where the tool is
relative to a hole, from the difference of the two pad forces.

Geometry along the sensor axis (a horizontal unit vector): pad 1 is centred at ``-spacing/2`` from
the tool tip, pad 2 at ``+spacing/2``, each ``width`` long; the surface has a hole (a slot across
the axis) of width ``hole_width`` centred at the feature. With the tool at offset ``xi`` from the
hole centre, pad ``i`` rests on the solid surface over the fraction ``phi_i`` of its length.

Statics. The tool is held by the travelling plate, which only translates, so both pads compress
by the same amount ``delta_p``; a pad is a uniform elastic layer, so its force is
``k_pad phi_i delta_p`` (``k_pad`` for a fully supported pad). The pads carry the whole normal
load ``F``: ``F_i = F phi_i / (phi_1 + phi_2)`` and ``delta_p = F / (k_pad (phi_1 + phi_2))``.

Where both pad ends overhang the hole edges (``|spacing - hole_width| < width``, the design
case), the supported fractions are linear in the offset near the centre,
``phi_{1,2} = phi_0 -+ xi / width`` with ``phi_0 = (spacing + width - hole_width) / (2 width)``, so

    F_1 - F_2 = -F xi / (width phi_0):

the difference measures the offset, and drives a loop to ``xi = 0``. Beyond that range it
saturates at ``-+F`` (one pad fully over the hole) up to ``|xi| = (hole_width + spacing - width)/2``,
then fades, keeping its sign, to zero at ``(hole_width + spacing + width)/2``, where both pads rest
on solid surface: the capture range of a loop that centres the tool.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np

__all__ = ["TactilePads", "Axis", "Readout", "supported_fractions", "pad_forces", "sensor_forces", "sensor_derivatives",
           "sensor_outputs"]


@dataclass(frozen=True)
class TactilePads:
    """Two elastic pads on the sensor axis (lengths in m, stiffness in N/m per pad)."""

    spacing: float = 0.01
    width: float = 0.004
    stiffness: float = 1e5

    def __post_init__(self) -> None:
        if not (self.spacing > self.width > 0.0 and self.stiffness > 0.0):
            raise ValueError(f"tactile pads need spacing > width > 0 and stiffness > 0, got spacing "
                             f"{self.spacing} m, width {self.width} m, stiffness {self.stiffness} N/m")

    def supported(self, offset: float, hole_width: float) -> tuple[float, float]:
        """Fractions of pads 1 and 2 over the solid surface, tool at ``offset`` from the hole centre."""
        return supported_fractions(self, offset, hole_width)

    def forces(self, load: float, offset: float, hole_width: float) -> tuple[float, float, float]:
        """Pad forces ``(F_1, F_2)`` under the normal ``load`` (N) and the pads' compression (m).

        Both zero when nothing presses or when both pads hang over the hole (the tool would
        drop in: outside this model)."""
        return pad_forces(self, load, offset, hole_width)

    def slope(self, load: float, hole_width: float) -> float:
        """``d(F_1 - F_2)/d offset`` at the centre, ``-load / (width phi_0)`` (N/m)."""
        phi0 = self.supported(0.0, hole_width)[0]
        return -load / (self.width * phi0) if phi0 > 0.0 else 0.0


class Axis(NamedTuple):
    """The sensor axis: a horizontal unit vector (pad 1 -> pad 2)."""

    x: float
    y: float


# The kernels below are plain float Python that deltafmi's code generator also compiles to C (the
# TactileSensor FMU's derivatives and outputs): the methods above and the component call them.

def _overlap(a0: float, a1: float, b0: float, b1: float) -> float:
    return max(0.0, min(a1, b1) - max(a0, b0))


def supported_fractions(pads: TactilePads, offset: float, hole_width: float) -> tuple[float, float]:
    """Fractions of pads 1 and 2 over the solid surface, tool at ``offset`` from the hole centre."""
    half, w = 0.5 * pads.width, 0.5 * hole_width
    c1, c2 = offset - 0.5 * pads.spacing, offset + 0.5 * pads.spacing
    return (1.0 - _overlap(c1 - half, c1 + half, -w, w) / pads.width,
            1.0 - _overlap(c2 - half, c2 + half, -w, w) / pads.width)


def pad_forces(pads: TactilePads, load: float, offset: float, hole_width: float) -> tuple[float, float, float]:
    """Pad forces ``(F_1, F_2)`` under the normal ``load`` (N) and the pads' compression (m)."""
    phi1, phi2 = supported_fractions(pads, offset, hole_width)
    support = phi1 + phi2
    if load <= 0.0 or support <= 0.0:
        return 0.0, 0.0, 0.0
    return load * phi1 / support, load * phi2 / support, load / (pads.stiffness * support)


def sensor_forces(pads: TactilePads, axis: Axis, tip: Sequence[float], hole_centre: Sequence[float],
                  load: float, hole_width: float) -> tuple[float, float, float, float]:
    """``(F_1, F_2, compression, offset)``: the tool tip's offset from the hole centre along the
    sensor ``axis`` and the pads' forces and compression there."""
    offset = axis.x * (tip[0] - hole_centre[0]) + axis.y * (tip[1] - hole_centre[1])
    f1, f2, compression = pad_forces(pads, load, offset, hole_width)
    return f1, f2, compression, offset


def sensor_derivatives(pads: TactilePads, axis: Axis, tip: Sequence[float],
                       hole_centre: Sequence[float], load: float, hole_width: float, bandwidth: float,
                       filtered: Sequence[float]) -> tuple[float, float]:
    """Rates of the lagged pad forces ``filtered``: a first-order lag of ``bandwidth`` Hz."""
    f1, f2, compression, offset = sensor_forces(pads, axis, tip, hole_centre, load, hole_width)
    rate = 2.0 * math.pi * bandwidth
    return rate * (f1 - filtered[0]), rate * (f2 - filtered[1])


def sensor_outputs(pads: TactilePads, axis: Axis, tip: Sequence[float], hole_centre: Sequence[float],
                   load: float, hole_width: float) -> tuple[float, float]:
    """The true ``(offset, compression)``."""
    f1, f2, compression, offset = sensor_forces(pads, axis, tip, hole_centre, load, hole_width)
    return offset, compression


@dataclass(frozen=True)
class Readout:
    """A sampled channel: Gaussian noise (N rms) and quantization (N per count; 0: none).

    The noise of sample ``k`` on channel ``c`` is drawn from a generator seeded with
    ``(seed, k, c)``: the same run gives the same noise whatever the stepping, rollbacks included.
    """

    noise: float = 0.0
    quantization: float = 0.0
    seed: int = 0

    def read(self, value: float, sample: int, channel: int) -> float:
        """The reading of ``value`` at sample ``sample`` on ``channel``."""
        if self.noise > 0.0:
            value += self.noise * float(np.random.default_rng([self.seed, sample, channel]).standard_normal())
        if self.quantization > 0.0:
            value = self.quantization * round(value / self.quantization)
        return value
