"""The live plot window (deltafmi.apps.scope): its rolling buffers, its routing of received
signals to subplots, its drawing (blitted frames against a full drawing), and the scope process
fed by real datagrams on 127.0.0.1, drawing off screen (Agg)."""
from __future__ import annotations

import io
import math
import os
import re
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from deltafmi.master.live.datagram import Encoder, encode, encode_json
from deltafmi.apps.scope.window import ScopeFigure, _size, run_scope
from deltafmi.master.live.display import display_problem
from deltafmi.apps.scope.data import MALFORMED_WARNINGS, ScopeData, Trace
from deltafmi.errors import BadInput

SUMMARY = re.compile(r"scope: (\d+) datagrams received \((\d+) malformed, (\d+) stale, (\d+) restarts\); "
                     r"(\d+) signals drawn; (\d+) frames? drawn, ended: (\w+)")


def _kept(times: np.ndarray, start: float) -> int:
    """Index of the first point a window from ``start`` on shows: the last one before ``start``."""
    inside = np.nonzero(times >= start)[0]
    return max(inside[0] - 1, 0)


def test_trace_keeps_the_window_through_compaction_and_growth():
    rng = np.random.default_rng(1)
    times = np.cumsum(rng.uniform(0.0, 0.01, 20000))  # irregular steps, some of them 0
    values = rng.normal(size=times.size)
    trace = Trace("x", window=0.5, capacity=8)
    stored = 0
    for size in rng.integers(1, 300, 200):
        for t, v in zip(times[stored:stored + size], values[stored:stored + size]):
            trace.add(float(t), float(v))
        trace.flush()
        stored = min(stored + size, times.size)
        newest = times[stored - 1]
        t, v = trace.since(newest - 0.5)
        first = _kept(times[:stored], newest - 0.5)
        assert np.array_equal(t, times[first:stored]) and np.array_equal(v, values[first:stored])
    assert len(trace) < 2 * 0.5 / 0.005 * 4  # old points were dropped: about 100 in a window


def test_visible_keeps_each_runs_extremes_and_they_stay_put():
    rng = np.random.default_rng(2)
    times = np.arange(30000) * 1e-3
    values = np.cumsum(rng.normal(size=times.size))
    trace = Trace("x", window=10.0)
    trace.extend(times[:20000], values[:20000])
    t, v = trace.visible(10.0, columns=400)
    first = _kept(times[:20000], 10.0)
    raw_t, raw_v = times[first:20000], values[first:20000]
    run = 32  # the least power of two that makes 10 001 points at most 400 runs
    assert len(raw_t) == 10001 and len(t) <= 2 * 400 + 2 * run
    assert np.all(np.diff(t) > 0) and np.all(np.isin(t, raw_t))
    assert np.array_equal(v, values[np.rint(t * 1e3).astype(int)])  # real points, with their times
    # runs are numbered from the trace's first point: each whole run keeps its least and greatest value
    for k in range(first // run + 1, 20000 // run):
        chunk = values[k * run:(k + 1) * run]
        shown = v[(t >= times[k * run]) & (t <= times[(k + 1) * run - 1])]
        assert sorted(shown) == sorted({chunk.min(), chunk.max()})
    assert v.min() == raw_v.min() and v.max() == raw_v.max()
    trace.extend(times[20000:20500], values[20000:20500])  # the window moves on half a second
    t2, v2 = trace.visible(10.5, columns=400)
    common = (t2 >= 11.0) & (t2 <= 19.9)
    assert np.array_equal(t2[common], t[(t >= 11.0) & (t <= 19.9)])  # the same points: no shimmer


def _data(*arguments, window=10.0):
    warnings = []
    return ScopeData(arguments, window, warn=warnings.append), warnings


def test_signals_go_to_the_subplots_of_their_patterns():
    data, _ = _data("plant.z[*]", "plant.z[1] follower.r[1]", "plant.q", "nothing.y")
    sent = []
    for k in range(50):
        values = {"follower.r[1]": 0.1 * k, "plant.z[1]": math.sin(k), "plant.z[2]": k + 0.5,
                  "plant.q[1]": -k, "plant.q[2]": 2.0 * k, "other.x": 7.0}
        sent.append(values)
        data.receive(encode(values, 0.01 * k, k))
    data.flush()
    names = [[trace.name for trace in group.traces] for group in data.groups]
    assert names == [["plant.z[1]", "plant.z[2]"], ["plant.z[1]", "follower.r[1]"], ["plant.q[1]", "plant.q[2]"], []]
    assert data.groups[0].traces[0] is data.groups[1].traces[0]  # one buffer, drawn twice
    for name, trace in data.traces.items():
        t, v = trace.since(-1.0)
        assert np.array_equal(t, [0.01 * k for k in range(50)])
        assert np.array_equal(v, [values[name] for values in sent])
    assert data.unselected == ["other.x"]
    assert data.unmatched() == ["'nothing.y' matched none of the received signals (received: other.x)"]
    assert data.counters == {"received": 50, "malformed": 0, "stale": 0, "restarts": 0}


def test_stale_datagrams_are_dropped_and_a_new_run_starts_the_picture_again():
    data, warnings = _data("x", window=1.0)
    for seq, t in enumerate([0.0, 0.1, 0.2, 0.3]):
        data.add(t, seq, {"x": t})
    data.add(0.25, 4, {"x": -1.0})  # late, but within the window and the sequence goes on: stale
    data.add(0.3, 5, {"x": 3.0})  # the same time again is not stale
    assert data.counters["stale"] == 1 and data.counters["restarts"] == 0
    data.add(0.05, 0, {"x": 5.0})  # the sequence went back: a new run
    data.add(0.06, 1, {"x": 6.0})
    data.flush()
    assert data.counters["restarts"] == 1 and data.started == 0.05
    assert np.array_equal(data.traces["x"].since(-1.0)[1], [5.0, 6.0])
    data.add(-5.0, 2, {"x": 1.0})  # time back by more than the window: a new run too
    assert data.counters["restarts"] == 2
    assert warnings[0] == "the sender's time went back from 0.3 s to 0.05 s: a new run, the picture starts again"
    data.add(-4.0, 0xFFFFFFFF, {"x": 1.0})
    data.add(-3.9, 0, {"x": 2.0})  # the sequence number wraps: not a restart
    assert data.counters["restarts"] == 2 and data.newest == -3.9


def test_malformed_datagrams_are_counted_and_the_first_ones_warned():
    data, warnings = _data("x")
    bad = [b"", b"garbage", encode({"x": 1.0}, 0.0, 0)[:-3], b"DFMI\x02" + bytes(15), b'{"format": "dfmi", "t": 1']
    for k in range(3 * len(bad)):
        data.receive(bad[k % len(bad)])
    data.receive(encode_json({"x": 2.5}, 1.0, 1))
    data.flush()
    assert data.counters == {"received": 3 * len(bad) + 1, "malformed": 3 * len(bad), "stale": 0, "restarts": 0}
    assert len(warnings) == MALFORMED_WARNINGS + 1 and warnings[-1] == "further malformed datagrams are counted only"
    assert warnings[0] == "malformed datagram dropped: empty datagram"
    assert warnings[3] == "malformed datagram dropped: version 2 (this deltafmi reads 1)"
    assert np.array_equal(data.traces["x"].since(0.0)[1], [2.5])


def test_bad_arguments_are_one_line_errors(tmp_path):
    with pytest.raises(BadInput, match="window must be a positive number of seconds, not 0"):
        ScopeData(["x"], 0.0)
    with pytest.raises(BadInput, match="name the signals to draw"):
        ScopeData(["x", "  "], 1.0)
    (tmp_path / "afile").write_text("a file where the picture's folder should be")
    with pytest.raises(BadInput, match=r"picture '.*afile/out\.png': .*afile is a file, not a folder"):
        run_scope(["x"], port=0, save=str(tmp_path / "afile" / "out.png"))


def test_a_display_with_a_backend_that_draws_no_window_is_told(monkeypatch):
    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    import matplotlib
    monkeypatch.setitem(matplotlib.rcParams, "backend", "Agg")
    assert display_problem() == "matplotlib's backend Agg draws no window (see MPLBACKEND)"
    monkeypatch.delenv("DISPLAY")
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert display_problem() == "no display (DISPLAY and WAYLAND_DISPLAY are unset)"


def _picture(arguments, window=10.0):
    data, _ = _data(*arguments, window=window)
    figure = Figure(figsize=_size(len(arguments)))
    FigureCanvasAgg(figure)
    return data, ScopeFigure(data, figure)


def _feed(data, start, count, rate=1000.0):
    for k in range(start, start + count):
        t = k / rate
        data.add(t, k, {"plant.z[1]": math.sin(t), "plant.z[2]": math.cos(3 * t), "plant.z[3]": -1.0 + 0.01 * t,
                        "trajectory.r[1]": 0.9})


def _pixels(figure):
    """A full drawing of the figure as it stands (what a saved file shows)."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="rgba", dpi=figure.dpi)
    width, height = figure.canvas.get_width_height()
    return np.frombuffer(buffer.getvalue(), np.uint8).reshape(height, width, 4)


def test_the_picture_shows_the_buffers_and_blitted_frames_equal_a_full_drawing():
    data, view = _picture(["plant.z[*]", "plant.z[1] trajectory.r[1]"])
    _feed(data, 0, 2500)
    view.render()
    assert view.full_draws == 1
    assert view.axes[-1].get_xlim() == (0.0, 10.0)  # the first window starts at the first time received
    _feed(data, 2500, 30000)
    view.render()
    right = math.ceil(data.newest / 1.0) * 1.0  # a tenth of the window
    assert view.axes[-1].get_xlim() == (right - 10.0, right) and right - 1.0 < data.newest <= right
    for ax, group, lines in zip(view.axes, data.groups, view.lines):
        assert [line.get_label() for line in lines] == [trace.name for trace in group.traces]
        for line, trace in zip(lines, group.traces):
            t, v = trace.visible(right - 10.0, int(ax.bbox.width))
            assert np.array_equal(line.get_xdata(), t) and np.array_equal(line.get_ydata(), v)
            raw = trace.since(right - 10.0)[1]
            assert ax.get_ylim()[0] <= raw.min() and raw.max() <= ax.get_ylim()[1]
    draws = view.full_draws
    _feed(data, 32500, 50)  # 50 ms more: the axes stay, the curves are blitted
    view.render()
    assert view.full_draws == draws
    blitted = np.asarray(view.figure.canvas.buffer_rgba()).copy()
    view.clock.set_animated(False)
    full = _pixels(view.figure)
    rows, columns = np.nonzero((blitted != full).any(axis=2))
    # only the anti-aliased edges of what lies over the curves (the opaque legends, the spines) may
    # differ: there a full drawing lets a curve show through a little
    height = view.figure.bbox.height
    covers = [artist.get_window_extent().extents
              for ax in view.axes for artist in [*ax.spines.values(), ax.get_legend()]]
    for row, column in zip(rows, columns):
        assert any(min(abs(column - x0), abs(column - x1)) <= 2 and height - y1 - 2 <= row <= height - y0 + 2
                   or min(abs(row - (height - y0)), abs(row - (height - y1))) <= 2 and x0 - 2 <= column <= x1 + 2
                   for x0, y0, x1, y1 in covers), (row, column)
    assert len(rows) < 100 and (full[..., :3] != 255).any(axis=2).sum() > 10000


def test_value_axes_keep_still_while_the_curves_stay_inside():
    data, view = _picture(["plant.z[*]"])
    _feed(data, 0, 12000)
    view.render()
    limits = view.axes[0].get_ylim()
    _feed(data, 12000, 8000)  # sin, cos: the same range
    view.render()
    assert view.axes[0].get_ylim() == limits
    data.add(20.0, 20000, {"plant.z[1]": 5.0})  # a curve leaves the axis
    view.render()
    assert view.axes[0].get_ylim()[1] >= 5.0


def _start_scope(tmp_path, *arguments):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    process = subprocess.Popen([sys.executable, "-m", "deltafmi.apps", "scope", "--port", "0", *arguments],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path)
    line = process.stdout.readline()
    match = re.fullmatch(r"listening 127\.0\.0\.1:(\d+)\n", line)
    assert match, (line, process.stderr.read() if process.poll() is not None else "")
    return process, ("127.0.0.1", int(match[1]))


def _ended(process, code: int = 0):
    out, err = process.communicate(timeout=600)
    assert process.returncode == code, err
    return SUMMARY.search(err), err


def test_the_scope_process_draws_what_it_receives_and_counts_malformed_datagrams(tmp_path):
    png = tmp_path / "out.png"
    process, address = _start_scope(tmp_path, "--window", "2", "--save", str(png), "--exit-when-idle", "1.5",
                                    "plant.z[*]", "nothing.y")
    encoder = Encoder(["plant.z[1]", "plant.z[2]", "other.x"])
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        for k in range(1000):
            sender.sendto(encoder.encode([math.sin(k * 1e-2), -1.0, 3.0], k * 1e-2, k), address)
            if k % 100 == 0:
                sender.sendto(b"DFMI not a datagram", address)
                time.sleep(0.01)  # a socket buffer of the kernel's default size must not overflow
    summary, err = _ended(process)
    assert summary and summary.groups()[:5] == ("1010", "10", "0", "0", "2"), err
    assert summary[7] == "idle" and int(summary[6]) >= 1
    assert err.count("malformed datagram dropped") == MALFORMED_WARNINGS
    assert "'nothing.y' matched none of the received signals (received: other.x)" in err
    from matplotlib.image import imread
    image = imread(png)
    assert image.shape[:2] == (100 * _size(2)[1], 100 * _size(2)[0])
    blue = np.all(np.abs(image[..., :3] - np.array([0x1f, 0x77, 0xb4]) / 255) < 0.02, axis=2)
    assert blue.sum() > 300  # the first curve is in the saved picture


def test_the_scope_process_ends_after_its_frames_and_on_sigterm(tmp_path):
    process, address = _start_scope(tmp_path, "--save", str(tmp_path / "a.png"), "--frames", "3", "--fps", "30", "x")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        k, deadline = 0, time.monotonic() + 600
        while process.poll() is None and time.monotonic() < deadline:
            sender.sendto(encode({"x": 1.0}, k * 1e-3, k), address)
            k += 1
            time.sleep(0.002)
    summary, err = _ended(process)
    assert summary and summary[6] == "3" and summary[7] == "frames", err
    process, address = _start_scope(tmp_path, "--save", str(tmp_path / "b.png"), "x")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        sender.sendto(encode({"x": 1.0}, 0.0, 0), address)
    time.sleep(0.5)
    process.send_signal(signal.SIGTERM)
    summary, err = _ended(process, 128 + signal.SIGTERM)
    assert summary and summary[1] == "1" and summary[7] == "terminated", err
    assert (tmp_path / "b.png").stat().st_size > 1000


def test_without_a_display_the_scope_needs_save_and_says_so_in_one_line(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    run = subprocess.run([sys.executable, "-m", "deltafmi.apps", "scope", "--port", "0", "x"],
                         capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr == ("Error: no display (DISPLAY and WAYLAND_DISPLAY are unset): give --save out.png "
                          "(with --frames N or --exit-when-idle SECONDS) to draw into a file\n")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        run = subprocess.run([sys.executable, "-m", "deltafmi.apps", "scope", "--port", str(port),
                              "--save", str(tmp_path / "c.png"), "x"], capture_output=True, text=True, timeout=600)
    assert run.returncode == 2
    assert run.stderr == f"Error: the scope cannot listen on 127.0.0.1:{port}: Address already in use\n"
