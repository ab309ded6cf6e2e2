"""Geometry of the peg-in-hole pictures (metres, numpy; no drawing): the fixture cut by a plane
through the hole axis, the peg's outline seen along that plane's normal, the contact force's line
of action, the peg's rims in 3D.

Hole frame as in :mod:`deltafmi.physics.peg.params`: origin the hole's top centre, e_z up the
hole axis, R_h = Ry(tilt_y) Rx(tilt_x). The section plane holds e_z and a horizontal unit d of the
hole frame; a point p (hole frame) has section coordinates (s, h) = (d . p, e_z . p), which is also
the orthographic view along the plane normal e_z x d.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull

from deltafmi.physics.peg import Hole, hole_rotation

__all__ = ["RIM_SAMPLES", "action_point", "fixture_section", "hole_matrix", "peg_silhouette", "rim_points",
           "section_direction", "to_hole_frame"]

#: samples of a rim circle; the inscribed polygon's area is (N / 2) sin(2 pi / N) / pi = 1 - 4.0e-4
#: of the ellipse's at N = 128, its largest radial gap r (1 - cos(pi / N)) = 3.0e-4 r
RIM_SAMPLES = 128


def hole_matrix(hole: Hole) -> np.ndarray:
    """R_h (3 x 3): the hole frame's axes as columns in the world."""
    return np.array(hole_rotation(hole)).reshape(3, 3)


def to_hole_frame(hole: Hole, points: np.ndarray) -> np.ndarray:
    """World points (..., 3) in the hole frame: R_h^T (p - hole top centre)."""
    return (np.asarray(points, dtype=float) - [hole.x, hole.y, hole.z]) @ hole_matrix(hole)


def section_direction(lateral: np.ndarray) -> np.ndarray:
    """The horizontal unit d (hole frame, (3,)) of the section plane: along a lateral offset
    (x, y, ...) of the tip from the hole axis, or e_x when it is under a micrometre."""
    norm = math.hypot(lateral[0], lateral[1])
    return np.array([lateral[0] / norm, lateral[1] / norm, 0.0]) if norm > 1e-6 else np.array([1.0, 0.0, 0.0])


def fixture_section(hole: Hole, half_width: float, below: float) -> np.ndarray:
    """The fixture cut through the hole axis, (s, h) polygon (closed): the top plane out to
    +-half_width, the chamfer from radius R_b + w at h = 0 to R_b at h = -w tan(alpha), the bore
    wall down to the bottom h = -depth, the block's base ``below`` the bottom."""
    rb, rc = hole.bore_radius, hole.bore_radius + hole.chamfer_width
    c, bottom = -hole.chamfer_width * math.tan(hole.chamfer_angle), -hole.depth
    base = bottom - below
    outline = [(rc, 0.0), (half_width, 0.0), (half_width, base), (-half_width, base), (-half_width, 0.0), (-rc, 0.0),
             (-rb, c), (-rb, bottom), (rb, bottom), (rb, c), (rc, 0.0)]
    return np.array(outline)


def rim_points(tip: np.ndarray, rotation: np.ndarray, radius: float, height: float,
               angles: np.ndarray) -> np.ndarray:
    """Points (len(angles), 3) of the peg's circle at ``height`` above the tip along the peg,
    the peg axis being -(tool z): tip + r (cos phi x_t + sin phi y_t) - height z_t."""
    x, y, z = rotation[:, 0], rotation[:, 1], rotation[:, 2]
    return tip + radius * (np.outer(np.cos(angles), x) + np.outer(np.sin(angles), y)) - height * z


def peg_silhouette(tip: np.ndarray, rotation: np.ndarray, radius: float, length: float,
                   direction: np.ndarray) -> np.ndarray:
    """The peg (a cylinder, bottom face centre ``tip``, axis the tool z, all in the hole frame)
    seen along the section plane's normal: the convex hull (closed (m, 2) polygon, (s, h)) of its
    two rims. The rims are sampled at RIM_SAMPLES angles plus the two where they reach furthest
    from the projected axis, so the outline's straight sides, at +-radius from the projected axis,
    are exact (the cylinder's silhouette generators project at distance r: their radial direction
    lies in the plane)."""
    basis = np.array([direction, [0.0, 0.0, 1.0]])          # (2, 3): s and h
    x, y = basis @ rotation[:, 0], basis @ rotation[:, 1]   # the rim's (cos, sin) directions in (s, h)
    axis = basis @ rotation[:, 2]
    side = np.array([-axis[1], axis[0]]) if np.hypot(*axis) > 1e-12 else np.array([1.0, 0.0])
    widest = math.atan2(side @ y, side @ x)
    angles = np.concatenate([np.linspace(0.0, 2.0 * math.pi, RIM_SAMPLES, endpoint=False),
                             [widest, widest + math.pi]])
    points = np.vstack([rim_points(tip, rotation, radius, h, angles) for h in (0.0, length)]) @ basis.T
    hull = points[ConvexHull(points).vertices]
    return np.vstack([hull, hull[:1]])


def action_point(force: np.ndarray, moment: np.ndarray, axis: np.ndarray, radius: float,
                 length: float) -> np.ndarray:
    """Where to draw a contact force F whose moment about the tip is M (relative to the tip): where
    its line of action enters the peg (the solid cylinder from the tip, radius r, length L along
    the unit ``axis``), the contact point of a single contact. The line is the wrench's central
    axis r0 + t F/|F|, r0 = F x M / |F|^2 (r0 x F = M when M is normal to F); its entry is the
    smallest t inside both the slab 0 <= (p . a) <= L and the tube |p - (p . a) a| <= r. A line
    that misses the peg (several contacts with a couple, e.g. two opposed wedging forces) is drawn
    at r0 when it lies within the peg's length of the tip, else at the tip; zero F: the tip."""
    f2 = float(force @ force)
    if f2 <= 0.0:
        return np.zeros(3)
    r0, u = np.cross(force, moment) / f2, force / math.sqrt(f2)
    low, high = _interval(r0 @ axis, u @ axis, 0.0, length)
    p, v = r0 - (r0 @ axis) * axis, u - (u @ axis) * axis       # across the axis
    a, b, c = v @ v, 2.0 * (p @ v), p @ p - radius * radius
    if a > 1e-24 and b * b - 4.0 * a * c >= 0.0:
        root = math.sqrt(b * b - 4.0 * a * c)
        low, high = max(low, (-b - root) / (2.0 * a)), min(high, (-b + root) / (2.0 * a))
    elif c > 0.0:
        low = math.inf                                            # parallel to the axis outside, or past it
    if low <= high:
        return r0 + low * u
    return r0 if np.linalg.norm(r0) <= length else np.zeros(3)


def _interval(start: float, rate: float, lower: float, upper: float) -> tuple[float, float]:
    """The t with lower <= start + rate t <= upper, as (low, high) (low > high: none)."""
    if abs(rate) < 1e-15:
        return (-math.inf, math.inf) if lower <= start <= upper else (math.inf, -math.inf)
    ends = sorted(((lower - start) / rate, (upper - start) / rate))
    return ends[0], ends[1]
