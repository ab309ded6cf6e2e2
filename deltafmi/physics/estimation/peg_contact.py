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
per contact point, so the first grid alone would not do; numpy only, as everything an FMU runs).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Optional, Sequence

import numpy as np

from ..delta_wrist.params import WristMount
from ..peg.contact import PegWrench, peg_wrench
from ..peg.params import Hole, Peg, PegContact
from ..wrist.kernels import WristConstants
from .wrist_process import N_REDUCED, STEPS, tool_pose

__all__ = ["HOLE_STATES", "HOLE_STEPS", "hole_of", "contact_wrench", "wrench_jacobian", "locate_hole"]

#: the hole's estimated parameters: x, y (m), tilt_x, tilt_y (rad)
HOLE_STATES = 4
#: forward-difference steps of the hole's columns (m, m, rad, rad)
HOLE_STEPS = np.array([1e-7, 1e-7, 1e-6, 1e-6])
_GRID = 20e-6  # m, the locator's grid (module docstring)


def hole_of(nominal: Hole, h: Sequence[float]) -> Hole:
    """The nominal hole with x, y, tilt_x, tilt_y replaced by h."""
    return replace(nominal, x=float(h[0]), y=float(h[1]), tilt_x=float(h[2]), tilt_y=float(h[3]))


def contact_wrench(nominal: Hole, peg: Peg, law: PegContact, w: WristConstants, m: WristMount, s: Sequence[float],
                   h: Sequence[float]) -> PegWrench:
    """The contact law's wrench (and diagnostics) on the peg at the reduced state s with the hole h."""
    return peg_wrench(hole_of(nominal, h), peg, law, *tool_pose(w, m, s))


def _wrench(c: PegWrench) -> np.ndarray:
    return np.array(c.force + c.moment)


def wrench_jacobian(nominal: Hole, peg: Peg, law: PegContact, w: WristConstants, m: WristMount, s: Sequence[float],
                    h: Sequence[float], hole_only: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """(c (6), dc/d[s, h] (6, 16) by forward differences, active contacts at (s, h)); with
    ``hole_only`` the columns of s are left zero (not evaluated)."""
    s, h = np.asarray(s, float), np.asarray(h, float)
    c0 = contact_wrench(nominal, peg, law, w, m, s, h)
    w0 = _wrench(c0)
    J = np.zeros((6, N_REDUCED + HOLE_STATES))
    for k, step in enumerate(np.concatenate([STEPS, HOLE_STEPS])):
        if hole_only and k < N_REDUCED:
            continue
        ds, dh = s.copy(), h.copy()
        if k < N_REDUCED:
            ds[k] += step
        else:
            dh[k - N_REDUCED] += step
        J[:, k] = (_wrench(contact_wrench(nominal, peg, law, w, m, ds, dh)) - w0) / step
    return w0, J, c0.active


def locate_hole(nominal: Hole, peg: Peg, law: PegContact, w: WristConstants, m: WristMount, s: Sequence[float],
                h: Sequence[float], felt: Sequence[float], weights: Sequence[float]) -> Optional[np.ndarray]:
    """A hole h (x, y moved, tilt kept) whose contact wrench at s explains the felt wrench (6) best
    in the weighted norm sum ((c - felt) / weights)^2, searched along the felt lateral force
    (module docstring); None if the felt force has no lateral part (the peg on the top face tells
    nothing of where the hole is) or no distance gives a contact."""
    felt, weights = np.asarray(felt, float), np.asarray(weights, float)
    lateral = float(np.hypot(felt[0], felt[1]))
    if not lateral > 0.0:
        return None
    direction = felt[:2] / lateral
    tip = np.array(tool_pose(w, m, s)[0][:2])
    h = np.asarray(h, float)

    def candidate(d: float) -> np.ndarray:
        return np.concatenate([tip + d * direction, h[2:]])

    def misfit(d: float) -> float:
        predicted = _wrench(contact_wrench(nominal, peg, law, w, m, s, candidate(d)))
        return float(np.sum(((predicted - felt) / weights) ** 2))

    reach = nominal.bore_radius + nominal.chamfer_width + nominal.edge_radius - peg.radius + 2.0 * _GRID
    grid = np.arange(0.0, reach, _GRID)
    values = np.array([misfit(d) for d in grid])
    best = int(np.argmin(values))
    if values[best] >= misfit(-1.0):  # no better than no contact at all
        return None
    lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    for _ in range(4):  # the bracket shrinks tenfold per pass: 4 um, 0.4 um, 40 nm, 4 nm
        fine = np.linspace(lo, hi, 21)
        k = int(np.argmin([misfit(d) for d in fine]))
        lo, hi = fine[max(k - 1, 0)], fine[min(k + 1, len(fine) - 1)]
    return candidate(0.5 * (lo + hi))
