"""A live run over UDP on 127.0.0.1: inputs sent by another thread while the run goes, outputs
streamed back, malformed, stale and missing datagrams, and ``--replay`` repeating the run.

The Oscillator (tests/oscillator_analytic.py, wall and force step out of the way) is driven by
the force it receives: its recorded motion must be the closed-form motion under the recorded
force held over each step, and the streamed datagrams must carry the recorded values bit for bit.
"""
from __future__ import annotations

import logging
import socket
import struct
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import deltafmi
from deltafmi.apps.cli import main
from deltafmi.master.live.datagram import decode, encode
from deltafmi.master.results.result import read_result
from oscillator_analytic import P, _free

STOP, STEP = 0.6, 1e-3


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _scenario(tmp_path: Path, fmu: Path, port: int, out_port: int, slow_port: int) -> Path:
    path = tmp_path / "udp_live.yaml"
    path.write_text(f"""\
experiment: {{stop: {STOP}, step: {STEP}, tolerance: 1.0e-10}}
master: {{realtime: true}}
live:
  cmd:
    udp: {{port: {port}}}
    timeout: 0.15
    signals:
      F: {{unit: N, start: 0.5}}
      G: {{}}
components:
  osc: {{fmu: {fmu}, interface: CS, parameters: {{wall: -10.0, t_step: 100.0}}}}
connections:
  - {{from: cmd.F, to: osc.F}}
outputs: [osc.x, osc.v]
streams:
  - {{udp: '127.0.0.1:{out_port}', signals: [osc.x, cmd.F]}}
  - {{udp: '127.0.0.1:{slow_port}', signals: [osc.x], rate: 30}}
""")
    return path


class _Sender(threading.Thread):
    """Sends the force F = 1 + n / 10 (datagram n) every 10 ms for 0.25 s, with garbage, a
    stale datagram and an undeclared name in between, then nothing."""

    def __init__(self, port: int) -> None:
        super().__init__(daemon=True)
        self.port = port

    def run(self) -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            begin = time.monotonic()
            n = 0
            while time.monotonic() - begin < 0.25:
                sock.sendto(encode({"F": 1.0 + n / 10}, t=n * 0.01, seq=n), ("127.0.0.1", self.port))
                if n == 5:
                    sock.sendto(b"DFMI\x02\x01" + bytes(14), ("127.0.0.1", self.port))
                    sock.sendto(encode({"F": -99.0}, t=0.0, seq=99), ("127.0.0.1", self.port))  # stale
                    sock.sendto(encode({"F": 1.55, "nope": 1.0}, t=0.055, seq=100), ("127.0.0.1", self.port))
                n += 1
                time.sleep(0.01)


class _Listener(threading.Thread):
    """Collects the streamed datagrams; starts ``then`` on the first (the run listens by then)."""

    def __init__(self, then: threading.Thread) -> None:
        super().__init__(daemon=True)
        self.then = then
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.5)
        self.port = self.sock.getsockname()[1]
        self.received: list = []
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.is_set():
            try:
                self.received.append(decode(self.sock.recv(65535)))
                if len(self.received) == 1:
                    self.then.start()
            except socket.timeout:
                pass
        self.sock.close()


@pytest.fixture(scope="module")
def live_run(build_fmu_from_src, tmp_path_factory):
    """The live run: its scenario, its results file and what it streamed out."""
    tmp_path = tmp_path_factory.mktemp("udp_live")
    port = _free_port()
    listener = _Listener(_Sender(port))
    slow = _Listener(threading.Thread())
    listener.start()
    slow.start()
    scenario = _scenario(tmp_path, build_fmu_from_src("oscillator.py"), port, listener.port, slow.port)
    out = tmp_path / "live.csv"
    records: list = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record.getMessage())

    handler = Keep()
    logging.getLogger("deltafmi.scenario").addHandler(handler)
    try:
        result = deltafmi.simulate(scenario, output=out)
    finally:
        logging.getLogger("deltafmi.scenario").removeHandler(handler)
        time.sleep(0.1)
        listener.done.set()
        slow.done.set()
        listener.join()
        slow.join()
    return scenario, out, result, listener.received, records, slow.received


def test_the_received_force_drives_the_physics(live_run):
    """x, v follow the closed form under the recorded force held over each step (CVODE at rtol
    1e-10); the force took the values sent, and the first value is the start value."""
    _, _, result, _, _, _ = live_run
    force = result["cmd.F"]
    assert force[0] == 0.5
    sent = {1.0 + n / 10 for n in range(40)} | {1.55}
    taken = set(np.unique(force[1:]).tolist()) - {0.5}
    assert taken and taken <= sent and -99.0 not in taken
    assert len(taken) >= 10  # about 25 datagrams over 0.25 s; most reach a step of their own
    x, v = 1.0, 0.0
    xs, vs = [x], [v]
    for k in range(len(result.time) - 1):
        x, v = _free(x, v, float(force[k]), STEP, {**P, "wall": -10.0})
        xs.append(x)
        vs.append(v)
    assert np.max(np.abs(np.array(xs) - result["osc.x"])) < 1e-7
    assert np.max(np.abs(np.array(vs) - result["osc.v"])) < 1e-6


def test_bad_and_missing_datagrams_are_counted_and_reported(live_run):
    """The garbage is malformed, the old datagram stale, the undeclared name unknown (its
    datagram's F used); the silence after the sender stops is reported and F holds."""
    _, _, result, _, messages, _ = live_run
    counts = result.summary.live.sources[0]
    assert counts.startswith("cmd: ") and "1 malformed" in counts and "1 stale" in counts and "1 unknown" in counts
    assert "silent 1 time" in counts
    assert any("version 2 (this deltafmi reads 1)" in m for m in messages), messages
    assert any(m.startswith("live input 'cmd': nothing received for ") and "holding F = " in m for m in messages)
    last_change = np.flatnonzero(np.diff(result["cmd.F"]))[-1] + 1
    assert result.time[last_change] < 0.45 and result["cmd.F"][-1] == result["cmd.F"][last_change]
    assert 1.55 in result["cmd.F"]


def test_the_stream_carries_the_recorded_values(live_run):
    """One datagram per communication point, in order, each the row of its time bit for bit."""
    _, _, result, received, _, _ = live_run
    assert len(received) == len(result.time)
    times = np.array([d.t for d in received])
    assert np.array_equal(times, result.time)
    assert [d.seq for d in received] == list(range(len(received)))
    assert np.array_equal([d.values["osc.x"] for d in received], result["osc.x"])
    assert np.array_equal([d.values["cmd.F"] for d in received], result["cmd.F"])


def test_a_stream_at_a_rate_sends_at_its_times_without_drift(live_run):
    """rate: 30 on a 1 ms grid: the first point at or after each n / 30 s (never two in one
    period, none skipped: no interval added up), and the run's last point."""
    _, _, result, _, _, slow = live_run
    times = np.array([d.t for d in slow])
    grid = result.time
    expected = [grid[0]] + [grid[np.searchsorted(grid, n / 30 - 1e-12)] for n in range(1, int(0.6 * 30) + 1)]
    expected = sorted(set(expected) | {grid[-1]})
    assert times.tolist() == expected
    assert np.array_equal([d.values["osc.x"] for d in slow], result["osc.x"][np.searchsorted(grid, times)])


def test_a_stream_that_cannot_start_leaves_the_earlier_results(build_fmu_from_src, tmp_path):
    """The streams connect before the result file is opened: a bad target fails the run with
    the earlier file as it was."""
    out = tmp_path / "earlier.csv"
    out.write_text("time,x\n0,1\n1,2\n")
    path = tmp_path / "bad_stream.yaml"
    path.write_text(f"""\
experiment: {{stop: 0.01, step: 1.0e-3}}
live:
  cmd: {{udp: {{port: {_free_port()}}}, signals: {{F: {{}}}}}}
components:
  osc: {{fmu: {build_fmu_from_src('oscillator.py')}, interface: CS}}
connections:
  - {{from: cmd.F, to: osc.F}}
streams:
  - {{udp: 'no-such-host.invalid:9', signals: [osc.x]}}
""")
    outcome = CliRunner().invoke(main, ["run", str(path), "-o", str(out)])
    assert outcome.exit_code == 2 and "Traceback" not in outcome.output
    assert "no-such-host.invalid" in outcome.output
    assert out.read_text() == "time,x\n0,1\n1,2\n"


def test_replay_repeats_the_run_bit_for_bit(live_run, tmp_path):
    """--replay takes the inputs from the results: no datagram, no clock, the same numbers."""
    scenario, out, result, _, _, _ = live_run
    again = tmp_path / "again.csv"
    outcome = CliRunner().invoke(main, ["run", str(scenario), "--replay", str(out), "-o", str(again)])
    assert outcome.exit_code == 0, outcome.output
    assert "cmd: " in outcome.output and "replayed" in outcome.output
    replayed = read_result(again)
    original = read_result(out)
    kept = [n for n in original.names if not n.startswith("realtime.")]
    assert replayed.names == kept
    for name in kept:
        assert np.array_equal(replayed[name], original[name]), name
    assert np.array_equal(replayed.time, original.time)


def test_replay_refuses_a_file_of_another_grid(live_run, tmp_path):
    scenario, out, _, _, _, _ = live_run
    outcome = CliRunner().invoke(main, ["run", str(scenario), "--replay", str(out), "--step", "3e-4"])
    assert outcome.exit_code == 2
    assert "no row at t = 0.0003 s" in outcome.output and "Traceback" not in outcome.output
    outcome = CliRunner().invoke(main, ["run", str(scenario), "--replay", str(out), "--stop", "0.7",
                                        "-o", str(tmp_path / "long.csv")])
    assert outcome.exit_code == 2 and "no row at t = 0.601 s" in outcome.output


@pytest.mark.parametrize("stop", [0.3, 0.009, 0.0095])
def test_replay_of_a_shorter_run_takes_the_rows_up_to_its_stop(live_run, tmp_path, stop):
    """A run stopped early (as Ctrl-C stops a live session) is replayed to where it stopped: its
    last row's time is 9 * 0.001 = 0.009000000000000001 where the replay stops at 0.009; a stop
    between two points replays the rows up to it."""
    scenario, out, result, _, _, _ = live_run
    short = tmp_path / "short.csv"
    first = deltafmi.simulate(scenario, replay=out, stop=stop, output=short)
    again = deltafmi.simulate(scenario, replay=short, stop=stop)
    n = len(first.time)
    assert n == len(again.time) == (int(round(stop / STEP)) + 1 if stop != 0.0095 else 11)
    assert np.array_equal(first["cmd.F"][:10], result["cmd.F"][:10])
    for name in first.names:
        assert np.array_equal(first[name], again[name]), name


def test_a_replay_sends_no_stream_unless_paced(live_run, tmp_path, caplog):
    """A replay at the desk must not drive the live run's device again: its streams stay quiet
    unless the replay is paced."""
    scenario, out, _, _, _, _ = live_run
    with caplog.at_level(logging.WARNING, logger="deltafmi.scenario"):
        replayed = deltafmi.simulate(scenario, replay=out, stop=0.05)
    assert replayed.summary.live.streams == []
    assert any("the streams are not sent in a replay" in r.getMessage() for r in caplog.records)


def test_packed_doubles_from_a_simulink_style_sender(build_fmu_from_src, tmp_path):
    """format: doubles, big-endian: two values per datagram in the order of signals, no header;
    a datagram of the wrong length is malformed. Unpaced (as fast as it goes) the run still
    takes what has arrived at each point."""
    port = _free_port()
    path = tmp_path / "doubles.yaml"
    path.write_text(f"""\
experiment: {{stop: 0.05, step: 1.0e-3}}
live:
  cmd:
    udp: {{port: {port}, format: doubles, byte_order: big}}
    signals: {{F: {{}}, G: {{}}}}
components:
  osc: {{fmu: {build_fmu_from_src('oscillator.py')}, interface: CS}}
connections:
  - {{from: cmd.F, to: osc.F}}
""")
    scenario = deltafmi.load_scenario(path)
    from deltafmi import resolve_system
    from deltafmi.master.stepping.master import Master

    master = Master(resolve_system(scenario), result=tmp_path / "d.csv")
    master.open()
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.sendto(struct.pack(">dd", 3.25, -1.5), ("127.0.0.1", port))
            sock.sendto(struct.pack(">d", 7.0), ("127.0.0.1", port))  # one value short
        time.sleep(0.05)
        master.step_all(master.stepping_blocks(), 0.0, 1e-3)
        master.live.at_point(1e-3, None)
        unit = master._by_name["cmd"]
        assert unit.values.tolist() == [3.25, -1.5]
        assert unit.source.counters()["malformed"] == 1
    finally:
        master.close()


def _without_streams(scenario: Path, tmp_path: Path) -> Path:
    text = scenario.read_text()
    path = tmp_path / "udp_live_no_streams.yaml"
    path.write_text(text[:text.index("streams:")])
    return path


def _spy_on_c_pacing(monkeypatch) -> list:
    """The speeds of the runs paced by the master's C loop (NativeLoop.pace, which still runs)."""
    from deltafmi.master.stepping.c_loop import NativeLoop

    paced, pace = [], NativeLoop.pace
    monkeypatch.setattr(NativeLoop, "pace", lambda loop, pacer, *rest: (paced.append(pacer.speed),
                                                                       pace(loop, pacer, *rest)))
    return paced


def test_a_paced_replay_without_streams_steps_in_c_and_repeats_the_run(live_run, tmp_path, monkeypatch):
    """Paced and without streams, a replay runs on the C loop, which hands back at every point
    for the replayed inputs: the numbers of the live run (stepped in Python for its streams)."""
    scenario, out, _, _, _, _ = live_run
    paced = _spy_on_c_pacing(monkeypatch)
    again = tmp_path / "again.csv"
    outcome = CliRunner().invoke(main, ["run", str(_without_streams(scenario, tmp_path)), "--replay", str(out),
                                        "--speed", "20", "-o", str(again)])
    assert outcome.exit_code == 0, outcome.output
    assert paced == [20.0]
    replayed, original = read_result(again), read_result(out)
    for name in [n for n in original.names if not n.startswith("realtime.")]:
        assert np.array_equal(replayed[name], original[name]), name


def test_live_sources_are_sampled_between_the_c_loops_calls(build_fmu_from_src, tmp_path, monkeypatch):
    """At 4x without streams the C loop steps 4 points a call (a millisecond of wall time) and the
    source is sampled in between: the force takes values sent, and x, v follow the closed form
    under the recorded force held over each step."""
    port = _free_port()
    scenario = _without_streams(_scenario(tmp_path, build_fmu_from_src("oscillator.py"), port, _free_port(),
                                          _free_port()), tmp_path)
    paced = _spy_on_c_pacing(monkeypatch)
    done = threading.Event()

    def send() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            n = 0
            while not done.is_set():
                sock.sendto(encode({"F": 1.0 + n / 10}, t=n * 0.01, seq=n), ("127.0.0.1", port))
                n += 1
                time.sleep(0.005)

    sender = threading.Thread(target=send, daemon=True)
    sender.start()
    try:
        result = deltafmi.simulate(scenario, speed=4.0, output=tmp_path / "fast.csv")
    finally:
        done.set()
        sender.join()
    assert paced == [4.0]
    force = result["cmd.F"]
    taken = set(np.unique(force[1:]).tolist()) - {0.5}
    assert taken and all(round((f - 1.0) * 10, 9) == round((f - 1.0) * 10) for f in taken)
    x, v = 1.0, 0.0
    xs, vs = [x], [v]
    for k in range(len(result.time) - 1):
        x, v = _free(x, v, float(force[k]), STEP, {**P, "wall": -10.0})
        xs.append(x)
        vs.append(v)
    assert np.max(np.abs(np.array(xs) - result["osc.x"])) < 1e-7
    assert np.max(np.abs(np.array(vs) - result["osc.v"])) < 1e-6


def test_udp_inputs_read_by_the_c_loop_reach_the_plant_at_the_points_they_arrived_before(
        build_fmu_from_src, tmp_path, monkeypatch):
    """At 50x (20 us paced steps) a UDP source on IPv4 is read by the C loop between its steps:
    the run is one call of the C loop, handing back to Python only for the datagrams Python must
    read (every 40th datagram, a malformed one, a stale one and one with an undeclared name), which are counted as a Python-read run counts them. Datagram n carries F = 1 + n / 1000, sent every
    millisecond of wall time by another thread with the wall time just before and just after
    sendto (loopback: in the socket when sendto returns). A value first recorded at point k was
    sent before the point after k was released (the source is read right after a point's
    release, before the next step) and not yet in the socket when point k - 1 was read (else
    point k - 1 would have taken it): sent_before < release[k + 1] and sent_after > release[k - 1],
    with the releases from the pacer's clock (``wall0``) and each point's recorded lateness. The
    oscillator's x and v follow the closed form under the recorded force held over each step:
    the plant got each value at the step whose row shows it."""
    from deltafmi.master.stepping.c_loop import NativeLoop

    port = _free_port()
    scenario = _without_streams(_scenario(tmp_path, build_fmu_from_src("oscillator.py"), port, _free_port(),
                                          _free_port()), tmp_path)
    readers, calls = [], []
    pace, run_streamed = NativeLoop.pace, NativeLoop.run_streamed
    monkeypatch.setattr(NativeLoop, "pace", lambda loop, pacer, slots, found=None: (readers.append(found),
                                                                                    pace(loop, pacer, slots, found)))
    monkeypatch.setattr(NativeLoop, "run_streamed", lambda loop, *args, **kw: (calls.append(args[0]),
                                                                               run_streamed(loop, *args, **kw))[1])
    done = threading.Event()
    sent: dict = {}

    def send() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            n = 0
            while not done.is_set():
                n += 1
                before = time.perf_counter()
                sock.sendto(encode({"F": 1.0 + n / 1000}, t=n * 1e-3, seq=n), ("127.0.0.1", port))
                sent[n] = (before, time.perf_counter())
                if n % 40 == 0:  # for Python to read: malformed, stale, an undeclared name
                    sock.sendto(b"DFMI\x02\x01" + bytes(14), ("127.0.0.1", port))
                    sock.sendto(encode({"F": -99.0}, t=0.0, seq=n - 1), ("127.0.0.1", port))
                    sock.sendto(encode({"F": 1.0 + n / 1000, "nope": 1.0}, t=n * 1e-3, seq=n), ("127.0.0.1", port))
                time.sleep(1e-3)

    sender = threading.Thread(target=send, daemon=True)
    sender.start()
    try:
        result = deltafmi.simulate(scenario, speed=50.0, stop=15.0, output=tmp_path / "fifty.csv")
    finally:
        done.set()
        sender.join()
    assert len(readers) == 1 and readers[0] is not None  # read in C
    report = result.summary.live.realtime
    assert report.speed == 50.0 and len(report.lateness) == 15000
    counts = readers[0].readers[0].source.counters()
    # sent in this order: the run may end between two of a trio
    assert counts["malformed"] >= counts["stale"] >= counts["unknown"] >= max(1, counts["malformed"] - 1), counts
    c_counts = readers[0].readers[0].counters()
    # most in C (Python reads what arrived before the paced run and at each hand-back): one call of
    # the C loop, and one more after each hand-back (about one for each trio of datagrams Python
    # must read: they come within microseconds)
    assert c_counts["accepted"] >= 50 and c_counts["accepted"] > counts["accepted"] / 2, (c_counts, counts)
    assert 1 <= len(calls) <= 3 * counts["malformed"] + 3, (len(calls), counts)
    force = result["cmd.F"]
    times = result.time
    release = report.wall0 + (times - report.t0) / report.speed
    release[1:] += result["realtime.lateness"][1:]
    first = {}
    for k in range(1, len(force)):
        n = round((float(force[k]) - 1.0) * 1000)
        if force[k] != force[k - 1] and n in sent and n not in first:
            first[n] = k
    assert len(first) >= 50
    for n, k in first.items():
        before, after = sent[n]
        if k + 1 < len(release):
            assert before < release[k + 1], (n, k)
        assert after > release[k - 1], (n, k)
    x, v = 1.0, 0.0
    xs, vs = [x], [v]
    for k in range(len(times) - 1):
        x, v = _free(x, v, float(force[k]), STEP, {**P, "wall": -10.0})
        xs.append(x)
        vs.append(v)
    assert np.max(np.abs(np.array(xs) - result["osc.x"])) < 1e-7
    assert np.max(np.abs(np.array(vs) - result["osc.v"])) < 1e-6
