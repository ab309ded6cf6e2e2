"""Pacing to the wall clock (``deltafmi run --realtime``, ``simulate(realtime=True)``).

The lower bounds are the pacing's promise (a point is never released before its time), so they
are asserted exactly; the upper bounds only have to hold on a loaded two-core machine: the tight
figures are in benchmarks/realtime.py.
"""
from __future__ import annotations

import logging
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import deltafmi
from deltafmi.master.results.csv_file import columns
from deltafmi.errors import BadInput
from signal_runs import DELTAFMI, interrupt_when, rows_in


def test_paced_run_takes_its_simulated_time_and_changes_no_number(monkeypatch):
    """0.3 s of the flagship at real time takes at least 0.3 s of stepping, and at 3x at least
    0.1 s; every value is bit for bit the unpaced run's (both step in the C loop, the paced one
    waiting there for every point: the same FMI calls)."""
    from deltafmi.master.stepping.c_loop import NativeLoop

    paced_in_c = []
    pace = NativeLoop.pace
    monkeypatch.setattr(NativeLoop, "pace", lambda loop, pacer, *rest: (paced_in_c.append(pacer.speed),
                                                                       pace(loop, pacer, *rest)))
    plain = deltafmi.simulate("delta_tracking", stop=0.3)
    paced = deltafmi.simulate("delta_tracking", stop=0.3, realtime=True)
    fast = deltafmi.simulate("delta_tracking", stop=0.3, speed=3.0)
    assert paced_in_c == [1.0, 3.0]
    for result, least in ((paced, 0.3), (fast, 0.1)):
        assert result.summary.stepping_time >= least
        assert result.summary.stepping_time < least + 5.0  # generous: a loaded machine
        for name in plain.names:
            assert np.array_equal(result[name], plain[name]), name
        lateness = result["realtime.lateness"]
        assert lateness[0] == 0 and (lateness >= 0).all()
        assert len(lateness) == len(plain.time) == 301
        report = result.summary.live.realtime
        assert len(report.lateness) == 300 and np.array_equal(report.lateness, lateness[1:])
    assert paced.summary.live.realtime.speed == 1.0 and fast.summary.live.realtime.speed == 3.0
    assert "realtime.lateness" not in plain.names and plain.summary.live is None
    text = str(paced.summary)
    assert re.search(r"real time at 1x: lateness median [\d.]+ us, 99th percentile [\d.]+ (us|ms), max", text), text


def test_falling_behind_warns_and_goes_on_or_stops_with_the_rows_kept(tmp_path, caplog):
    """At 1000x the flagship's 1 ms step has 1 us of wall time: the run falls behind at once.
    behind=warn: one warning per episode, the episodes in the summary, realtime.behind = 1 where
    the run was a step late; behind=error: a SimulationError, and the rows up to there on disk."""
    with caplog.at_level(logging.WARNING, logger="deltafmi.scenario"):
        result = deltafmi.simulate("delta_tracking", stop=0.05, speed=1000.0)
    warnings = [r.getMessage() for r in caplog.records if "fell behind real time" in r.getMessage()]
    report = result.summary.live.realtime
    assert len(warnings) == len(report.behind) >= 1
    assert warnings[0].startswith("fell behind real time at t = ") and warnings[0].endswith("; going on")
    behind = result["realtime.behind"]
    late = result["realtime.lateness"] > 1e-3 / 1000
    assert np.array_equal(behind == 1.0, late) and behind.sum() > 0
    assert "fell behind" in str(result.summary)



def test_falling_behind_as_an_error_stops_the_run_with_its_rows(tmp_path):
    """--behind error: exit 1 with a one-line reason, and the rows up to there on disk."""
    from click.testing import CliRunner
    from deltafmi.apps.cli import main

    out = tmp_path / "behind.csv"
    outcome = CliRunner().invoke(main, ["run", "delta_tracking", "--stop", "0.05", "--speed", "1000",
                                        "--behind", "error", "-o", str(out), "-q"])
    assert outcome.exit_code == 1, outcome.output
    assert "Traceback" not in outcome.output
    message = outcome.output.strip().splitlines()[-1]
    assert message.startswith("Error: fell behind real time at t = "), message
    assert f"results up to the failure in {tmp_path / 'behind.failed.csv'}" in message
    kept = columns(tmp_path / "behind.failed.csv")
    assert len(kept["time"]) >= 2 and kept["time"][0] == 0.0


def test_sigterm_stops_a_paced_run_between_points_with_its_rows(tmp_path):
    """A paced run sleeps most of the time: SIGTERM there ends it as it ends an unpaced one
    (exit 143, every row up to there in the file)."""
    out = tmp_path / "paced.csv"
    code, _, stderr = interrupt_when([*DELTAFMI, "run", "delta_tracking", "--realtime", "--speed", "0.5", "-o", str(out)],
                                     lambda: rows_in(out) > 20, signal.SIGTERM)
    assert code == 143, stderr
    assert "Traceback" not in stderr
    assert re.fullmatch(r"interrupted at t = \S+ s \(results up to \S+ in .+\)", stderr.strip().splitlines()[-1])
    kept = columns(out)
    assert kept["time"][-1] < 3.5 and len(kept["time"]) > 20
    assert np.array_equal(kept["time"], np.arange(len(kept["time"])) * 1e-3)


def test_a_stop_signal_ends_a_long_wait_at_once(tmp_path):
    """At 1e-5x a point is due every 100 s: SIGTERM during that wait ends the run then, not at
    the deadline (the bound, half of one wait, holds on a machine slowed down a hundredfold,
    and fails a run that waits the point out). The run streams its first row once the clock
    starts: the signal comes in the wait."""
    import socket

    from deltafmi.shipped import SCENARIOS_DIR

    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", 0))
    listener.settimeout(600)
    scenario = tmp_path / "slow.yaml"
    scenario.write_text((SCENARIOS_DIR / "delta_tracking.yaml").read_text()
                        + f"streams:\n  - {{udp: '127.0.0.1:{listener.getsockname()[1]}', signals: [plant.residual]}}\n")
    process = subprocess.Popen([sys.executable, "-c", "from deltafmi.apps.cli import main; main()", "run",
                                str(scenario), "--speed", "1e-5", "-o", str(tmp_path / "slow.csv")],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        listener.recv(65535)  # the first row: the clock has started
        time.sleep(0.2)
        sent = time.monotonic()
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=600)
        took = time.monotonic() - sent
    finally:
        listener.close()
        if process.poll() is None:
            process.kill()
    assert process.returncode == 143, stderr
    assert took < 50.0, took
    assert "warning: live run up to t = 0.001 s: real time at 1e-05x" in stderr, stderr


def test_pacing_options_are_checked():
    with pytest.raises(BadInput, match=r"real-time speed -1: must be greater than 0"):
        deltafmi.simulate("delta_tracking", stop=0.01, speed=-1)
    with pytest.raises(BadInput, match="no live source to take from it"):
        deltafmi.simulate("delta_tracking", stop=0.01, replay=Path(__file__))


def test_points_released_in_c_make_the_episodes_one_by_one_would():
    """The C loop's points, noted at once (Pacer.note_released, which looks only at where the run
    falls behind or catches up), give the episodes and warnings of the same points noted one at
    a time, whatever pieces a run hands back."""
    from deltafmi.master.live.pacing import Pacer

    rng = np.random.default_rng(7)
    period = 1e-3 / 50.0
    for trial in range(40):
        n = int(rng.integers(1, 400))
        lateness = np.where(rng.random(n) < rng.choice([0.02, 0.3, 0.9]), rng.uniform(period, 5 * period, n),
                            rng.uniform(0.0, period, n))
        lateness[rng.random(n) < 0.05] = period  # a whole step exactly: not behind
        times = np.arange(1, n + 1) * 1e-3
        warned: list = [[], []]
        at_once, one_by_one = (Pacer(50.0, 1e-3, n, warn=warned[i].append, behind="error" if trial % 2 else "warn")
                               for i in range(2))
        cuts = sorted({0, n, *rng.integers(0, n, 3).tolist()})
        for a, b in zip(cuts, cuts[1:]):
            at_once.note_released(times[a:b], lateness[a:b])
        for t, late in zip(times.tolist(), lateness.tolist()):
            one_by_one._episode(t, late)
        assert at_once.report().behind == one_by_one.report().behind and warned[0] == warned[1]
        assert str(at_once.failure) == str(one_by_one.failure)


def _status(field: str) -> int:
    return int(re.search(rf"{field}:\s*([0-9a-f]+)", Path("/proc/self/status").read_text()).group(1), 16 if
               field.startswith("Cap") else 10)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl and mlockall are Linux's")
def test_the_pacer_gives_back_the_timer_slack_and_memory_lock_it_took():
    """While paced, the thread's timer slack is 1 ns; the process's memory is locked only where
    locking without limit is permitted (CAP_IPC_LOCK or RLIMIT_MEMLOCK unlimited), and both are
    as they were after close(); a lock the program made itself stays untouched."""
    import ctypes
    import resource

    from deltafmi.master.live.pacing import Pacer

    libc = ctypes.CDLL("libc.so.6", use_errno=True)
    slack = libc.prctl(30, 0, 0, 0, 0)  # PR_GET_TIMERSLACK
    permitted = bool(_status("CapEff") >> 14 & 1) or \
        resource.getrlimit(resource.RLIMIT_MEMLOCK)[0] == resource.RLIM_INFINITY
    assert _status("VmLck") == 0
    pacer = Pacer(1.0, 1e-3, 10)
    pacer.start(0.0)
    try:
        assert libc.prctl(30, 0, 0, 0, 0) == 1
        assert pacer.locked == permitted and (_status("VmLck") > 0) == permitted
        for k in range(1, 11):
            pacer.wait(k * 1e-3)
    finally:
        pacer.close()
    assert libc.prctl(30, 0, 0, 0, 0) == slack and _status("VmLck") == 0
    report = pacer.report()
    assert report.locked == permitted and len(report.lateness) == 10
    # one thread: its CPU time cannot exceed the wall time (the CPU clock is read first, a few
    # microseconds before the wall clock starts); a wait on time ends polling (a late point polls not at all)
    assert 0 < report.cpu <= report.wall + 1e-4 and 0 <= report.polled <= report.wall
    if permitted:
        assert libc.mlockall(1 | 4) == 0  # MCL_CURRENT | MCL_ONFAULT: the program's own lock
        try:
            other = Pacer(1.0, 1e-3, 1)
            other.start(0.0)
            other.close()
            assert not other.locked and _status("VmLck") > 0
        finally:
            libc.munlockall()


def test_a_paced_run_in_c_reports_its_cpu_and_polling():
    """The C loop adds up its thread's CPU time, its wall time and its polling (the thread's CPU
    time cannot exceed its wall time)."""
    result = deltafmi.simulate("delta_tracking", stop=0.2, speed=50.0)
    report = result.summary.live.realtime
    assert 0 <= report.polled <= report.wall and 0 < report.cpu <= report.wall + 1e-6
    # no point more than the lead (0.5 ms at 50x) before its time: the run waits at least the 4 ms
    # of the 200 points less the lead
    assert report.lead == 5e-4
    assert report.wall >= 0.2 / 50 - report.lead - 1e-9
    assert _status("VmLck") == 0  # given back


@pytest.mark.parametrize("lead", [None, 2e-3, 0.0])
def test_a_lead_releases_points_early_by_at_most_the_lead_and_changes_no_number(lead):
    """At 50x (a 20 us paced step: finer than 0.1 ms) the default lead is 0.5 ms: a point due
    within the lead goes out at once, one due later is waited for until half the lead is left,
    so no point is released more than the lead before its time, and a run of 200 points (4 ms)
    with a 2 ms lead releases some points more than 1 ms early; lead 0 releases none early.
    The values are the unpaced run's bit for bit."""
    from dataclasses import replace

    scenario = deltafmi.load_scenario("delta_tracking")
    scenario = replace(scenario, master=replace(scenario.master, realtime=replace(scenario.master.realtime,
                                                                                  lead=lead)))
    plain = deltafmi.simulate("delta_tracking", stop=0.2)
    paced = deltafmi.simulate(scenario, stop=0.2, speed=50.0)
    report = paced.summary.live.realtime
    expected = 5e-4 if lead is None else lead
    assert report.lead == expected and report.tolerance == 5e-6
    assert report.lateness.min() >= -expected - 1e-12
    assert np.array_equal(report.lateness, paced["realtime.lateness"][1:])
    if expected == 0:
        assert report.lateness.min() >= 0
    elif expected > 1e-3:
        assert report.lateness.min() < -1e-3  # steps of 2.5 us: the run is ahead by more than half the lead
        assert re.search(r"released up to [\d.]+ (us|ms) early \(lead 2000.0 us\)", str(report)), str(report)
    for name in plain.names:
        assert np.array_equal(paced[name], plain[name]), name


@pytest.mark.parametrize("speed", [3.0, 1000.0])
def test_a_paced_run_streams_its_rows_through_a_small_ring_unchanged(monkeypatch, caplog, speed):
    """A paced run without live sources steps in one call of the C loop while this thread takes
    its rows: through a ring of 64 rows for 300 points (at 1000x the loop, a whole step behind
    at once, fills the ring and waits for room), every row of the unpaced run comes out, in
    order, bit for bit, and every point's lateness is noted."""
    from deltafmi.master.stepping import master

    monkeypatch.setattr(master, "_C_ROWS_BYTES", 1)  # the smallest block: 64 rows
    caplog.set_level(logging.ERROR, logger="deltafmi.scenario")  # back as it was after the test
    plain = deltafmi.simulate("delta_tracking", stop=0.3)
    paced = deltafmi.simulate("delta_tracking", stop=0.3, speed=speed)
    assert len(paced.time) == 301 and len(paced.summary.live.realtime.lateness) == 300
    for name in plain.names:
        assert np.array_equal(paced[name], plain[name]), name
    if speed > 100:  # a 1 us paced step: shorter than one step's computing
        assert (paced["realtime.behind"][1:] == 1).any() and paced.summary.live.realtime.behind


def test_points_handed_back_one_at_a_time_make_the_episodes_of_their_lateness(tmp_path, caplog):
    """With a live source the C loop hands back at every point, which is noted without arrays:
    at 2000x (0.5 us per step: behind from the first point, caught up now and then) the run's
    episodes are those of its recorded lateness noted one point at a time."""
    import socket

    from deltafmi.master.live.pacing import Pacer

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    scenario = tmp_path / "live.yaml"
    scenario.write_text(f"""\
experiment: {{stop: 0.3, step: 1.0e-3}}
master: {{realtime: true}}
live:
  cmd:
    udp: {{port: {port}}}
    timeout: 100.0
    signals: {{x: {{}}}}
components:
  osc: {{source: 'deltafmi.models:Oscillator', interface: CS}}
connections:
  - {{from: cmd.x, to: osc.F}}
outputs: [osc.x]
""")
    caplog.set_level(logging.ERROR, logger="deltafmi.scenario")  # back as it was after the test
    result = deltafmi.simulate(scenario, speed=2000.0)
    report = result.summary.live.realtime
    assert len(report.lateness) == 300 and np.array_equal(report.lateness, result["realtime.lateness"][1:])
    one_by_one = Pacer(2000.0, 1e-3, 300)
    for t, late in zip(result.time[1:].tolist(), report.lateness.tolist()):
        one_by_one._episode(t, late)
    assert report.behind and report.behind == one_by_one.report().behind


@pytest.mark.skipif(not Path(f"/proc/{__import__('os').getpid()}/timerslack_ns").exists(),
                    reason="/proc/<tid>/timerslack_ns is Linux's (4.6 on)")
def test_the_thread_that_paces_a_streamed_run_has_the_least_timer_slack(monkeypatch):
    """A paced run without live sources steps on a thread of its own (NativeLoop.run_streamed),
    made after the pacer set the slack: it paces with 1 ns, and this thread has its own back."""
    import threading

    from deltafmi.master.stepping import master

    def slack(thread_id: int) -> int:
        return int(Path(f"/proc/{thread_id}/timerslack_ns").read_text())

    before, seen = slack(threading.get_native_id()), []
    take = master.Master._take_rows

    def looking(self, rows):
        seen.extend(slack(t.native_id) for t in threading.enumerate() if t.name == "deltafmi-paced-steps")
        take(self, rows)

    monkeypatch.setattr(master.Master, "_take_rows", looking)
    deltafmi.simulate("delta_tracking", stop=0.2, speed=1.0)
    assert seen and set(seen) == {1}
    assert slack(threading.get_native_id()) == before


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setscheduler"), reason="real-time priorities are Linux's")
def test_a_run_paced_at_a_real_time_priority_steps_at_it_and_gives_it_back(tmp_path, monkeypatch):
    """master.realtime.priority: the thread that paces (here the streamed run's own) is SCHED_FIFO
    at that priority while it steps (where this process may raise it), the calling thread's
    scheduling is as before afterwards; a priority out of 1-99 is refused."""
    import os
    import threading

    from deltafmi.master.stepping import master

    source = Path(deltafmi.__file__).resolve().parent.parent / "scenarios" / "delta_tracking.yaml"
    text = source.read_text().replace("master:\n", "master:\n  realtime: {priority: 10}\n", 1)
    assert "priority: 10" in text
    scenario = tmp_path / "delta_tracking.yaml"
    scenario.write_text(text)
    before, seen = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority), []
    take = master.Master._take_rows

    def looking(self, rows):
        seen.extend((os.sched_getscheduler(t.native_id), os.sched_getparam(t.native_id).sched_priority)
                    for t in threading.enumerate() if t.name == "deltafmi-paced-steps")
        take(self, rows)

    monkeypatch.setattr(master.Master, "_take_rows", looking)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))
        os.sched_setscheduler(0, *before[:1], os.sched_param(before[1]))
        permitted = True
    except PermissionError:
        permitted = False
    result = deltafmi.simulate(scenario, stop=0.2)
    assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before
    assert len(result.time) == 201
    if permitted:
        assert seen and set(seen) == {(os.SCHED_FIFO, 10)}
    with pytest.raises(deltafmi.ScenarioError, match=r"bad.yaml:\d+: error: master.realtime: .*'priority': 100"):
        bad = tmp_path / "bad.yaml"
        bad.write_text(text.replace("priority: 10", "priority: 100"))
        deltafmi.simulate(bad, stop=0.01)


def test_two_stop_signals_stop_a_streamed_run_where_its_rows_end():
    """SIGTERM twice, close together, while a streamed paced run goes: the run is interrupted
    (the second signal where this thread waits for the stepping thread), the stepping thread has
    stopped before the run is closed, and the time the run says it stopped at is its last row's."""
    import os
    import threading

    def twice() -> None:  # once the run steps (its stop signals caught), not before
        while not any(t.name == "deltafmi-paced-steps" for t in threading.enumerate()):
            time.sleep(0.01)
        time.sleep(0.3)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.001)
        os.kill(os.getpid(), signal.SIGTERM)

    killer = threading.Thread(target=twice)
    killer.start()
    try:
        with pytest.raises(deltafmi.Interrupted) as caught:
            deltafmi.simulate("delta_tracking", stop=20.0, speed=1.0)
    finally:
        killer.join()
    assert not any(t.name == "deltafmi-paced-steps" for t in threading.enumerate())
    result = caught.value.result
    said = float(re.search(r"interrupted at t = ([\d.]+) s", str(caught.value)).group(1))
    assert 0 < said == result.time[-1] and len(result.time) == round(said / 1e-3) + 1


def test_the_python_pacer_keeps_the_same_lead():
    """The Pacer (the Python loop's, with streams) waits as the C loop does with a lead: a point
    due within the lead goes out at once, one due later at half the lead before its time (or
    later), never earlier than the lead; 40 points of 1 ms with a 4 ms lead take at least 36 ms."""
    import time

    from deltafmi.master.live.pacing import Pacer

    pacer = Pacer(1.0, 1e-3, 40, lead=4e-3)
    assert pacer.spin == 0.0 and pacer.lead == 4e-3
    pacer.start(0.0)
    begin = time.perf_counter()
    try:
        late = [pacer.wait(k * 1e-3) for k in range(1, 41)]
    finally:
        pacer.close()
    wall = time.perf_counter() - begin
    assert min(late) >= -4e-3 - 1e-12 and wall >= 40e-3 - 4e-3
    assert late[0] < -0.9e-3  # due 1 ms ahead, within the lead: at once
    report = pacer.report()
    assert report.lead == 4e-3 and np.array_equal(report.lateness, np.array(late))
    # no lead by default at 1 ms paced steps: never before its time
    assert Pacer(1.0, 1e-3, 1).lead == 0.0 and Pacer(1.0, 1e-3, 1).spin == 5e-5
    assert Pacer(50.0, 1e-3, 1).lead == 5e-4 and Pacer(50.0, 1e-3, 1).spin == 0.0
