"""Reference trajectories for the delta robot wrist: r(t), r'(t), r''(t) in the base frame.

Four generators share one interface, ``evaluate(t) -> (r, rd, rdd)`` (three length-3 arrays):

- :class:`MinimumJerkPath`: point-to-point minimum-jerk moves through waypoints, with dwell;
- :class:`ConstantSpeedPath`: straight moves through waypoints at set speeds (an approach or a
  slide at a given speed), speeding up and slowing down along minimum-jerk blends;
- :class:`CirclePath`: a horizontal circle whose angular rate ramps in along a minimum-jerk
  profile, so position, velocity, acceleration and jerk are continuous from rest;
- :class:`RecordedPath`: playback of a CSV ``time, x, y, z`` through a cubic (optionally
  smoothing) spline, whose first and second derivatives give rd and rdd.

The two waypoint paths are also fixed-length tables (:class:`MinimumJerkTable`,
:class:`ConstantSpeedTable`, up to :data:`MAX_MOVES` moves, from ``path.table()``): their
evaluation (:func:`evaluate_table`, :func:`evaluate_speed_table`, the paths' own ``evaluate_flat``)
translates to C of one type whatever the number of waypoints (deltafmi.builder.codegen).

Waypoints and circles are checked against the nominal workspace (a convex cylinder, so every
straight segment between admissible waypoints is admissible) and, when a ``DeltaParams``-like
object is given, against inverse-kinematic reachability along the sampled path.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np

from .control import inverse_kinematics_servo

__all__ = ["CirclePath", "ConstantSpeedPath", "ConstantSpeedTable", "Flat9", "MAX_MOVES", "MinimumJerkPath",
           "MinimumJerkTable", "RecordedPath", "Workspace", "evaluate_speed_table", "evaluate_table", "minimum_jerk"]

Vector3 = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class Workspace:
    """Nominal workspace of the RL5 delta: a vertical cylinder below the base (metres)."""

    r_max: float = 0.5
    z_min: float = -1.2
    z_max: float = -0.75

    def violation(self, point: Sequence[float]) -> str | None:
        """Return why ``point`` lies outside the cylinder, or None when it is inside."""
        x, y, z = (float(c) for c in point)
        if not all(math.isfinite(c) for c in (x, y, z)):
            return "is not finite"
        if math.hypot(x, y) > self.r_max + 1e-12:
            return f"has radius {math.hypot(x, y):.4g} m > r_max {self.r_max:g} m"
        if not self.z_min - 1e-12 <= z <= self.z_max + 1e-12:
            return f"has z {z:.4g} m outside [{self.z_min:g}, {self.z_max:g}] m"
        return None


def minimum_jerk(tau: float) -> tuple[float, float, float]:
    """Normalised minimum-jerk blend s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5 and its first two
    derivatives with respect to tau, clamped to the rest values outside [0, 1]."""
    if tau <= 0.0:
        return 0.0, 0.0, 0.0
    if tau >= 1.0:
        return 1.0, 0.0, 0.0
    t2 = tau * tau
    return (t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau)),
            30.0 * t2 * (1.0 - tau) ** 2,
            60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau))


def _check_points(points: np.ndarray, workspace: Workspace | None, params, what: str) -> None:
    """Raise ValueError naming the first point (by index) that is outside or unreachable."""
    for i, p in enumerate(points):
        reason = workspace.violation(p) if workspace is not None else None
        if reason is None and params is not None and not _reachable(params, p):
            reason = "is not reachable by inverse kinematics"
        if reason is not None:
            raise ValueError(f"{what} {i} = ({p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g}) m {reason}")


def _waypoints(waypoints: Sequence[Sequence[float]], n_moves: int, dwell: float | Sequence[float],
               workspace: Workspace | None, params) -> tuple[np.ndarray, np.ndarray]:
    """Checked waypoints (n x 3) for ``n_moves`` = n - 1 moves, and the dwell at each of them."""
    pts = np.asarray(waypoints, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 1:
        raise ValueError(f"waypoints must be an n x 3 array with n >= 1, got shape {pts.shape}")
    if n_moves != len(pts) - 1:
        raise ValueError(f"{len(pts)} waypoints need {len(pts) - 1} durations, got {n_moves}")
    D = np.broadcast_to(np.asarray(dwell, dtype=float), (len(pts),)).copy()
    if np.any(D < 0.0) or not np.all(np.isfinite(D)):
        raise ValueError(f"dwell must be finite and >= 0, got {dwell}")
    _check_points(pts, workspace, params, "waypoint")
    if params is not None:
        # the cylinder is convex, the reachable set need not be: sample every move too
        for k in range(n_moves):
            for s in np.linspace(0.0, 1.0, 12)[1:-1]:
                p = pts[k] + s * (pts[k + 1] - pts[k])
                if not _reachable(params, p):
                    raise ValueError(f"move {k} (waypoint {k} -> {k + 1}) leaves the "
                                     f"reachable workspace near ({p[0]:.4g}, {p[1]:.4g}, "
                                     f"{p[2]:.4g}) m")
    return pts, D


def _move_starts(t0: float, durations: np.ndarray, dwell: np.ndarray) -> list[float]:
    """Start time of each move: after all earlier dwells and moves, plus the dwell at its start."""
    before = np.concatenate(([0.0], np.cumsum(dwell[:-1] + durations)[:-1]))[:len(durations)]
    return (t0 + before + dwell[:-1]).tolist()


Flat9 = tuple[float, float, float, float, float, float, float, float, float]


def _resting(point: np.ndarray) -> Flat9:
    """At rest at ``point``: r, rd, rdd as nine floats."""
    x, y, z = point.tolist()
    return (x, y, z, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def _vectors(flat: Flat9) -> Vector3:
    """r, rd, rdd as three arrays from nine floats."""
    return np.array(flat[0:3]), np.array(flat[3:6]), np.array(flat[6:9])


def _reachable(params, point: np.ndarray) -> bool:
    try:
        inverse_kinematics_servo(params, point)
    except ValueError:
        return False
    return True


#: moves a path's table holds (the C layout of the generated kernels is fixed at build time;
#: the Trajectory component needs MAX_WAYPOINTS - 1 = 7)
MAX_MOVES = 15
Point3 = tuple[float, float, float]


#: one minimum-jerk move: duration (s), start point, displacement (m) (plain tuples: unpacking
#: a NamedTuple is slower)
MinimumJerkMove = tuple[float, Point3, Point3]
#: one constant-speed move: duration (s), cruise speed (m/s), length (m), start point, unit direction
ConstantSpeedMove = tuple[float, float, float, Point3, Point3]

_Starts = tuple[(float,) * MAX_MOVES]
_MinimumJerkMoves = tuple[(MinimumJerkMove,) * MAX_MOVES]
_ConstantSpeedMoves = tuple[(ConstantSpeedMove,) * MAX_MOVES]
_NO_MOVE = (1.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))  # padding (never read)
_NO_SPEED_MOVE = (1.0, 1.0, 0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


class MinimumJerkTable(NamedTuple):
    """A :class:`MinimumJerkPath` as fixed-length data (a C struct whatever the waypoint count).

    Moves ``n_moves`` and beyond are padding, never read: the search for the move under way
    stops at ``n_moves`` (and their starts are +inf, so ``starts`` stays sorted).
    :func:`evaluate_table` evaluates it; :meth:`MinimumJerkPath.table` builds it.
    """

    n_moves: int
    starts: _Starts  #: start time of each move (s), after the dwell at its first waypoint
    moves: _MinimumJerkMoves
    at_rest: Flat9  #: r, rd, rdd before the first move


class ConstantSpeedTable(NamedTuple):
    """A :class:`ConstantSpeedPath` as fixed-length data, padded as :class:`MinimumJerkTable`;
    :func:`evaluate_speed_table` evaluates it."""

    n_moves: int
    starts: _Starts
    moves: _ConstantSpeedMoves
    blend: float  #: time to reach a move's speed, and to stop (s)
    at_rest: Flat9


def _along(tau: float, T: float, V: float, length: float, Tb: float) -> tuple[float, float, float]:
    """Distance, speed and acceleration at time ``tau`` into a move of duration ``T``, speed ``V``
    and ``length`` with blends of ``Tb``."""
    if tau <= Tb:
        x = tau / Tb
        s, ds, _ = minimum_jerk(x)
        return V * Tb * x ** 4 * (2.5 + x * (-3.0 + x)), V * s, V * ds / Tb
    if tau >= T - Tb:
        x = min((T - tau) / Tb, 1.0)
        s, ds, _ = minimum_jerk(x)
        return length - V * Tb * x ** 4 * (2.5 + x * (-3.0 + x)), V * s, -V * ds / Tb
    return V * (tau - 0.5 * Tb), V, 0.0


def _padded(items: list, pad, size: int) -> tuple:
    """``items`` then ``pad`` up to ``size`` elements."""
    return tuple(items) + (pad,) * (size - len(items))


def _fixed(table, what: str):
    """``table`` when it fits the C layout (MAX_MOVES moves), else a ValueError saying so."""
    if table.n_moves > MAX_MOVES:
        raise ValueError(f"a {what} path of {table.n_moves} moves does not fit the generated C, "
                         f"which holds at most MAX_MOVES = {MAX_MOVES}")
    return table


class _WaypointPath:
    """Moves between waypoints, evaluated as nine plain floats by the subclass's ``evaluate_flat``.

    A path is a value once made: nothing changes it (its arrays are read-only), so a copy of it,
    deep or not, is the path itself (a component's FMU state holds it without copying its moves).
    """

    def _freeze(self) -> None:
        """Make the path's arrays read-only copies (the end of a subclass's ``__init__``; the
        caller's arrays stay as they were)."""
        for name, value in list(vars(self).items()):
            if isinstance(value, np.ndarray):
                frozen = value.copy()
                frozen.setflags(write=False)
                setattr(self, name, frozen)

    def __copy__(self) -> "_WaypointPath":
        return self

    def __deepcopy__(self, memo: dict) -> "_WaypointPath":
        return self

    def evaluate_flat(self, t: float) -> Flat9:
        raise NotImplementedError

    def evaluate(self, t: float) -> Vector3:
        """Reference position, velocity and acceleration at time ``t``."""
        return _vectors(self.evaluate_flat(t))


class MinimumJerkPath(_WaypointPath):
    """Rest-to-rest minimum-jerk moves through ``waypoints`` (n x 3, metres).

    ``durations[k]`` (n-1 values, s) is the time of the move from waypoint k to waypoint k+1;
    ``dwell`` (scalar or n values, s) is the time held at each waypoint before leaving it (the
    dwell at the last waypoint only lengthens :attr:`duration`). Before ``t0`` the path rests at
    the first waypoint, after the end at the last one. Every waypoint must lie in ``workspace``
    (pass None to skip) and, when ``params`` is given, the waypoints and points sampled along
    every move must be reachable by inverse kinematics.
    """

    def __init__(self, waypoints: Sequence[Sequence[float]], durations: Sequence[float],
                 dwell: float | Sequence[float] = 0.0, t0: float = 0.0,
                 workspace: Workspace | None = Workspace(), params=None) -> None:
        T = np.array(durations, dtype=float).reshape(-1)
        for k, Tk in enumerate(T):
            if not Tk > 0.0:
                raise ValueError(f"duration {k} (waypoint {k} -> {k + 1}) = {Tk} s must be > 0")
        pts, D = _waypoints(waypoints, len(T), dwell, workspace, params)
        self.waypoints, self.durations, self.dwell, self.t0 = pts, T, D, float(t0)
        self.duration = float(D.sum() + T.sum())
        # plain floats for evaluate(): sampled every step, where numpy's per-call cost dominates
        self._starts = _move_starts(self.t0, T, D)
        moves = [(float(T[k]), tuple(pts[k].tolist()), tuple((pts[k + 1] - pts[k]).tolist()))
                 for k in range(len(T))]
        # the fields of its MinimumJerkTable (padded; beyond MAX_MOVES for Python's use only)
        size = max(MAX_MOVES, len(moves))
        self.n_moves, self.starts = len(moves), _padded(self._starts, math.inf, size)
        self.moves, self.at_rest = _padded(moves, _NO_MOVE, size), _resting(pts[0])
        self._freeze()

    def table(self) -> MinimumJerkTable:
        """The path as a :class:`MinimumJerkTable` for :func:`evaluate_table` (and its generated
        C); ValueError when it has more than :data:`MAX_MOVES` moves."""
        return _fixed(MinimumJerkTable(self.n_moves, self.starts, self.moves, self.at_rest), "minimum-jerk")

    def evaluate_flat(self, t: float) -> Flat9:
        """:meth:`evaluate` as nine plain floats r, rd, rdd (no arrays: for writing into buffers).

        It reads only the fields a :class:`MinimumJerkTable` has, so it is also
        :func:`evaluate_table`, the kernel translated to C: one source, and no second Python call
        (which would cost ~15 % here)."""
        starts = self.starts
        k = bisect.bisect_right(starts, t, 0, self.n_moves) - 1
        if k < 0:
            return self.at_rest
        T, p, d = self.moves[k]
        s, ds, dds = minimum_jerk((t - starts[k]) / T)
        ds, dds = ds / T, dds / (T * T)
        return (p[0] + s * d[0], p[1] + s * d[1], p[2] + s * d[2], ds * d[0], ds * d[1], ds * d[2],
                dds * d[0], dds * d[1], dds * d[2])


#: ``evaluate_table(table: MinimumJerkTable, t) -> Flat9``: r, rd, rdd of the path at ``t``
evaluate_table = MinimumJerkPath.evaluate_flat


class ConstantSpeedPath(_WaypointPath):
    """Straight moves through ``waypoints`` (n x 3, m) at ``speeds[k]`` (m/s) along move k.

    Each move starts from rest, reaches its speed along the minimum-jerk blend over ``blend``
    seconds, cruises, and comes to rest at the next waypoint along the mirrored blend (position,
    velocity and acceleration continuous; a blend covers ``speed * blend / 2``, so a move must be
    at least ``speed * blend`` long). ``dwell``, ``t0``, ``workspace`` and ``params`` as for
    :class:`MinimumJerkPath`.
    """

    def __init__(self, waypoints: Sequence[Sequence[float]], speeds: Sequence[float], blend: float,
                 dwell: float | Sequence[float] = 0.0, t0: float = 0.0,
                 workspace: Workspace | None = Workspace(), params=None) -> None:
        V = np.array(speeds, dtype=float).reshape(-1)
        pts, D = _waypoints(waypoints, len(V), dwell, workspace, params)
        if not blend > 0.0:
            raise ValueError(f"blend must be > 0, got {blend} s")
        moves, T = [], []
        for k, Vk in enumerate(V):
            d = pts[k + 1] - pts[k]
            length = float(np.linalg.norm(d))
            if not Vk > 0.0:
                raise ValueError(f"speed {k} (waypoint {k} -> {k + 1}) = {Vk} m/s must be > 0")
            if length < Vk * blend:
                raise ValueError(f"move {k} (waypoint {k} -> {k + 1}) is {length:.6g} m long, shorter "
                                 f"than speed x blend = {Vk * blend:.6g} m: lower the speed or the blend")
            T.append(length / Vk + blend)
            moves.append((float(T[-1]), float(Vk), length, tuple(pts[k].tolist()), tuple((d / length).tolist())))
        self.waypoints, self.speeds, self.blend, self.dwell, self.t0 = pts, V, float(blend), D, float(t0)
        self.durations = np.array(T)
        self.duration = float(D.sum() + self.durations.sum())
        self._starts = _move_starts(self.t0, self.durations, D)
        # the fields of its ConstantSpeedTable (padded; beyond MAX_MOVES for Python's use only)
        size = max(MAX_MOVES, len(moves))
        self.n_moves, self.starts = len(moves), _padded(self._starts, math.inf, size)
        self.moves, self.at_rest = _padded(moves, _NO_SPEED_MOVE, size), _resting(pts[0])
        self._freeze()

    def table(self) -> ConstantSpeedTable:
        """The path as a :class:`ConstantSpeedTable` for :func:`evaluate_speed_table` (and its
        generated C); ValueError when it has more than :data:`MAX_MOVES` moves."""
        return _fixed(ConstantSpeedTable(self.n_moves, self.starts, self.moves, self.blend, self.at_rest),
                      "constant-speed")

    def evaluate_flat(self, t: float) -> Flat9:
        """:meth:`evaluate` as nine plain floats r, rd, rdd (no arrays: for writing into buffers);
        also :func:`evaluate_speed_table`, as :meth:`MinimumJerkPath.evaluate_flat`."""
        starts = self.starts
        k = bisect.bisect_right(starts, t, 0, self.n_moves) - 1
        if k < 0:
            return self.at_rest
        T, V, length, p, u = self.moves[k]
        s, v, a = _along(min(t - starts[k], T), T, V, length, self.blend)
        return (p[0] + s * u[0], p[1] + s * u[1], p[2] + s * u[2], v * u[0], v * u[1], v * u[2],
                a * u[0], a * u[1], a * u[2])


#: ``evaluate_speed_table(table: ConstantSpeedTable, t) -> Flat9``: r, rd, rdd of the path at ``t``
evaluate_speed_table = ConstantSpeedPath.evaluate_flat


class CirclePath:
    """Horizontal circle ``centre + radius (cos phi, sin phi, 0)`` run counter-clockwise.

    The angular rate rises from 0 to 2 pi / period over ``ramp_time`` (default one period) along
    the minimum-jerk blend, so the path starts at rest at phase ``phase0`` and r, rd, rdd (and
    the jerk) are continuous. Before ``t0`` the path rests at its start point.
    """

    def __init__(self, centre: Sequence[float], radius: float, period: float,
                 ramp_time: float | None = None, phase0: float = 0.0, t0: float = 0.0,
                 workspace: Workspace | None = Workspace(), params=None,
                 n_check: int = 72) -> None:
        c = np.array(centre, dtype=float).reshape(-1)
        if c.shape != (3,):
            raise ValueError(f"centre must have 3 components, got {centre!r}")
        if not radius > 0.0 or not period > 0.0:
            raise ValueError(f"radius ({radius} m) and period ({period} s) must be > 0")
        self.ramp_time = float(period if ramp_time is None else ramp_time)
        if not self.ramp_time > 0.0:
            raise ValueError(f"ramp_time must be > 0, got {ramp_time}")
        self.centre, self.radius, self.period = c, float(radius), float(period)
        self.omega, self.phase0, self.t0 = 2.0 * math.pi / self.period, float(phase0), float(t0)
        phi = self.phase0 + np.linspace(0.0, 2.0 * math.pi, n_check, endpoint=False)
        ring = c + self.radius * np.column_stack((np.cos(phi), np.sin(phi), np.zeros_like(phi)))
        _check_points(c[None, :], None, None, "circle centre")
        try:
            _check_points(ring, workspace, params, "circle point")
        except ValueError as exc:
            raise ValueError(f"circle (centre {tuple(c)}, radius {radius}): {exc}") from None

    def phase(self, t: float) -> tuple[float, float, float]:
        """Phase angle phi(t) and its first two time derivatives."""
        tau, Tr, W = (t - self.t0) / self.ramp_time, self.ramp_time, self.omega
        if tau <= 0.0:
            return self.phase0, 0.0, 0.0
        if tau >= 1.0:
            # integral of the blend over [0, 1] is 1/2
            return self.phase0 + W * (0.5 * Tr + (t - self.t0 - Tr)), W, 0.0
        s, ds, _ = minimum_jerk(tau)
        integral = tau ** 4 * (2.5 + tau * (-3.0 + tau))  # int_0^tau s
        return self.phase0 + W * Tr * integral, W * s, W * ds / Tr

    def evaluate(self, t: float) -> Vector3:
        """Reference position, velocity and acceleration at time ``t``."""
        phi, w, wd = self.phase(t)
        c, s, R = math.cos(phi), math.sin(phi), self.radius
        r = self.centre + np.array([R * c, R * s, 0.0])
        rd = np.array([-R * s * w, R * c * w, 0.0])
        rdd = np.array([-R * (s * wd + c * w * w), R * (c * wd - s * w * w), 0.0])
        return r, rd, rdd


class RecordedPath:
    """Playback of recorded references (CSV columns ``time, x, y, z``; a header line is allowed).

    Interpolated by :class:`scipy.interpolate.CubicSpline` ("not-a-knot"), which passes through
    every sample and is C2, so rdd is continuous and piecewise linear; errors are O(h^4), O(h^3)
    and O(h^2) in r, rd, rdd for sample spacing h. It also passes the recording noise through,
    amplified by 1/h^2 in rdd (10 um at 100 Hz gives m/s^2 errors): for measured recordings
    set ``smoothing`` > 0 to use a penalised cubic smoothing spline instead
    (:func:`scipy.interpolate.make_smoothing_spline` with ``lam`` = ``smoothing``, in s^3;
    1e-4 suits 100 Hz samples of hand-guided motion). Outside the recorded interval the path
    holds the end sample at rest; the time origin is shifted by ``t0``.
    """

    def __init__(self, data: str | np.ndarray, smoothing: float = 0.0, t0: float = 0.0,
                 workspace: Workspace | None = Workspace(), params=None) -> None:
        from scipy.interpolate import CubicSpline, make_smoothing_spline

        arr = _load_csv(data) if isinstance(data, str) else np.asarray(data, dtype=float)
        if arr.ndim != 2 or arr.shape[1] != 4 or len(arr) < 4:
            raise ValueError(f"recorded references need >= 4 rows of (time, x, y, z), "
                             f"got shape {arr.shape}")
        t = arr[:, 0]
        if np.any(np.diff(t) <= 0.0):
            k = int(np.argmax(np.diff(t) <= 0.0)) + 1
            raise ValueError(f"recorded time must increase strictly; row {k} has t = {t[k]}")
        _check_points(arr[:, 1:], workspace, params, "recorded sample")
        if smoothing > 0.0:
            self._spline = [make_smoothing_spline(t, arr[:, j], lam=smoothing) for j in (1, 2, 3)]
        else:
            self._spline = [CubicSpline(t, arr[:, 1:], axis=0)]
        self._d1 = [s.derivative(1) for s in self._spline]
        self._d2 = [s.derivative(2) for s in self._spline]
        self.t_start, self.t_end, self.t0 = float(t[0]), float(t[-1]), float(t0)
        self._first, self._last = arr[0, 1:].copy(), arr[-1, 1:].copy()

    @property
    def duration(self) -> float:
        """Length of the recording in seconds."""
        return self.t_end - self.t_start

    def evaluate(self, t: float) -> Vector3:
        """Reference position, velocity and acceleration at time ``t``."""
        tau = t - self.t0
        if tau <= self.t_start:
            return self._first.copy(), np.zeros(3), np.zeros(3)
        if tau >= self.t_end:
            return self._last.copy(), np.zeros(3), np.zeros(3)
        return (np.hstack([s(tau) for s in self._spline]),
                np.hstack([s(tau) for s in self._d1]),
                np.hstack([s(tau) for s in self._d2]))


def _load_csv(path: str) -> np.ndarray:
    with open(path, encoding="utf-8") as fh:
        first = fh.readline()
    try:
        [float(v) for v in first.replace(";", ",").split(",")]
        skip = 0
    except ValueError:
        skip = 1
    try:
        return np.loadtxt(path, delimiter=",", skiprows=skip, ndmin=2)
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read recorded references from {path!r}: {exc}") from None
