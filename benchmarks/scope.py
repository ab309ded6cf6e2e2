"""What the live plot window (``deltafmi scope``) costs: per redraw, and per datagram drained.

1. Redraw: a ScopeData full of 1 kHz signals (a window of 10 s: 10 000 points per curve), moved on
   by 50 ms of simulation time between frames (a 20 Hz scope following a run at real time);
   printed: the median cost of a frame that blits the curves and of one that draws everything
   (the time axis moved a step), over --frames frames, for 3 signals on one axes and 9 on three.
2. Drain: a sender process sends 9-signal DFMI datagrams on 127.0.0.1 for --seconds, as fast as
   it can or at a set rate; the scope drains them (alone, then while drawing at 20 Hz off
   screen). Printed: datagrams per second drained and the share of those sent that were lost
   (a full socket buffer drops them: the sender is never slowed). Also the cost of receive() per datagram
   (decode + keep), from bytes already in memory.

Usage: python benchmarks/scope.py [--frames 60] [--seconds 2]
"""
from __future__ import annotations

import argparse
import math
import multiprocessing
import socket
import statistics
import time
import timeit

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from deltafmi.master.live.datagram import Encoder
from deltafmi.apps.scope.window import Scope, ScopeFigure, _size, run_loop
from deltafmi.apps.scope.data import ScopeData

NAMES = [f"{quantity}[{i}]" for quantity in ("plant.z", "trajectory.r", "controller.u") for i in (1, 2, 3)]
RATE, WINDOW, FRAME = 1000.0, 10.0, 0.05


def _feed(data: ScopeData, names, start: int, count: int) -> None:
    for k in range(start, start + count):
        t = k / RATE
        data.add(t, k, {name: math.sin(t + i) for i, name in enumerate(names)})


def redraw(arguments, names, frames: int) -> None:
    data = ScopeData(arguments, WINDOW, warn=lambda _: None)
    figure = Figure(figsize=_size(len(arguments)))
    FigureCanvasAgg(figure)
    view = ScopeFigure(data, figure)
    per_frame = int(RATE * FRAME)
    step = int(RATE * WINDOW)
    _feed(data, names, 0, step)
    view.render()
    blits, full = [], []
    for f in range(frames):
        _feed(data, names, step + f * per_frame, per_frame)
        before = view.full_draws
        t0 = time.perf_counter()
        view.render()
        (full if view.full_draws > before else blits).append(time.perf_counter() - t0)
    points = sum(len(line.get_xdata()) for lines in view.lines for line in lines)
    mean = (sum(blits) + sum(full)) / frames
    print(f"redraw, {len(names)} signals on {len(arguments)} axes ({points} points drawn): "
          f"curves only {_ms(blits)} ({len(blits)} frames), full {_ms(full)} ({len(full)} frames); "
          f"mean {1e3 * mean:.1f} ms per frame = {100 * mean / FRAME:.0f} % of a core at 20 Hz")


def _ms(times) -> str:
    return f"median {1e3 * statistics.median(times):.1f} ms" if times else "-"



def _send(port: int, seconds: float, rate: float, counter) -> None:
    """Datagrams at ``rate`` per second (as fast as possible when 0), sent in 1 ms batches."""
    encoder = Encoder(NAMES)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    start = time.perf_counter()
    k = 0
    while (now := time.perf_counter() - start) < seconds:
        due = int(now * rate) + 1 if rate else k + 100
        if k >= due:
            time.sleep(1e-3)
        while k < due:
            try:
                sock.sendto(encoder.encode([math.sin(k * 1e-3 + i) for i in range(9)], k * 1e-3, k),
                            ("127.0.0.1", port))
            except OSError:
                pass
            k += 1
    counter.value = k


def drain(seconds: float, rate: float, draw: bool) -> None:
    scope = Scope(["plant.z[*]", "trajectory.r[*]", "controller.u[*]"], WINDOW, warn=lambda _: None)
    _, port = scope.open()
    figure = Figure(figsize=_size(3))
    FigureCanvasAgg(figure)
    view = ScopeFigure(scope.data, figure)
    counter = multiprocessing.Value("q", 0)
    sender = multiprocessing.Process(target=_send, args=(port, seconds, rate, counter))
    sender.start()
    started = time.perf_counter()
    if draw:
        run_loop(scope, view, fps=20.0, exit_when_idle=0.3)
    else:
        last = time.perf_counter()
        while time.perf_counter() - last < 0.3:
            if scope.drain(0.05):
                last = time.perf_counter()
            else:
                scope.wait(0.05)
    elapsed = time.perf_counter() - started - 0.3
    sender.join()
    scope.close()
    received, sent = scope.data.counters["received"], counter.value
    print(f"drain {'while drawing at 20 Hz' if draw else 'alone'}, sender at "
          f"{f'{rate:,.0f}/s' if rate else 'full speed'}: {received / elapsed:,.0f} datagrams/s "
          f"({received} of {sent} sent in {seconds:g} s, {100 * (1 - received / sent):.1f} % lost, "
          f"{view.frames} frames)")


def per_datagram() -> None:
    data = ScopeData(["plant.z[*]", "trajectory.r[*]", "controller.u[*]"], WINDOW, warn=lambda _: None)
    encoder = Encoder(NAMES)
    datagrams = [encoder.encode([math.sin(k * 1e-3 + i) for i in range(9)], k * 1e-3, k) for k in range(20000)]
    it = iter(datagrams * 5)
    runs = timeit.repeat(lambda: data.receive(next(it)), number=10000, repeat=7)
    data.flush()
    print(f"receive(), 9 signals: {1e6 * statistics.median(runs) / 10000:.2f} us per datagram (decode and keep), "
          f"flush {len(data.traces['plant.z[1]'])} points per signal")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--seconds", type=float, default=2.0)
    options = parser.parse_args()
    redraw(["plant.z[*]"], NAMES[:3], options.frames)
    redraw(["plant.z[*]", "trajectory.r[*]", "controller.u[*]"], NAMES, options.frames)
    per_datagram()
    drain(options.seconds, 0.0, draw=False)
    for rate in (1e3, 1e4, 3e4, 0.0):
        drain(options.seconds, rate, draw=True)


if __name__ == "__main__":
    main()
