"""Wrist reference trajectory FMU: a thin component over deltafmi.physics.delta.trajectory."""
import os
from typing import Optional

from deltafmi.component import Component, Experiment, Kernel, NativeKernels, Output, Parameter
from deltafmi.physics.delta.trajectory import (CirclePath, ConstantSpeedPath, ConstantSpeedTable, Flat9,
                                                 MinimumJerkPath, MinimumJerkTable, RecordedPath, evaluate_speed_table,
                                                 evaluate_table)

__all__ = ["Trajectory"]

MAX_WAYPOINTS = 8


def reference(jerk: Optional[MinimumJerkTable], speed: Optional[ConstantSpeedTable], t: float) -> Flat9:
    """r, rd, rdd at ``t`` from the waypoint path's table (modes 0 and 3; the compiled kernel)."""
    if jerk is not None:
        return evaluate_table(jerk, t)
    if speed is not None:
        return evaluate_speed_table(speed, t)
    raise ValueError("only the waypoint paths (modes 0 and 3) have a table")


def reference_after_step(jerk: Optional[MinimumJerkTable], speed: Optional[ConstantSpeedTable], t: float,
                         h: float) -> Flat9:
    """The Co-Simulation step from ``t`` over ``h``: the reference at its end (the compiled step)."""
    return reference(jerk, speed, t + h)


class Trajectory(Component):
    """Reference r, rd, rdd for the delta robot wrist: waypoints, circle, recorded CSV, set speeds.

    mode 0: rest-to-rest minimum-jerk moves through the first n_waypoints of (wp_x, wp_y, wp_z);
    wp_T[k] is the duration of the move from waypoint k to waypoint k+1, and the path rests for
    ``dwell`` at each waypoint. mode 1: horizontal circle (circle_centre, radius, period) whose
    angular rate ramps in along a minimum-jerk profile over ramp_time. mode 2: playback of
    csv_file (columns time, x, y, z; relative paths are looked up in the working directory,
    then in the FMU resources) through a cubic spline, smoothed when csv_smoothing > 0. mode 3:
    straight moves through the waypoints at set speeds, wp_v[k] along the move from waypoint k,
    each reaching its speed (and rest) along a minimum-jerk blend of blend_time, with dwell.
    Everything starts at t_start. Waypoints and circles outside the nominal workspace
    (r <= 0.5 m, -1.2 <= z <= -0.75 m) fail initialization with a message naming them.
    """

    model_name = "Trajectory"
    default_experiment = Experiment(start=0.0, stop=3.0, step=1e-3, tolerance=1e-6)

    mode = Parameter(0, type=int, min=0, max=3,
                     description="0 minimum-jerk waypoints, 1 circle, 2 CSV playback, 3 waypoints at set speeds")
    t_start = Parameter(0.0, unit="s", description="Time at which the motion starts")
    n_waypoints = Parameter(4, type=int, min=1, max=MAX_WAYPOINTS,
                            description="Number of waypoints used (mode 0)")
    wp_x = Parameter([0.0, 0.1, 0.1, 0.0] + [0.0] * 4, unit="m", description="Waypoint x")
    wp_y = Parameter([0.0, 0.0, 0.1, 0.0] + [0.0] * 4, unit="m", description="Waypoint y")
    wp_z = Parameter([-1.0, -1.0, -0.9, -1.0] + [-1.0] * 4, unit="m", description="Waypoint z")
    wp_T = Parameter([0.5] * MAX_WAYPOINTS, unit="s", min=0.0,
                     description="wp_T[k]: duration of the move from waypoint k to k+1")
    wp_v = Parameter([0.1] * MAX_WAYPOINTS, unit="m/s", min=0.0,
                     description="wp_v[k]: speed of the move from waypoint k to k+1 (mode 3)")
    blend_time = Parameter(0.1, unit="s", min=0.0,
                           description="Time to reach a move's speed and to stop again (mode 3)")
    dwell = Parameter(0.2, unit="s", min=0.0, description="Rest at each waypoint (modes 0, 3)")
    circle_centre = Parameter([0.0, 0.0, -1.0], unit="m", description="Circle centre (mode 1)")
    radius = Parameter(0.1, unit="m", min=0.0, description="Circle radius (mode 1)")
    period = Parameter(1.0, unit="s", min=0.0, description="Period at full speed (mode 1)")
    ramp_time = Parameter(1.0, unit="s", min=0.0,
                          description="Time to reach full angular rate (mode 1)")
    csv_file = Parameter("", type=str, description="CSV of time, x, y, z (mode 2)")
    csv_smoothing = Parameter(0.0, unit="s3", min=0.0,
                              description="Smoothing-spline penalty; 0 interpolates (mode 2)")

    r = Output(shape=3, unit="m", description="Reference wrist position")
    rd = Output(shape=3, unit="m/s", description="Reference wrist velocity")
    rdd = Output(shape=3, unit="m/s2", description="Reference wrist acceleration")

    #: the waypoint paths (modes 0 and 3) in C; the circle and the CSV playback stay Python
    native = NativeKernels(
        outputs=Kernel(reference, "_jerk", "_speed", "t", returns=("r", "rd", "rdd")),
        step=Kernel(reference_after_step, "_jerk", "_speed", "t", "h", returns=("r", "rd", "rdd")),
        attributes={"_jerk": Optional[MinimumJerkTable], "_speed": Optional[ConstantSpeedTable]})

    def setup(self) -> None:
        self._path = self._jerk = self._speed = None

    def initialize(self, t: float) -> None:
        try:
            self._path = self._make_path()
        except ValueError as exc:
            if self.mode not in (0, 3):
                raise
            raise ValueError(f"{exc} (waypoints count from 0 here: waypoint k is "
                             f"wp_x[k+1], wp_y[k+1], wp_z[k+1])") from None
        self._tables()

    def _tables(self) -> None:
        """The waypoint path's table (the kernels' data), None for the other paths."""
        path = self._path
        self._jerk = path.table() if isinstance(path, MinimumJerkPath) else None
        self._speed = path.table() if isinstance(path, ConstantSpeedPath) else None

    def _make_path(self):
        if self.mode in (0, 3):
            n = self.n_waypoints
            if not 1 <= n <= MAX_WAYPOINTS:
                raise ValueError(f"n_waypoints = {n} must be in 1..{MAX_WAYPOINTS}")
            points = list(zip(self.wp_x[:n], self.wp_y[:n], self.wp_z[:n]))
            if self.mode == 3:
                return ConstantSpeedPath(points, self.wp_v[:n - 1], self.blend_time, dwell=self.dwell,
                                         t0=self.t_start)
            return MinimumJerkPath(points, self.wp_T[:n - 1], dwell=self.dwell, t0=self.t_start)
        if self.mode == 1:
            return CirclePath(self.circle_centre, self.radius, self.period,
                              ramp_time=self.ramp_time, t0=self.t_start)
        if self.mode == 2:
            return RecordedPath(self._csv_path(), smoothing=self.csv_smoothing, t0=self.t_start)
        raise ValueError(f"mode = {self.mode} must be 0 (waypoints), 1 (circle), 2 (CSV) or 3 (set speeds)")

    def _csv_path(self) -> str:
        name = self.csv_file
        if not name:
            raise ValueError("mode 2 needs csv_file")
        for candidate in (name, os.path.join(self.resources_dir, name)):
            if os.path.isfile(candidate):
                return candidate
        raise ValueError(f"csv_file {name!r} not found (also looked in {self.resources_dir!r})")

    def outputs(self, t: float) -> None:
        if self._path is None:
            self._path = self._make_path()
            self._tables()
        if self._jerk is not None or self._speed is not None:
            self.write_reals(reference(self._jerk, self._speed, t), "r", "rd", "rdd")
        else:
            self.r, self.rd, self.rdd = self._path.evaluate(t)

    def do_step(self, t: float, h: float) -> None:
        pass  # no state: the runtime evaluates the outputs at t + h
