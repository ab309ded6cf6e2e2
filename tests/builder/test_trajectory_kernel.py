"""The waypoint paths as generated C of one fixed type (issue 26): ``evaluate_table`` over a
:class:`MinimumJerkTable` (and ``evaluate_speed_table`` over a :class:`ConstantSpeedTable`) is
translated once; a path of 1 to 16 waypoints is data of that one C struct, its unused moves
padded. The C equals the Python bit for bit (the generator keeps Python's float operations, and
the unit is compiled with -ffp-contract=off), and both equal the minimum-jerk closed form,
written out here independently, to round-off: a wrong move (e.g. a padding one, which the
search must never reach) shows there.
"""
from __future__ import annotations

import bisect
import math
import struct
from pathlib import Path

import numpy as np
import pytest
import yaml

from deltafmi.builder.codegen import D, Entry, I, Vec, named
from deltafmi.builder.codegen.build import compile_unit, from_c, to_c
from deltafmi.toolchain import NoCompilerError
from deltafmi.physics.delta.trajectory import (MAX_MOVES, ConstantSpeedPath, ConstantSpeedTable, MinimumJerkPath,
                                                 MinimumJerkTable, evaluate_speed_table, evaluate_table)

FLAGSHIP = Path(__file__).resolve().parents[2] / "scenarios" / "delta_tracking.yaml"


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    entries = [Entry("dfk_path", evaluate_table, [named(MinimumJerkTable), D]),
               Entry("dfk_speed_path", evaluate_speed_table, [named(ConstantSpeedTable), D]),
               Entry("bisect_between", bisect_between, [Vec(6), D, I, I])]
    try:
        return compile_unit(entries, tmp_path_factory.mktemp("trajectory_kernel"), name="path")
    except NoCompilerError as exc:
        pytest.skip(f"no C compiler for the generated kernels: {exc}")


def bisect_between(a, x, lo, hi):
    """The kernels' search for the move under way, on a slice of a sequence (as a float: the
    ctypes bridge of build.py returns floats and sequences)."""
    return float(bisect.bisect_right(a, x, lo, hi))


def flagship_waypoints() -> tuple[list, list, float, float]:
    """Waypoints, move durations, dwell and start of the flagship's Trajectory (mode 0)."""
    p = yaml.safe_load(FLAGSHIP.read_text())["components"]["trajectory"]["parameters"]
    n = p["n_waypoints"]
    points = list(zip(p["wp_x"][:n], p["wp_y"][:n], p["wp_z"][:n]))
    return points, p["wp_T"][:n - 1], p["dwell"], p.get("t_start", 0.0)


def random_waypoints(n: int, seed: int) -> tuple[list, list, list, float]:
    """n waypoints in the workspace, durations 0.1-0.6 s, dwells of 0 (moves back to back) to 0.3 s."""
    rng = np.random.default_rng(seed)
    radius, angle = 0.45 * np.sqrt(rng.uniform(0.0, 1.0, n)), rng.uniform(0.0, 2 * math.pi, n)
    points = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), rng.uniform(-1.15, -0.8, n)])
    dwell = np.where(rng.uniform(0.0, 1.0, n) < 0.4, 0.0, rng.uniform(0.0, 0.3, n))
    return points.tolist(), rng.uniform(0.1, 0.6, n - 1).tolist(), dwell.tolist(), 0.3


CASES = {"flagship": flagship_waypoints(), "1 waypoint": random_waypoints(1, 1),
         "2 waypoints": random_waypoints(2, 2), "8 waypoints": random_waypoints(8, 8)}


def times(path) -> list[float]:
    """Dense times from before the start to after the end, every move's start and end exactly
    and one ulp either side, and the infinities."""
    edges = [s for s, T in zip(path.starts, path.durations) for s in (s, s + T)]
    near = [math.nextafter(e, d) for e in edges for d in (-math.inf, math.inf)]
    dense = np.linspace(path.t0 - 0.3, path.t0 + path.duration + 0.3, 2500).tolist()
    return dense + edges + near + [path.t0, -math.inf, math.inf]


def bits(values) -> list[int]:
    return [struct.unpack("<q", struct.pack("<d", v))[0] for v in values]


def closed_form(points, durations, dwell, t0, t) -> np.ndarray:
    """r, rd, rdd of rest-to-rest moves with s(u) = 10 u^3 - 15 u^4 + 6 u^5, from the path's
    definition: hold at waypoint k for dwell[k], then move to k + 1 in durations[k]."""
    p = np.asarray(points, dtype=float)
    hold = np.broadcast_to(np.asarray(dwell, dtype=float), (len(p),))
    begin = t0
    for k, T in enumerate(durations):
        begin += hold[k]
        if t < begin:
            break
        if t < begin + T:
            u, d = (t - begin) / T, p[k + 1] - p[k]
            s = 10 * u ** 3 - 15 * u ** 4 + 6 * u ** 5
            v = (30 * u ** 2 - 60 * u ** 3 + 30 * u ** 4) / T
            a = (60 * u - 180 * u ** 2 + 120 * u ** 3) / T ** 2
            return np.concatenate([p[k] + s * d, v * d, a * d])
        begin += T
    else:
        k = len(p) - 1
    return np.concatenate([p[k], np.zeros(6)])


@pytest.mark.parametrize("case", CASES)
def test_minimum_jerk_kernel_c_equals_python_bit_for_bit(lib, case):
    points, durations, dwell, t0 = CASES[case]
    path = MinimumJerkPath(points, durations, dwell=dwell, t0=t0)
    table = path.table()
    assert table.n_moves == len(points) - 1 and len(table.starts) == MAX_MOVES
    for t in times(path):
        c = lib.call("dfk_path", table, t)
        assert bits(c) == bits(evaluate_table(table, t)) == bits(path.evaluate_flat(t)), f"{case}: t = {t!r}"


@pytest.mark.parametrize("case", CASES)
def test_minimum_jerk_kernel_equals_the_closed_form(lib, case):
    points, durations, dwell, t0 = CASES[case]
    path = MinimumJerkPath(points, durations, dwell=dwell, t0=t0)
    table = path.table()
    worst = np.zeros(3)
    for t in times(path):
        err = np.abs(np.array(lib.call("dfk_path", table, t)) - closed_form(points, durations, dwell, t0, t))
        worst = np.maximum(worst, err.reshape(3, 3).max(axis=1))
    # round-off (seen: 2e-15 m, 2e-14 m/s, 8e-13 m/s^2 on ~1 m, ~10 m/s, ~300 m/s^2); a wrong
    # move is off by centimetres
    assert worst[0] < 1e-13 and worst[1] < 1e-12 and worst[2] < 1e-10, worst


def test_a_table_is_one_c_type_for_every_waypoint_count():
    c_type = named(MinimumJerkTable)
    for points, durations, dwell, t0 in CASES.values():
        table = MinimumJerkPath(points, durations, dwell=dwell, t0=t0).table()
        # the struct's layout comes from the class, and holds every table whole
        assert from_c(c_type, to_c(c_type, table)) == table and len(table.moves) == MAX_MOVES
        assert all(s == math.inf for s in table.starts[table.n_moves:])
    # more moves than the C holds: Python still evaluates the path, table() says why it cannot
    points, durations, dwell, t0 = random_waypoints(MAX_MOVES + 2, 5)
    path = MinimumJerkPath(points, durations, dwell=dwell, t0=t0)
    end = closed_form(points, durations, dwell, t0, path.t0 + path.duration)
    assert np.max(np.abs(np.array(path.evaluate_flat(path.t0 + path.duration)) - end)) < 1e-12
    with pytest.raises(ValueError, match=rf"{MAX_MOVES + 1} moves .* at most MAX_MOVES = {MAX_MOVES}"):
        path.table()


@pytest.mark.parametrize("case", CASES)
def test_constant_speed_kernel_c_equals_python_and_the_path(lib, case):
    points, _, dwell, t0 = CASES[case]
    lengths = [float(np.linalg.norm(np.subtract(b, a))) for a, b in zip(points, points[1:])]
    blend = 0.05  # s; speeds with room to cruise: a move must be at least speed x blend long
    speeds = [max(0.05, min(1.0, 0.8 * L / blend)) for L in lengths]
    path = ConstantSpeedPath(points, speeds, blend, dwell=dwell, t0=t0)
    table = path.table()
    for t in times(path):
        c = lib.call("dfk_speed_path", table, t)
        assert bits(c) == bits(evaluate_speed_table(table, t)) == bits(path.evaluate_flat(t)), f"{case}: t = {t!r}"
    # independent of the kernel: at rest on the waypoints (before, mid-dwell, after), at speed mid-cruise
    hold = np.broadcast_to(np.asarray(dwell, dtype=float), (len(points),))
    rests = [(t0 - 1.0, 0), (path.t0 + path.duration + 1.0, -1), (math.inf, -1)]
    begin = t0
    for k, T in enumerate(path.durations.tolist()):
        if hold[k] > 0.0:
            rests.append((begin + 0.5 * hold[k], k))
        mid = np.array(lib.call("dfk_speed_path", table, begin + hold[k] + 0.5 * T))
        assert np.linalg.norm(mid[3:6]) == pytest.approx(speeds[k], rel=1e-12) and not mid[6:].any(), (case, k)
        begin += hold[k] + T
    for t, k in rests:
        r = np.array(lib.call("dfk_speed_path", table, t))
        assert np.max(np.abs(r[:3] - points[k])) < 1e-12 and not r[3:].any(), (case, k, t)


def test_bisect_right_between_lo_and_hi_as_python(lib):
    rng = np.random.default_rng(6)
    for _ in range(300):
        a = np.sort(rng.choice([0.0, 0.5, 1.0, 1.5, 2.0, math.inf], 6)).tolist()
        lo = int(rng.integers(0, 7))
        hi = int(rng.integers(lo, 7))
        x = float(rng.choice(a + [-1.0, 0.25, 3.0, math.inf]))
        assert lib.call("bisect_between", a, x, lo, hi) == bisect_between(a, x, lo, hi), (a, x, lo, hi)
