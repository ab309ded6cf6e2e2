"""Reference trajectories: boundary conditions, analytic peaks, geometry, derivative
consistency and workspace errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltafmi.physics.delta.params import RL5
from deltafmi.physics.delta.trajectory import (CirclePath, MinimumJerkPath, RecordedPath, Workspace,
                                           minimum_jerk)

A, B, C = (0.0, 0.0, -1.0), (0.2, -0.1, -0.9), (-0.1, 0.3, -1.1)


def numeric_derivatives(path, t, h=1e-5):
    """Central differences of r and rd at t."""
    rp, rdp, _ = path.evaluate(t + h)
    rm, rdm, _ = path.evaluate(t - h)
    return (rp - rm) / (2 * h), (rdp - rdm) / (2 * h)


def test_minimum_jerk_blend_boundary_conditions():
    assert minimum_jerk(0.0) == (0.0, 0.0, 0.0) and minimum_jerk(1.0) == (1.0, 0.0, 0.0)
    s, ds, dds = minimum_jerk(0.5)
    assert (s, ds, dds) == pytest.approx((0.5, 1.875, 0.0))


def test_waypoint_moves_rest_at_waypoints_and_peak_speed():
    path = MinimumJerkPath([A, B, C], [0.8, 1.2], dwell=[0.0, 0.3, 0.0], t0=0.5)
    assert path.duration == pytest.approx(2.3)
    # rest at every waypoint, at the start and end of every move
    for t, point in [(0.5, A), (1.3, B), (1.6, B), (2.8, C), (10.0, C), (-1.0, A)]:
        r, rd, rdd = path.evaluate(t)
        assert np.max(np.abs(r - point)) < 1e-15
        assert np.max(np.abs(rd)) < 1e-12 and np.max(np.abs(rdd)) < 1e-9
    # peak speed 1.875 D / T at mid-move, and it is the maximum
    for start, T, p0, p1 in [(0.5, 0.8, A, B), (1.6, 1.2, B, C)]:
        D = np.linalg.norm(np.subtract(p1, p0))
        _, rd, rdd = path.evaluate(start + T / 2)
        assert np.linalg.norm(rd) == pytest.approx(1.875 * D / T, rel=1e-12)
        assert np.max(np.abs(rdd)) < 1e-12
        speeds = [np.linalg.norm(path.evaluate(t)[1]) for t in np.linspace(start, start + T, 101)]
        assert max(speeds) == pytest.approx(1.875 * D / T, rel=1e-12)
        # peak acceleration of the quintic: 10 / sqrt(3) D / T^2
        accs = [np.linalg.norm(path.evaluate(t)[2]) for t in np.linspace(start, start + T, 2001)]
        assert max(accs) == pytest.approx(10 / math.sqrt(3) * D / T ** 2, rel=1e-5)


def test_waypoint_derivatives_are_consistent():
    path = MinimumJerkPath([A, B, C], [0.8, 1.2], dwell=0.2)
    for t in np.linspace(0.05, path.duration - 0.05, 23):
        _, rd, rdd = path.evaluate(t)
        nrd, nrdd = numeric_derivatives(path, t)
        assert np.max(np.abs(rd - nrd)) < 1e-8 and np.max(np.abs(rdd - nrdd)) < 1e-6


def test_circle_radius_speed_and_smooth_ramp():
    centre, R, period, ramp = np.array([0.1, -0.05, -0.95]), 0.12, 1.5, 0.75
    path = CirclePath(centre, R, period, ramp_time=ramp, t0=0.2)
    r, rd, rdd = path.evaluate(0.0)
    assert np.allclose(r, centre + [R, 0, 0]) and not rd.any() and not rdd.any()
    for t in np.linspace(0.0, 3.0, 61):
        r, rd, rdd = path.evaluate(t)
        assert np.linalg.norm(r - centre) == pytest.approx(R, rel=1e-12)
        assert r[2] == centre[2] and rd[2] == 0.0 and rdd[2] == 0.0
        nrd, nrdd = numeric_derivatives(path, t)
        assert np.max(np.abs(rd - nrd)) < 1e-8 and np.max(np.abs(rdd - nrdd)) < 1e-5
    # full speed after the ramp: 2 pi R / period, centripetal acceleration R w^2
    w = 2 * math.pi / period
    for t in (1.0, 2.0, 2.9):
        _, rd, rdd = path.evaluate(t)
        assert np.linalg.norm(rd) == pytest.approx(w * R, rel=1e-12)
        assert np.linalg.norm(rdd) == pytest.approx(w * w * R, rel=1e-12)
    # rd and rdd continuous across the end of the ramp (and the jerk too: no kink in rdd)
    te, h = 0.2 + ramp, 1e-7
    for k in (1, 2):
        assert np.max(np.abs(path.evaluate(te - h)[k] - path.evaluate(te + h)[k])) < 1e-5
    # phase: half the ramp is lost against full speed from the start, per the blend's mean 1/2
    phi, _, _ = path.phase(0.2 + ramp + 1.0)
    assert phi == pytest.approx(w * (ramp / 2 + 1.0), rel=1e-12)


def test_recorded_playback_derivatives_of_an_analytic_signal(tmp_path):
    # x = a sin(w t), y = b cos(w t), z = z0 + c t^2, sampled at 100 Hz
    a, b, c, w = 0.05, 0.03, -0.01, 2 * math.pi * 0.5
    t = np.arange(0.0, 4.0 + 1e-9, 0.01)
    data = np.column_stack([t, a * np.sin(w * t), b * np.cos(w * t), -1.0 + c * t ** 2])
    csv = tmp_path / "ref.csv"
    np.savetxt(csv, data, delimiter=",", header="time,x,y,z", comments="")
    path = RecordedPath(str(csv), t0=1.0)
    assert path.duration == pytest.approx(4.0)
    h = 0.01
    for tau in np.linspace(0.5, 3.5, 31):    # away from the not-a-knot ends
        r, rd, rdd = path.evaluate(1.0 + tau)
        exact = (np.array([a * np.sin(w * tau), b * np.cos(w * tau), -1.0 + c * tau ** 2]),
                 np.array([a * w * np.cos(w * tau), -b * w * np.sin(w * tau), 2 * c * tau]),
                 np.array([-a * w * w * np.sin(w * tau), -b * w * w * np.cos(w * tau), 2 * c]))
        # cubic spline errors: O(h^4 f'''') for r, O(h^3) for rd, O(h^2) for rdd
        assert np.max(np.abs(r - exact[0])) < 0.05 * h ** 4 * a * w ** 4 + 1e-15
        assert np.max(np.abs(rd - exact[1])) < 0.1 * h ** 3 * a * w ** 4
        assert np.max(np.abs(rdd - exact[2])) < 0.5 * h ** 2 * a * w ** 4
    # outside the recording: hold the end samples at rest
    r, rd, rdd = path.evaluate(0.0)
    assert np.allclose(r, data[0, 1:]) and not rd.any() and not rdd.any()
    r, rd, rdd = path.evaluate(10.0)
    assert np.allclose(r, data[-1, 1:]) and not rd.any() and not rdd.any()


def test_recorded_smoothing_spline_tames_noise():
    # 10 um of recording noise at 100 Hz: the interpolating spline turns it into rdd errors as
    # large as the signal (noise / h^2); the smoothing spline keeps rdd within 1 %
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 4.0 + 1e-9, 0.01)
    noisy = np.column_stack([t, 0.05 * np.sin(math.pi * t) + rng.normal(0, 1e-5, t.size),
                             np.zeros_like(t), np.full_like(t, -1.0)])
    ts = np.linspace(0.5, 3.5, 301)
    amplitude = 0.05 * math.pi ** 2
    exact = -amplitude * np.sin(math.pi * ts)

    def rms_rdd_error(path):
        return np.sqrt(np.mean([(path.evaluate(s)[2][0] - e) ** 2 for s, e in zip(ts, exact)]))
    assert rms_rdd_error(RecordedPath(noisy)) > 0.5 * amplitude
    assert rms_rdd_error(RecordedPath(noisy, smoothing=1e-4)) < 0.01 * amplitude


def test_waypoint_outside_workspace_names_index_and_value():
    with pytest.raises(ValueError, match=r"waypoint 2 = \(0\.6, 0, -1\) m has radius 0\.6"):
        MinimumJerkPath([A, B, (0.6, 0.0, -1.0)], [1.0, 1.0])
    with pytest.raises(ValueError, match=r"waypoint 1 .* has z -0\.5 m outside"):
        MinimumJerkPath([A, (0.0, 0.0, -0.5)], [1.0])
    with pytest.raises(ValueError, match="duration 1"):
        MinimumJerkPath([A, B, C], [1.0, 0.0])
    # beyond the nominal cylinder but within reach: IK decides when the cylinder is off
    far = (0.0, 0.0, -1.4)
    MinimumJerkPath([A, far], [1.0], workspace=None, params=RL5)
    with pytest.raises(ValueError, match=r"waypoint 1 .* not reachable"):
        MinimumJerkPath([A, (0.0, 0.0, -1.5)], [1.0], workspace=None, params=RL5)
    # both ends reachable, the straight move between them is not (too close to the base)
    with pytest.raises(ValueError, match=r"move 0 \(waypoint 0 -> 1\) leaves the reachable"):
        MinimumJerkPath([(0.6, 0.0, -0.6), (-0.6, 0.0, -0.6)], [1.0], workspace=None,
                        params=RL5)


def test_circle_outside_workspace_is_rejected():
    with pytest.raises(ValueError, match=r"circle point 0 = \(0\.55, 0, -1\) m has radius"):
        CirclePath((0.4, 0.0, -1.0), 0.15, 1.0)
    with pytest.raises(ValueError, match="radius"):
        CirclePath((0.0, 0.0, -1.0), -0.1, 1.0)
    CirclePath((0.3, 0.0, -1.0), 0.2, 1.0, workspace=Workspace(r_max=0.5))


# ------------------------------------------------------------------------------ the FMU
@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_trajectory_fmu_matches_the_library(build_fmu_from_src, tmp_path, fmi_type):
    from fmpy import simulate_fmu

    fmu = build_fmu_from_src("trajectory.py")
    t = np.arange(0.0, 2.0 + 1e-9, 0.02)
    data = np.column_stack([t, 0.05 * np.sin(t), 0.02 * t, -1.0 - 0.01 * t ** 2])
    csv = tmp_path / "rec.csv"
    np.savetxt(csv, data, delimiter=",", header="time,x,y,z", comments="")
    cases = [
        ({"mode": 0, "n_waypoints": 3, "wp_x[2]": 0.2, "wp_y[3]": -0.1, "wp_z[3]": -0.8,
          "wp_T[1]": 0.6, "wp_T[2]": 0.9, "dwell": 0.1, "t_start": 0.2},
         MinimumJerkPath([(0, 0, -1), (0.2, 0, -1), (0.1, -0.1, -0.8)], [0.6, 0.9], dwell=0.1,
                         t0=0.2)),
        ({"mode": 1, "circle_centre[1]": 0.1, "radius": 0.05, "period": 0.8, "ramp_time": 0.4},
         CirclePath((0.1, 0.0, -1.0), 0.05, 0.8, ramp_time=0.4)),
        ({"mode": 2, "csv_file": str(csv), "t_start": 0.3}, RecordedPath(str(csv), t0=0.3)),
    ]
    names = [f"{v}[{i}]" for v in ("r", "rd", "rdd") for i in (1, 2, 3)]
    for start_values, path in cases:
        res = simulate_fmu(fmu, fmi_type=fmi_type, stop_time=2.5, output_interval=0.05,
                           start_values=start_values, output=names)
        for row in res[::5]:
            expected = np.concatenate(path.evaluate(row["time"]))
            got = np.array([row[n] for n in names])
            assert np.max(np.abs(got - expected)) < 1e-12, (start_values, row["time"])


def test_trajectory_fmu_rejects_a_waypoint_outside_the_workspace(build_fmu_from_src, capfd):
    from fmpy import simulate_fmu

    # fmpy's default logger prints: a logger passed to simulate_fmu would stay registered in
    # fmpy's native logging proxy after the call, freed, and crash the next FMU that logs
    with pytest.raises(Exception):
        simulate_fmu(build_fmu_from_src("trajectory.py"), fmi_type="CoSimulation",
                     stop_time=1.0, start_values={"wp_x[3]": 0.7})
    messages = "".join(capfd.readouterr()).splitlines()
    assert any("waypoint 2 = (0.7, 0.1, -0.9) m has radius" in m and "wp_x[k+1]" in m
               for m in messages)


def test_a_path_is_a_value_its_copies_share():
    """Nothing changes a path once made (its arrays are read-only copies of the caller's), so its
    copies, deep or not, are the path itself; the robot's parameters likewise."""
    import copy

    from deltafmi.physics.delta.trajectory import ConstantSpeedPath

    waypoints = np.array([A, B, C])
    for path in (MinimumJerkPath(waypoints, [0.8, 1.2], dwell=0.2),
                 ConstantSpeedPath(waypoints, [0.5, 0.5], blend=0.1, dwell=0.2)):
        assert copy.deepcopy(path) is path and copy.copy(path) is path
        assert copy.deepcopy({"p": path})["p"] is path
        with pytest.raises(ValueError):
            path.waypoints[0, 0] = 1.0
        assert path.waypoints[0, 0] == A[0]
    waypoints[0, 0] = 0.5  # the caller's array is still its own, writable
    assert copy.deepcopy(RL5) is RL5
