"""The peg-in-hole contact law as an estimator's measurement: the wrench it predicts from the hole's
parameters and the robot's reduced state, its Jacobian, and where a hole must be to explain a wrench.

The hole's unknowns h = [x, y, tilt_x, tilt_y] (top centre in the world, tilt as
:class:`deltafmi.physics.peg.Hole`; its height is known). With s the reduced state of
:mod:`.wrist_process`, the contact law of the plant (:func:`deltafmi.physics.peg.peg_wrench`,
penalty springs and dampers at the peg's rim and the hole's edges, regularised Coulomb friction)
predicts the wrench on the peg

    W = c(h, s) = peg_wrench(Hole(h), Peg, PegContact, tool_pose(s))   (force at the tip, moment about it).

c is a sum of contacts, each zero until its penetration is positive: at a hole estimate that puts
no contact where the robot feels one, c and its gradient vanish and a Kalman update cannot move
the estimate. :func:`locate_hole` then finds a start: the lateral contact force pushes the peg
towards the hole's axis (chamfer, bore wall and edges alike), so the axis lies at some distance d
from the tip along that force's horizontal direction f_xy/|f_xy|; d is the one whose predicted
wrench is nearest the felt one (a grid of 20 um over the chamfer's reach, then nested grids, each a
tenth of the last, around the best point down to 4 nm: the penalty force changes by 4 N per 20 um
per contact point, so the first grid alone would not do; plain floats, :func:`.peg_kernels.hole_search`, compiled in the FMU).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Optional, Sequence

import numpy as np

from ..delta_wrist.params import WristMount
from ..peg.contact import PegWrench, peg_wrench
from ..peg.params import Hole, Peg, PegContact
from ..wrist.kernels import WristConstants
from . import peg_kernels
from .wrist_process import N_REDUCED, tool_pose

__all__ = ["HOLE_STATES", "HOLE_STEPS", "hole_of", "contact_wrench", "wrench_jacobian", "locate_hole"]

#: the hole's estimated parameters: x, y (m), tilt_x, tilt_y (rad)
HOLE_STATES = 4
#: forward-difference steps of the hole's columns (m, m, rad, rad)
HOLE_STEPS = np.array(peg_kernels.HOLE_STEPS)


def _floats(v: Sequence[float]) -> list[float]:
    return [float(c) for c in v]


def hole_of(nominal: Hole, h: Sequence[float]) -> Hole:
    """The nominal hole with x, y, tilt_x, tilt_y replaced by h."""
    return replace(nominal, x=float(h[0]), y=float(h[1]), tilt_x=float(h[2]), tilt_y=float(h[3]))


def contact_wrench(nominal: Hole, peg: Peg, law: PegContact, w: WristConstants, m: WristMount, s: Sequence[float],
                   h: Sequence[float]) -> PegWrench:
    """The contact law's wrench (and diagnostics) on the peg at the reduced state s with the hole h."""
    return peg_wrench(hole_of(nominal, h), peg, law, *tool_pose(w, m, s))


def linearization_parts(values: Sequence[float]) -> tuple[np.ndarray, np.ndarray, float]:
    """(c (6), dc/d[s, h] (6, 16), active contacts) of :func:`.peg_kernels.contact_linearization`'s
    flat result."""
    values = np.asarray(values, float)
    return values[:6].copy(), values[6:6 + 6 * (N_REDUCED + HOLE_STATES)].reshape(-1, 6).T.copy(), float(values[-1])


def wrench_jacobian(nominal: Hole, peg: Peg, law: PegContact, w: WristConstants, m: WristMount, s: Sequence[float],
                    h: Sequence[float], hole_only: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """(c (6), dc/d[s, h] (6, 16) by forward differences, active contacts at (s, h)); with
    ``hole_only`` the columns of s are left zero (not evaluated)."""
    return linearization_parts(peg_kernels.contact_linearization(nominal, peg, law, w, m, _floats(s), _floats(h),
                                                                 bool(hole_only)))


def located(values: Sequence[float]) -> Optional[np.ndarray]:
    """The hole of :func:`.peg_kernels.hole_search`'s flat result, None where it found none."""
    return None if values[0] == 0.0 else np.array(values[1:5], float)


def locate_hole(nominal: Hole, peg: Peg, law: PegContact, w: WristConstants, m: WristMount, s: Sequence[float],
                h: Sequence[float], felt: Sequence[float], weights: Sequence[float]) -> Optional[np.ndarray]:
    """A hole h (x, y moved, tilt kept) whose contact wrench at s explains the felt wrench (6) best
    in the weighted norm sum ((c - felt) / weights)^2, searched along the felt lateral force
    (module docstring); None if the felt force has no lateral part (the peg on the top face tells
    nothing of where the hole is) or no distance gives a contact."""
    return located(peg_kernels.hole_search(nominal, peg, law, w, m, _floats(s), _floats(h), _floats(felt),
                                           _floats(weights)))
