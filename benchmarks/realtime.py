"""Issue 28's figures: how well a paced run keeps the wall clock, and UDP round trips through a run.

- Lateness of the flagship (scenarios/delta_tracking.yaml, 1 kHz) paced at real time:
  median, 99th percentile and largest lateness of its communication points, overruns (later than a
  quarter step), times it fell behind; and the wall time one step computes ("busy"). Medians over
  ``--repeats`` runs of ``--seconds`` simulated seconds.
- The highest speed-up at which it still keeps up: paced runs of 1 simulated second at rising
  speeds (doubling, then bisecting), "keeps up" = at most 1 % of the points overrun. Against the baseline measured in the same run: the speed the busy time
  allows (step / median busy), and the unpaced run's real-time factor (both on the master's C
  loop: a paced run without streams waits for every point in C).
- The flagship at ``--target-speed`` (default 50x) over ``--seconds``, ``--repeats`` times: overruns
  and times it fell behind (target: never behind, at most 1 % of the points overrun); and the
  busy time per point (computing, not waiting) of the C loop against the Python loop paced the
  same way (``LiveRun.paced_in_c`` off), in the same run: on a loaded machine, where other
  processes' turns make points late, the busy time against the paced step says whether a run
  can keep up.
- The machine's floor at ``--target-speed``, measured beside each of those runs: a C loop paced
  exactly as the master's (benchmarks/native/paced_floor.c) around a step that only spends the
  flagship's median busy time; what it counts late is the machine's (other processes' turns,
  scheduler ticks, a virtual machine's host), not the master's. The load average is printed
  with it. ``--target-only`` measures this and the line above only.
- UDP round trip: a datagram sent to a live UDP input comes back on a UDP stream of the same
  signal (the run at 1 kHz paced, and unpaced); wall time from sendto to recv, median and 99th
  percentile over ``--pings``. Baseline in the same run: a plain Python echo over loopback (one
  thread receives and sends back), the floor of any round trip through Python sockets.

Usage: python benchmarks/realtime.py [--seconds 3] [--repeats 3] [--pings 300] [--target-only]
"""
from __future__ import annotations

import argparse
import ctypes
import logging
import os
import random
import signal
import socket
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

import deltafmi
from deltafmi.master.live.datagram import decode, encode


def lateness_figures(seconds: float, speed: float = 1.0) -> dict:
    result = deltafmi.simulate("delta_tracking", stop=seconds, speed=speed)
    report = result.summary.live.realtime
    busy = result["realtime.busy"][1:]
    return {"median": report.percentile(50), "p99": report.percentile(99), "max": float(report.lateness.max()),
            "overruns": report.overruns, "behind": len(report.behind), "busy": float(np.median(busy)),
            "points": len(report.lateness)}


def python_loop_busy(seconds: float, speed: float) -> float:
    """Median busy time per point of the same paced run stepped by the master's Python loop."""
    from deltafmi.master.live.run import LiveRun

    paced_in_c = LiveRun.paced_in_c
    LiveRun.paced_in_c = lambda self: False
    try:
        return lateness_figures(seconds, speed)["busy"]
    finally:
        LiveRun.paced_in_c = paced_in_c


def keeps_up(speed: float) -> bool:
    """At most 1 % of the points overrun (a loaded machine's odd stall is not a failure to keep
    up; a step that takes longer than its paced time makes every point late)."""
    figures = lateness_figures(1.0, speed)
    return figures["overruns"] <= 0.01 * figures["points"]


def highest_speed() -> float:
    good, bad, speed = 0.0, None, 1.0
    while bad is None and speed <= 1024:
        if keeps_up(speed):
            good, speed = speed, speed * 2
        else:
            bad = speed
    if bad is None:
        return good
    for _ in range(4):
        middle = (good + bad) / 2
        good, bad = (middle, bad) if keeps_up(middle) else (good, middle)
    return good


class PacedFloor:
    """benchmarks/native/paced_floor.c compiled (``cc -std=c99 -O2``) and loaded."""

    def __init__(self, directory: Path) -> None:
        from deltafmi.toolchain import require_compiler

        source = Path(__file__).resolve().parent / "native" / "paced_floor.c"
        library = directory / "paced_floor.so"
        subprocess.run([*require_compiler(source), "-std=c99", "-O2", "-shared", "-fPIC", str(source), "-o",
                        str(library)], check=True, capture_output=True)
        self._floor = ctypes.CDLL(str(library)).paced_floor
        self._floor.argtypes = [ctypes.c_long, ctypes.c_double, ctypes.c_double, ctypes.c_double,
                                ctypes.POINTER(ctypes.c_long), ctypes.POINTER(ctypes.c_long)]
        self._floor.restype = ctypes.c_double

    def __call__(self, points: int, period: float, busy: float) -> dict:
        """Overruns (later than a quarter period, as the Pacer's tolerance), fell-behind episodes
        and the largest lateness of ``points`` paced points around ``busy`` seconds of work."""
        overruns, behind = ctypes.c_long(), ctypes.c_long()
        worst = self._floor(points, period, busy, period / 4, ctypes.byref(overruns), ctypes.byref(behind))
        return {"overruns": overruns.value, "behind": behind.value, "max": worst, "points": points}


def target_speed(seconds: float, repeats: int, speed: float) -> list:
    """The flagship paced at ``speed`` and, right after each run, the machine's floor with its
    median busy time (:class:`PacedFloor`): (flagship figures, floor figures, load average)."""
    with tempfile.TemporaryDirectory() as folder:
        floor = PacedFloor(Path(folder))
        runs = []
        for _ in range(repeats):
            load = os.getloadavg()[0]
            flagship = lateness_figures(seconds, speed)
            runs.append((flagship, floor(flagship["points"], 1e-3 / speed, flagship["busy"]), load))
    return runs


def print_target(runs: list, speed: float, seconds: float) -> None:
    def share(figures: dict) -> str:
        return f"{figures['overruns']} of {figures['points']} ({figures['overruns'] / figures['points']:.1%})"
    print(f"flagship at {speed:g}x real time, {seconds:g} s, {len(runs)} runs (target: never behind, overruns <= 1 %); "
          f"beside each, the machine's floor (a C loop paced the same way around the same busy time):")
    for flagship, floor, load in runs:
        print(f"  load {load:5.2f}: flagship overruns {share(flagship)}, fell behind {flagship['behind']}, max late "
              f"{_us(flagship['max'])}, busy median {_us(flagship['busy'])} | floor overruns {share(floor)}, fell "
              f"behind {floor['behind']}, max late {_us(floor['max'])}")
    fraction = statistics.median(f["overruns"] / f["points"] for f, _, _ in runs)
    floor_fraction = statistics.median(f["overruns"] / f["points"] for _, f, _ in runs)
    print(f"  medians: overruns flagship {fraction:.2%}, floor {floor_fraction:.2%}; fell behind flagship "
          f"{statistics.median(f['behind'] for f, _, _ in runs):g}, floor {statistics.median(f['behind'] for _, f, _ in runs):g}")


def _echo_scenario(folder: Path, port: int, back: int) -> Path:
    path = folder / "echo.yaml"
    path.write_text(f"""\
experiment: {{stop: 1000.0, step: 1.0e-3}}
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
streams:
  - {{udp: '127.0.0.1:{back}', signals: [cmd.x]}}
""")
    return path


def _ports() -> tuple:
    probes = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2)]
    for probe in probes:
        probe.bind(("127.0.0.1", 0))
    ports = tuple(p.getsockname()[1] for p in probes)
    for probe in probes:
        probe.close()
    return ports


def round_trips(pings: int, paced: bool) -> list:
    """Wall seconds from sending x = n to receiving a stream datagram with x = n, through a
    ``deltafmi run`` in a process of its own (as another program would meet it)."""
    port, back = _ports()
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", back))
    receiver.settimeout(60.0)
    with tempfile.TemporaryDirectory() as folder:
        scenario = _echo_scenario(Path(folder), port, back)
        run = subprocess.Popen([sys.executable, "-c", "from deltafmi.apps.cli import main; main()", "run", str(scenario), "-q",
                                "--realtime" if paced else "--no-realtime", "-o", str(Path(folder) / "echo.csv")],
                               stderr=subprocess.DEVNULL)  # its "interrupted" line: the stop asked for
        try:
            receiver.recv(65535)  # the first row: the run listens
            times = []
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
                for n in range(1, pings + 1):
                    sent = time.perf_counter()
                    sender.sendto(encode({"x": float(n)}, t=float(n), seq=n), ("127.0.0.1", port))
                    while decode(receiver.recv(65535)).values["cmd.x"] != n:
                        pass
                    times.append(time.perf_counter() - sent)
                    time.sleep(0.002 + 0.001 * random.random())  # at every phase of the run's points
        finally:
            run.send_signal(signal.SIGTERM)
            run.wait(60)
    receiver.close()
    return times


def python_echo(pings: int) -> list:
    """The same round trip through a plain Python echo thread."""
    server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    server.bind(("127.0.0.1", 0))
    done = threading.Event()

    def echo() -> None:
        server.settimeout(0.2)
        while not done.is_set():
            try:
                data, sender = server.recvfrom(65535)
                server.sendto(data, sender)
            except socket.timeout:
                pass

    thread = threading.Thread(target=echo, daemon=True)
    thread.start()
    times = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as client:
        for n in range(pings):
            sent = time.perf_counter()
            client.sendto(struct.pack("<d", n), server.getsockname())
            client.recv(64)
            times.append(time.perf_counter() - sent)
    done.set()
    thread.join()
    server.close()
    return times


def _us(seconds: float) -> str:
    return f"{seconds * 1e6:8.1f} us"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--pings", type=int, default=300)
    parser.add_argument("--target-speed", type=float, default=50.0)
    parser.add_argument("--target-only", action="store_true",
                        help="only the flagship at --target-speed and the machine's floor beside it")
    args = parser.parse_args()

    logging.getLogger("deltafmi.scenario").setLevel(logging.ERROR)  # "fell behind" while probing speeds
    deltafmi.simulate("delta_tracking", stop=0.01)  # builds the FMUs once
    if args.target_only:
        print_target(target_speed(args.seconds, args.repeats, args.target_speed), args.target_speed, args.seconds)
        return
    runs = [lateness_figures(args.seconds) for _ in range(args.repeats)]
    med = {key: statistics.median(run[key] for run in runs) for key in runs[0]}
    print(f"flagship at 1 kHz, real time, {args.seconds:g} s x {args.repeats} (medians of the runs):")
    print(f"  lateness median {_us(med['median'])}, 99th percentile {_us(med['p99'])}, max {_us(med['max'])}")
    print(f"  overruns (> 250 us) {med['overruns']:g} of {med['points']:g} points; fell behind {med['behind']:g} times")
    print(f"  busy (one step computing) median {_us(med['busy'])} = {med['busy'] / 1e-3:.1%} of the 1 ms step")

    runs = target_speed(args.seconds, args.repeats, args.target_speed)
    print_target(runs, args.target_speed, args.seconds)
    fast = [flagship for flagship, _, _ in runs]
    python_busy = [python_loop_busy(args.seconds, args.target_speed) for _ in range(args.repeats)]
    c_busy = statistics.median(run["busy"] for run in fast)
    print(f"  busy per point, medians: C loop {_us(c_busy)}, Python loop {_us(statistics.median(python_busy))} "
          f"(paced step {_us(1e-3 / args.target_speed)}); Python / C {statistics.median(python_busy) / c_busy:.1f}x")

    plain = deltafmi.simulate("delta_tracking")
    rtf = plain.summary.simulated / plain.summary.stepping_time
    speed = highest_speed()
    print(f"highest speed that keeps up: {speed:.1f}x real time")
    print(f"  baseline (same run): step / busy = {1e-3 / med['busy']:.1f}x; unpaced real-time factor "
          f"{rtf:.0f}x (C loop); ratio kept-up / busy-allowed = {speed / (1e-3 / med['busy']):.2f}")

    echo = python_echo(args.pings)
    for paced in (True, False):
        trips = round_trips(args.pings, paced)
        label = "paced at 1 kHz" if paced else "unpaced"
        print(f"UDP round trip through a run ({label}): median {_us(statistics.median(trips))}, "
              f"99th percentile {_us(float(np.percentile(trips, 99)))}")
    print(f"  baseline plain Python echo: median {_us(statistics.median(echo))}, "
          f"99th percentile {_us(float(np.percentile(echo, 99)))}")


if __name__ == "__main__":
    main()
