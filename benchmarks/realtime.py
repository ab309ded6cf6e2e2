"""How well a paced run keeps the wall clock, and UDP round trips through a run.

- The highest speed-up at which it still keeps up: paced runs of 1 simulated second at rising
  speeds (doubling, then bisecting), "keeps up" = at most 1 % of the points overrun. Against the baseline measured in the same run: the speed the busy time
  allows (step / median busy), and the unpaced run's real-time factor (both on the master's C
  loop: a paced run without streams waits for every point in C).
- The paced flagship beside the machine's floor, interleaved, ``--repeats`` times: the flagship
  at 50x (``--seconds-fast`` simulated seconds) and 1x (``--seconds-real``) on the master's C loop,
  as it paces by default (at 50x a lead of 0.5 ms, sleeping; at 1x a deadline per step, sleeping
  then polling 50 us) and at 50x with a deadline per step (lead 0, polling: the pacing before the
  lead), at 1x sleeping only and polling 200 us (the default before) too; beside benchmarks/native/paced_floor.c, a bare C program pacing
  as many points around the flagship's median busy time, waiting each of those ways (and at 1x
  by polling only, by sleeping then polling the last 50 us). For each: overruns (later than a
  quarter step, the Pacer's tolerance), the shares later than 1 us, half and a whole step,
  fell-behind episodes, median, 99th percentile and largest lateness, the largest earliness (a
  lead's price), and CPU time over wall time; medians over the repeats, the load average beside
  them; whether the flagship meets the 50x target (never behind, overruns <= 1 %) and whether
  the floor does at the same moments. ``--fifo``: both at real-time priority 50 too (the
  flagship with ``master.realtime.priority: 50``, the floor under ``chrt -f 50``: root).
  ``--target-only`` measures this only. Also the busy time per point of the C loop against the
  Python loop paced the same way (``LiveRun.paced_in_c`` off).
- A UDP live input at 50x: the Oscillator paced with a datagram sent to it every millisecond of
  wall time, its source read by the C loop between steps and, as the baseline in the same run,
  sampled in Python at every point (the C loop handing back at each): overruns, fell-behind,
  lateness, busy time, values taken (``--udp-only`` measures this only).
- UDP round trip: a datagram sent to a live UDP input comes back on a UDP stream of the same
  signal (the run at 1 kHz paced, and unpaced); wall time from sendto to recv, median and 99th
  percentile over ``--pings``. Baseline in the same run: a plain Python echo over loopback (one
  thread receives and sends back), the floor of any round trip through Python sockets.

Usage: python benchmarks/realtime.py [--seconds 3] [--repeats 3] [--pings 300] [--target-only] [--fifo] [--udp-only]
       [--seconds-fast 10] [--seconds-real 2]
       python benchmarks/realtime.py --throttling   # the floor at priority 50 for 0.8 s and 1.4 s (root)
"""
from __future__ import annotations

import argparse
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
from typing import Optional

import numpy as np

import deltafmi
from deltafmi.master.live.datagram import decode, encode

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "delta_tracking.yaml"


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
    """benchmarks/native/paced_floor.c compiled (``cc -std=c99 -O2``) as a program of its own."""

    def __init__(self, directory: Path) -> None:
        from deltafmi.toolchain import require_compiler

        source = Path(__file__).resolve().parent / "native" / "paced_floor.c"
        self.program, self.out = directory / "paced_floor", directory / "lateness.bin"
        subprocess.run([*require_compiler(source), "-std=c99", "-O2", str(source), "-o", str(self.program)],
                       check=True, capture_output=True)

    def __call__(self, mode: str, points: int, period: float, busy: float, spin: float = 2e-4,
                 lock: bool = True, prefix: tuple = (), lead: float = 0.0) -> dict:
        """``points`` points ``period`` apart around ``busy`` seconds of work, waiting by ``mode``
        (spin, sleep, hybrid: sleep to ``spin`` before the deadline, then poll): :func:`figures`.
        ``prefix``: the command it runs under (``chrt -f 50``)."""
        done = subprocess.run([*prefix, str(self.program), mode, str(points), repr(period), repr(busy), repr(spin),
                               str(self.out), *(["mlock"] if lock else []), f"lead={lead!r}"], check=True,
                              capture_output=True, text=True)
        cpu, wall, locked, _ = done.stdout.split()
        late = np.fromfile(self.out)
        found = figures(late, period, float(cpu), float(wall), locked == "1")
        found["early"] = float(max(0.0, -late.min()))
        found["miss"] = float("nan")  # benchmarks/pacing_floor.py measures the floor's
        return found


def figures(lateness: np.ndarray, period: float, cpu: float, wall: float, locked: bool) -> dict:
    """Overruns (the Pacer's: later than a quarter period), shares later than 1 us, half and a
    whole period, fell-behind episodes (as the Pacer counts them) and the median time between
    their starts, lateness percentiles, the CPU time of the loop against its wall time, and
    whether the last point was still a whole period late (the run had not caught up by its end)."""
    late = np.asarray(lateness, dtype=float)
    beyond = late > period
    starts = np.flatnonzero(beyond & ~np.concatenate(([False], beyond[:-1])))
    return {"spacing": float(np.median(np.diff(starts))) * period if len(starts) > 2 else float("nan"),
            "points": len(late), "overruns": float(np.mean(late > period / 4)), "over_1us": float(np.mean(late > 1e-6)),
            "over_half": float(np.mean(late > period / 2)), "over_period": float(np.mean(beyond)),
            "behind": int(np.count_nonzero(beyond & ~np.concatenate(([False], beyond[:-1])))),
            "p50": float(np.median(late)), "p99": float(np.percentile(late, 99)), "max": float(late.max()),
            "cpu": cpu / wall if wall > 0 else float("nan"), "locked": locked, "end": bool(late[-1] > period)}


def handing_back(begin_fixed_steps):
    """Master.begin_fixed_steps as it was before the streamed paced run: the C loop hands back
    to Python after every 50 ms of wall time (LiveRun.points_between_samples points)."""
    def begin(self, *args, **kwargs):
        begin_fixed_steps(self, *args, **kwargs)
        if getattr(self, "_streamed", False):
            self._streamed = False
            self._fixed_chunk = self._fixed_most = self.live.points_between_samples()
    return begin


def ours(stop: float, speed: float, spin: Optional[float] = None, priority: Optional[int] = None,
         hand_back: bool = False, lead: Optional[float] = None, lock: bool = True,
         cpu: Optional[int] = None) -> dict:
    """The flagship paced at ``speed`` for ``stop`` simulated seconds (the master's C loop);
    ``spin``, ``priority``, ``lead``: ``master.realtime``'s (None: the defaults; ``lead=0``: a
    deadline per step, the pacing before the lead); ``hand_back``: the C loop handing back every
    50 ms (:func:`handing_back`); ``lock=False``: memory not locked (mlockall); ``cpu``: the process
    on that CPU only while it runs: :func:`figures` and the median busy time."""
    from dataclasses import replace

    from deltafmi.master.live import pacing

    scenario = deltafmi.load_scenario(SCENARIO)
    if spin is not None or priority is not None or lead is not None:
        realtime = replace(scenario.master.realtime, spin=spin, priority=priority, lead=lead)
        scenario = replace(scenario, master=replace(scenario.master, realtime=realtime))
    from deltafmi.master.stepping.master import Master

    begin, lock_memory, affinity = Master.begin_fixed_steps, pacing.lock_memory, os.sched_getaffinity(0)
    if hand_back:
        Master.begin_fixed_steps = handing_back(begin)
    if not lock:
        pacing.lock_memory = lambda: False
    if cpu is not None:
        os.sched_setaffinity(0, {cpu})
    try:
        result = deltafmi.simulate(scenario, stop=stop, speed=speed)
    finally:
        Master.begin_fixed_steps, pacing.lock_memory = begin, lock_memory
        os.sched_setaffinity(0, affinity)
    report = result.summary.live.realtime
    found = figures(report.lateness, 1e-3 / speed, report.cpu, report.wall, report.locked)
    found["busy"] = float(np.median(result["realtime.busy"][1:]))
    found["polled"] = report.polled / report.wall
    found["early"] = float(max(0.0, -report.lateness.min())) if len(report.lateness) else 0.0
    found["miss"] = deadline_misses(result["realtime.lateness"], result["realtime.busy"], 1e-3 / speed)
    return found


def deadline_misses(lateness: np.ndarray, busy: np.ndarray, period: float) -> float:
    """The share of steps that finished computing after their point's deadline (a real-time
    engineer's overrun): point k's step began at the release of point k - 1 (its deadline plus its
    lateness) and computed ``busy[k]`` seconds; the first point starts the clock."""
    finished = (np.arange(len(lateness) - 1) * period + lateness[:-1]) + busy[1:]
    return float(np.mean(finished > np.arange(1, len(lateness)) * period))


#: a real-time priority (SCHED_FIFO 50: root or CAP_SYS_NICE), for --fifo
FIFO = ("chrt", "-f", "50")


def compare(repeats: int, seconds: dict, fifo: bool = False) -> dict:
    """Each configuration once per repeat, in an order shuffled anew each repeat (the load changes
    from one moment to the next; a fixed order would favour a place in it): the flagship paced at
    50x as it paces by default (a lead of 0.5 ms, sleeping) and with a deadline per step (lead 0,
    polling: the pacing before the lead), and at 1x (per step, sleeping then polling 50 us; sleeping
    only and polling 200 us too), beside the floor (:class:`PacedFloor`) around the flagship's median busy time (from a
    first run, not counted) waiting each way; ``fifo``: both at real-time priority 50 too
    (``master.realtime.priority``; the floor under :data:`FIFO`). ``seconds``: simulated seconds
    per speed. Returns {label: [figures per repeat]}; each figures' "load" is the load average
    when its repeat began."""
    runs: dict = {}
    shuffle = random.Random(42).shuffle
    with tempfile.TemporaryDirectory() as folder:
        floor = PacedFloor(Path(folder))
        busy = {speed: ours(seconds[speed], speed)["busy"] for speed in (50.0, 1.0)}
        plan: list = []
        for speed in (50.0, 1.0):
            period, stop = 1e-3 / speed, seconds[speed]
            n = int(round(stop / 1e-3))
            b = busy[speed]
            plan.append((f"ours {speed:g}x", lambda stop=stop, speed=speed: ours(stop, speed)))
            if speed == 50.0:
                plan += [("ours 50x per step", lambda stop=stop: ours(stop, 50.0, lead=0.0)),
                         ("floor 50x spin (per step)", lambda n=n, period=period, b=b: floor("spin", n, period, b)),
                         ("floor 50x sleep, lead 500 us", lambda n=n, period=period, b=b:
                          floor("sleep", n, period, b, spin=0.0, lead=5e-4)),
                         ("floor 50x sleep (per step)", lambda n=n, period=period, b=b:
                          floor("sleep", n, period, b, spin=0.0))]
                if fifo:
                    plan += [("ours 50x priority 50", lambda stop=stop: ours(stop, 50.0, priority=50)),
                             ("ours 50x priority 50, no mlock", lambda stop=stop: ours(stop, 50.0, priority=50,
                                                                                       lock=False)),
                             ("ours 50x per step, priority 50", lambda stop=stop: ours(stop, 50.0, priority=50,
                                                                                         lead=0.0)),
                             ("floor 50x spin SCHED_FIFO", lambda n=n, period=period, b=b:
                              floor("spin", n, period, b, prefix=FIFO)),
                             ("floor 50x lead SCHED_FIFO", lambda n=n, period=period, b=b:
                              floor("sleep", n, period, b, spin=0.0, lead=5e-4, prefix=FIFO))]
            else:
                plan += [("ours 1x sleep only", lambda stop=stop: ours(stop, 1.0, spin=0.0)),
                         ("ours 1x polling 200 us", lambda stop=stop: ours(stop, 1.0, spin=2e-4))]
                for mode, spin in (("sleep", 0.0), ("hybrid", 2e-4), ("hybrid", 5e-5), ("spin", 0.0)):
                    label = f"floor 1x {mode}" + (f" {spin * 1e6:.0f} us" if mode == "hybrid" else "")
                    plan.append((label, lambda mode=mode, n=n, period=period, b=b, spin=spin:
                                 floor(mode, n, period, b, spin)))
                if fifo:
                    plan += [("ours 1x priority 50", lambda stop=stop: ours(stop, 1.0, priority=50)),
                             ("floor 1x hybrid 50 us SCHED_FIFO", lambda n=n, period=period, b=b:
                              floor("hybrid", n, period, b, 5e-5, prefix=FIFO))]
        for label, _ in plan:
            runs[label] = []
        for _ in range(repeats):
            load = os.getloadavg()[0]
            order = list(plan)
            shuffle(order)
            for label, run in order:
                found = run()
                found["load"] = load
                runs[label].append(found)
    return runs


def kernel_hz() -> Optional[str]:
    """CONFIG_HZ of the running kernel (/proc/config.gz or /boot/config-RELEASE), or None."""
    import gzip

    for path, read in ((Path("/proc/config.gz"), lambda p: gzip.decompress(p.read_bytes()).decode()),
                       (Path(f"/boot/config-{os.uname().release}"), lambda p: p.read_text())):
        try:
            text = read(path)
        except OSError:
            continue
        return next((line.split("=")[1] for line in text.splitlines() if line.startswith("CONFIG_HZ=")), None)
    return None


def print_compare(runs: dict, repeats: int, seconds: dict) -> None:
    print(f"paced flagship (master's C loop) beside the machine's floor (a bare C program around the flagship's "
          f"median busy time), {repeats} repeats, each configuration once a repeat in a shuffled order; 50x: {seconds[50.0]:g} s simulated "
          f"({int(seconds[50.0] * 1e3)} points, 20 us paced step, overrun = later than 5 us), 1x: {seconds[1.0]:g} s "
          f"(1 ms step, overrun = later than 250 us); load average (1 min) at each repeat's start: "
          + ", ".join(f"{f['load']:.2f}" for f in runs["ours 50x"]))
    print(f"  {'':34} {'overruns':>9} {'miss':>7} {'>1us':>7} {'>T/2':>7} {'>T':>7} {'behind':>7} {'p50':>9} "
          f"{'p99':>10} {'max':>10} {'early':>10} {'CPU':>6} {'end':>4}   (medians over the repeats; per repeat: "
          f"overruns %, fell behind; miss: steps that finished computing after their deadline; end: repeats whose "
          f"last point was still a step late)")
    for label, found in runs.items():
        med = {key: statistics.median(f[key] for f in found) for key in ("overruns", "miss", "over_1us", "over_half",
                                                                            "over_period", "behind", "p50", "p99",
                                                                            "max", "early", "cpu")}
        each = " ".join(f"{f['overruns']:.1%}/{f['behind']}" for f in found)
        print(f"  {label:34} {med['overruns']:9.2%} {med['miss']:7.2%} {med['over_1us']:7.1%} {med['over_half']:7.1%} "
              f"{med['over_period']:7.1%} {med['behind']:7g} {_us(med['p50'])} {_us(med['p99'])} {_us(med['max'])} "
              f"{_us(med['early'])} {med['cpu']:6.0%} {sum(f['end'] for f in found):4d}   {each}")
    for speed in (50.0, 1.0):
        mine = runs[f"ours {speed:g}x"]
        print(f"  ours {speed:g}x: busy median {_us(statistics.median(f['busy'] for f in mine))}, polling "
              f"{statistics.median(f['polled'] for f in mine):.0%} of wall, memory locked "
              f"{all(f['locked'] for f in mine)}")
    pairs = [("ours 50x", "floor 50x sleep, lead 500 us"), ("ours 50x per step", "floor 50x spin (per step)"),
             ("ours 1x", "floor 1x hybrid 50 us"), ("ours 1x polling 200 us", "floor 1x hybrid 200 us"),
             ("ours 1x sleep only", "floor 1x sleep")]
    if "ours 50x priority 50" in runs:
        pairs += [("ours 50x priority 50", "floor 50x lead SCHED_FIFO"),
                  ("ours 50x per step, priority 50", "floor 50x spin SCHED_FIFO"),
                  ("ours 1x priority 50", "floor 1x hybrid 50 us SCHED_FIFO")]
    for mine_label, floor_label in pairs:
        mine = statistics.median(f["overruns"] for f in runs[mine_label])
        floor = statistics.median(f["overruns"] for f in runs[floor_label])
        print(f"  overruns {mine_label} / {floor_label} (waiting alike): {mine:.2%} / {floor:.2%}"
              + (f" = {mine / floor:.2f}" if floor else ""))

    def met(label: str) -> str:
        return "met" if statistics.median(f["overruns"] for f in runs[label]) <= 0.01 and \
            statistics.median(f["behind"] for f in runs[label]) == 0 else "missed"

    print(f"  target at 50x (never behind, overruns <= 1 %), at these moments: ours {met('ours 50x')} (per step "
          f"{met('ours 50x per step')}), the floor waiting as ours does {met('floor 50x sleep, lead 500 us')} "
          f"(per step {met('floor 50x spin (per step)')})")
    if "ours 50x priority 50" in runs:
        spacing = [statistics.median(f["spacing"] for f in runs[label]) * 1e3
                   for label in ("ours 50x per step, priority 50", "floor 50x spin SCHED_FIFO")]
        hz = kernel_hz()
        print(f"  at priority 50 per step, a point later than a step comes every {spacing[0]:.2f} ms (ours) and "
              f"{spacing[1]:.2f} ms (floor), medians of the time between them; the kernel's scheduler tick: "
              + (f"every {1e3 / int(hz):g} ms (CONFIG_HZ={hz})" if hz else "CONFIG_HZ unknown"))
        print(f"  at real-time priority 50: ours {met('ours 50x priority 50')} (per step "
              f"{met('ours 50x per step, priority 50')}), the floor with the lead {met('floor 50x lead SCHED_FIFO')} "
              f"(per step {met('floor 50x spin SCHED_FIFO')})")


def throttling() -> None:
    """The floor polling at real-time priority 50 for 0.8 s and 1.4 s of wall time (20 us steps):
    Linux's real-time throttling (kernel.sched_rt_runtime_us of sched_rt_period_us) stops a thread
    that never sleeps for the rest of each period once it has run its share."""
    runtime, period = (int(Path(f"/proc/sys/kernel/sched_rt_{name}_us").read_text()) for name in ("runtime", "period"))
    print(f"real-time throttling: sched_rt_runtime_us {runtime} of sched_rt_period_us {period}; the floor polling "
          f"at priority 50 (20 us steps):")
    with tempfile.TemporaryDirectory() as folder:
        floor = PacedFloor(Path(folder))
        for seconds in (0.8, 1.4):
            found = floor("spin", int(seconds / 2e-5), 2e-5, 2.3e-6, prefix=FIFO)
            late = np.fromfile(floor.out)
            print(f"  {seconds:g} s: {np.count_nonzero(late > 1e-2)} points later than 10 ms of {found['points']}, "
                  f"largest {found['max'] * 1e3:.1f} ms, overruns {found['overruns']:.2%}")


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


def _udp_input_scenario(folder: Path, port: int, priority: Optional[int] = None) -> Path:
    path = folder / "udp_input.yaml"
    realtime = "true" if priority is None else f"{{priority: {priority}}}"
    path.write_text(f"""\
experiment: {{stop: 1000.0, step: 1.0e-3}}
master: {{realtime: {realtime}}}
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
    return path


def udp_input_run(stop: float, speed: float, in_c: bool, priority: Optional[int] = None) -> dict:
    """The Oscillator paced at ``speed`` for ``stop`` simulated seconds with a UDP live input that
    another thread sends a datagram to every millisecond of wall time: the live source read by the
    C loop between its steps (``in_c``), or sampled in Python at every point (the C loop handing
    back at each, as before the C reader); ``priority``: ``master.realtime.priority``: :func:`figures`,
    the median busy time and the datagrams taken."""
    from deltafmi.master.live.run import LiveRun

    port = _ports()[0]
    done = threading.Event()

    def send() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            n = 0
            while not done.is_set():
                n += 1
                sock.sendto(encode({"x": float(n)}, t=n * 1e-3, seq=n), ("127.0.0.1", port))
                time.sleep(1e-3)

    read_in_c = LiveRun.read_in_c
    if not in_c:
        LiveRun.read_in_c = lambda self: None
    sender = threading.Thread(target=send, daemon=True)
    with tempfile.TemporaryDirectory() as folder:
        scenario = _udp_input_scenario(Path(folder), port, priority)
        sender.start()
        try:
            result = deltafmi.simulate(scenario, stop=stop, speed=speed, output=Path(folder) / "udp.csv")
        finally:
            done.set()
            sender.join()
            LiveRun.read_in_c = read_in_c
    report = result.summary.live.realtime
    found = figures(report.lateness, 1e-3 / speed, report.cpu, report.wall, report.locked)
    found["busy"] = float(np.median(result["realtime.busy"][1:]))
    found["taken"] = len(np.unique(result["cmd.x"]))
    return found


def udp_figures(seconds: float, repeats: int, fifo: bool = False) -> None:
    """:func:`udp_input_run` at 50x read in C and in Python (``fifo``: at priority 50 too), each
    once per repeat in a shuffled order; medians over the repeats."""
    load = os.getloadavg()[0]
    plan = [("read by the C loop between steps", True, None), ("sampled in Python at every point", False, None)]
    if fifo:
        plan += [("read in C, priority 50", True, 50), ("sampled in Python, priority 50", False, 50)]
    found: dict = {label: [] for label, _, _ in plan}
    shuffle = random.Random(5).shuffle
    for _ in range(repeats):
        order = list(plan)
        shuffle(order)
        for label, in_c, priority in order:
            found[label].append(udp_input_run(seconds, 50.0, in_c, priority))
    print(f"UDP live input at 50x (the Oscillator, {seconds:g} s simulated, a datagram every ms of wall time), "
          f"{repeats} repeats, medians; load average {load:.2f} at the start, {os.getloadavg()[0]:.2f} at the end:")
    for label, runs in found.items():
        med = {key: statistics.median(f[key] for f in runs) for key in ("overruns", "behind", "p50", "p99", "busy",
                                                                           "taken")}
        each = " ".join(f"{f['overruns']:.1%}/{f['behind']}" for f in runs)
        print(f"  {label:34} overruns {med['overruns']:7.2%}, behind {med['behind']:5g}, p50 {_us(med['p50'])}, "
              f"p99 {_us(med['p99'])}, busy {_us(med['busy'])}, values taken {med['taken']:g}   ({each})")


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
    parser.add_argument("--seconds-fast", type=float, default=10.0, help="simulated seconds of the 50x runs")
    parser.add_argument("--seconds-real", type=float, default=2.0, help="simulated seconds of the 1x runs")
    parser.add_argument("--target-only", action="store_true",
                        help="only the paced flagship at 50x and 1x beside the machine's floor")
    parser.add_argument("--fifo", action="store_true",
                        help="at 50x, the flagship and the floor at a real-time priority too (chrt -f 50: root)")
    parser.add_argument("--udp-only", action="store_true",
                        help="only the UDP live input at 50x, read in C and in Python")
    parser.add_argument("--throttling", action="store_true",
                        help="only the floor at real-time priority 50 for 0.8 s and 1.4 s (Linux's real-time throttling)")
    args = parser.parse_args()
    if args.throttling:
        throttling()
        return
    logging.getLogger("deltafmi.scenario").setLevel(logging.ERROR)  # "fell behind" while probing speeds
    deltafmi.simulate("delta_tracking", stop=0.01)  # builds the FMUs once
    if args.udp_only:
        udp_figures(args.seconds, args.repeats, args.fifo)
        return
    seconds = {50.0: args.seconds_fast, 1.0: args.seconds_real}
    runs = compare(args.repeats, seconds, args.fifo)
    print_compare(runs, args.repeats, seconds)
    if args.target_only:
        return
    python_busy = [python_loop_busy(args.seconds, 50.0) for _ in range(args.repeats)]
    c_busy = statistics.median(run["busy"] for run in runs["ours 50x"])
    print(f"  busy per point, medians: C loop {_us(c_busy)}, Python loop {_us(statistics.median(python_busy))} "
          f"(paced step {_us(1e-3 / 50.0)}); Python / C {statistics.median(python_busy) / c_busy:.1f}x")

    busy = statistics.median(run["busy"] for run in runs["ours 1x"])
    plain = deltafmi.simulate("delta_tracking")
    rtf = plain.summary.simulated / plain.summary.stepping_time
    speed = highest_speed()
    print(f"highest speed that keeps up: {speed:.1f}x real time")
    print(f"  baseline (same run): step / busy = {1e-3 / busy:.1f}x; unpaced real-time factor "
          f"{rtf:.0f}x (C loop); ratio kept-up / busy-allowed = {speed / (1e-3 / busy):.2f}")

    udp_figures(args.seconds, args.repeats, args.fifo)

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
