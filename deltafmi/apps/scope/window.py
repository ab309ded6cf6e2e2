"""The live plot window: a rolling picture of the signals a run streams out as DFMI datagrams.

``python -m deltafmi.apps scope --port P --window 10 SIGNAL...`` (``deltafmi scope``) binds a
UDP socket, prints ``listening HOST:PORT`` as its first line of stdout (``--port 0``: a free port,
the one to send to), and draws what arrives. It runs in a process of its own, so drawing never
takes time from the simulation: a run only sends datagrams (a scope that falls behind drops them,
it never slows the sender).

Layout, decided for 3-9 signals: one subplot per SIGNAL argument, stacked and sharing the time
axis; the signals an argument matches share its axes, told apart by a legend, and the subplot's
title is the argument. An argument may hold several patterns separated by spaces: ``'plant.z[1]
follower.r[1]'`` draws a reference and what follows it on one axes (:mod:`.data` holds and
routes the signals). The time axis ends at (just after) the newest time received and spans
``window`` seconds; each value axis fits its visible curves, with some slack so that it does not
twitch every frame. The scope reads DFMI datagrams (binary or JSON); packed doubles carry no names.
"""
from __future__ import annotations

import math
import select
import signal
import socket
import time
from pathlib import Path
from typing import Any, Callable, List, Optional, Sequence, Tuple

from deltafmi.errors import BadInput

from deltafmi.master.live.display import display_problem

from .data import Group, ScopeData, warn_on_stderr

__all__ = ["Scope", "ScopeFigure", "run_loop", "run_scope"]

#: asked of the kernel for the socket (it caps this at net.core.rmem_max): room for the datagrams
#: that arrive while a frame is drawn
_RECEIVE_BUFFER = 1 << 22
#: value axes: slack added around the visible values, and the least share of the axis they may fill
#: before it shrinks to them
_SLACK, _LEAST_FILL = 0.08, 0.4
#: while a frame is not due yet, datagrams are drained this often (the socket buffer holds them)
_GATHER = 0.01


def _fit(current: Tuple[float, float], lo: float, hi: float) -> Optional[Tuple[float, float]]:
    """New limits of a value axis showing ``lo``..``hi``, or None to keep ``current``: the values
    are inside them and fill at least :data:`_LEAST_FILL` of them. New limits leave some slack
    and are rounded outwards to a fifth of the power of ten below their span, so that small
    changes keep them; a constant shows in the middle of its axis."""
    span = hi - lo
    bottom, top = current
    if bottom <= lo and hi <= top and span >= _LEAST_FILL * (top - bottom):
        return None
    slack = _SLACK * span if span > 0 else (abs(lo) * _SLACK or 1.0)
    grain = 10.0 ** math.floor(math.log10(span + 2 * slack)) / 5
    return math.floor((lo - slack) / grain) * grain, math.ceil((hi + slack) / grain) * grain


class ScopeFigure:
    """The picture of a :class:`ScopeData` on a matplotlib ``figure``: one axes per group, stacked,
    sharing the time axis; :meth:`render` draws a frame.

    A full draw of the axes (ticks, labels, legends) costs tens of milliseconds, the curves alone a
    few: so the curves are animated artists blitted over a saved background, and the background is
    redrawn only when the axes change. The time axis therefore follows the newest time in steps
    of a tenth of the window (its right end is the newest time rounded up to such a step), the
    value axes move only when the curves leave them or fill less than :data:`_LEAST_FILL` of them,
    and curves are thinned to about two points per column of pixels."""

    #: the time axis moves in steps of this share of the window
    STEP = 0.1

    def __init__(self, data: ScopeData, figure: Any, title: str = "deltafmi scope") -> None:
        self.data = data
        self.figure = figure
        self.axes = list(figure.subplots(len(data.groups), 1, sharex=True, squeeze=False)[:, 0])
        self.lines: List[List[Any]] = [[] for _ in data.groups]
        self._waiting = []
        for ax, group in zip(self.axes, data.groups):
            ax.set_title(group.title, loc="left", fontsize="medium")
            ax.grid(True, alpha=0.3)
            self._waiting.append(ax.text(0.5, 0.5, f"waiting for {group.title}", transform=ax.transAxes,
                                         ha="center", va="center", color="0.5"))
        self.axes[-1].set_xlabel("time [s]")
        self.axes[-1].set_xlim(0.0, data.window)
        figure.suptitle(title)
        #: canvases that cannot blit (cairo's) draw everything every frame
        self.blit = bool(getattr(figure.canvas, "supports_blit", False))
        self.clock = figure.text(0.98, 0.98, "", ha="right", va="top", family="monospace", animated=self.blit)
        self.frames = 0  # counted by run_loop
        self.full_draws = 0
        self._background: Any = None
        self._covers: List[Tuple[int, int, int, int]] = []
        self._stale = True  # the background no longer shows the axes as they are
        figure.canvas.mpl_connect("draw_event", self._drawn)

    def update(self) -> None:
        """Bring the picture to the data: lines for newly matched signals (and their legends),
        each curve's visible part, the time and value axes."""
        data = self.data
        data.flush()
        if data.newest == -math.inf:
            return
        step = self.STEP * data.window
        right = max(math.ceil(data.newest / step) * step, data.started + data.window)
        left = right - data.window
        if self.axes[-1].get_xlim() != (left, right):
            self.axes[-1].set_xlim(left, right)
            self._stale = True
        for ax, group, lines, waiting in zip(self.axes, data.groups, self.lines, self._waiting):
            if len(lines) != len(group.traces):
                self._relabel(ax, group, lines, waiting)
                self._stale = True
            columns = max(int(ax.bbox.width), 16)
            lo, hi = math.inf, -math.inf
            for line, trace in zip(lines, group.traces):
                t, v = trace.visible(left, columns)
                line.set_data(t, v)
                if len(v):
                    lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
            if lo <= hi:
                limits = _fit(ax.get_ylim(), lo, hi)
                if limits is not None:
                    ax.set_ylim(*limits)
                    self._stale = True
        self.clock.set_text(f"t = {data.newest:.3f} s")

    def render(self) -> None:
        """Update and draw one frame: the curves over the saved background, or everything when
        the axes changed."""
        self.update()
        canvas = self.figure.canvas
        if self._stale or self._background is None or not self.blit:
            canvas.draw()  # _drawn saves the background and draws the curves
        else:
            canvas.restore_region(self._background)
            self._draw_curves()
        canvas.blit(self.figure.bbox)

    def _drawn(self, _event: Any) -> None:
        """After every full draw (ours, a resized window's): the new background, then the curves."""
        canvas = self.figure.canvas
        if canvas.is_saving() or not self.blit:
            return
        self.full_draws += 1
        self._background = canvas.copy_from_bbox(self.figure.bbox)
        height = self.figure.bbox.height
        self._covers = []  # in the background's pixels: counted from the top, not from the bottom
        for ax in self.axes:
            for artist in [*ax.spines.values(), ax.get_legend()]:
                if artist is not None and artist.get_visible():
                    x0, y0, x1, y1 = artist.get_window_extent().extents
                    self._covers.append((math.floor(x0), math.floor(height - y1),
                                         math.ceil(x1), math.ceil(height - y0)))
        self._stale = False
        self._draw_curves()

    def _draw_curves(self) -> None:
        canvas = self.figure.canvas
        for lines in self.lines:
            for line in lines:
                self.figure.draw_artist(line)
        for box in self._covers:  # spines and (opaque) legends back over the curves, as in a full drawing
            canvas.restore_region(self._background, bbox=box, xy=(0, 0))
        self.figure.draw_artist(self.clock)

    def save(self, path: str) -> None:
        """Write the picture, as it stands, to a file (its format from the name's suffix), whole
        or not at all: an earlier file of that name stays until the new one is complete."""
        from deltafmi.files import replaced_atomically

        self.clock.set_animated(False)  # a figure's own animated artists are left out of a saved file
        try:
            with replaced_atomically(Path(path)) as temporary:
                self.figure.savefig(temporary, format=Path(path).suffix.lstrip(".").lower() or None)
        finally:
            self.clock.set_animated(self.blit)

    def _relabel(self, ax: Any, group: Group, lines: List[Any], waiting: Any) -> None:
        for line in lines:
            line.remove()
        ax.set_prop_cycle(None)  # colours in legend order, as if drawn in one go
        lines[:] = [ax.plot([], [], lw=1.2, label=trace.name, animated=self.blit)[0] for trace in group.traces]
        waiting.set_visible(False)
        ax.legend(loc="upper left", fontsize="small", framealpha=1.0, ncol=1 + (len(lines) > 3) + (len(lines) > 6))


class Scope:
    """The scope's socket and data: :meth:`open` binds, :meth:`drain` reads what is pending."""

    def __init__(self, arguments: Sequence[str], window: float = 10.0, host: str = "127.0.0.1",
                 port: int = 0, warn: Callable[[str], None] = warn_on_stderr) -> None:
        self.data = ScopeData(arguments, window, warn)
        self.host, self.port = host, port
        self._socket: Optional[socket.socket] = None
        #: whether the last :meth:`drain` ran out of time with datagrams still pending
        self.backlog = False

    def open(self) -> Tuple[str, int]:
        """Bind the socket (non-blocking); the address it listens on. Raises BadInput (one line)."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.bind((self.host, self.port))
        except (OSError, OverflowError) as error:
            sock.close()
            raise BadInput(f"the scope cannot listen on {self.host}:{self.port}: "
                           f"{getattr(error, 'strerror', None) or error}") from None
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, _RECEIVE_BUFFER)
        except OSError:
            pass
        sock.setblocking(False)
        self._socket = sock
        self.host, self.port = sock.getsockname()[:2]
        return self.host, self.port

    def drain(self, budget: float = 0.02) -> int:
        """Receive the pending datagrams, for at most about ``budget`` seconds (a flood must not
        stop the drawing); how many were received."""
        recv, receive = self._socket.recv, self.data.receive
        deadline = time.perf_counter() + budget
        count = 0
        self.backlog = False
        while True:
            try:
                data = recv(65536)
            except (BlockingIOError, InterruptedError):
                return count
            except OSError:  # an ICMP error queued on the socket: nothing to read
                return count
            receive(data)
            count += 1
            if not count % 64 and time.perf_counter() > deadline:
                self.backlog = True
                return count

    def wait(self, timeout: float) -> None:
        """Until a datagram is pending or ``timeout`` seconds have passed."""
        select.select([self._socket], [], [], max(timeout, 0.0))

    def close(self) -> None:
        """Close the socket (idempotent)."""
        if self._socket is not None:
            self._socket.close()
            self._socket = None


class _Stop:
    """Why the loop ends: set by a closed window or a signal."""

    def __init__(self) -> None:
        self.reason: Optional[str] = None

    def __call__(self, reason: str) -> None:
        self.reason = self.reason or reason

    def on_signal(self, reason: str) -> Callable[[int, Any], None]:
        """A signal handler that stops the loop for ``reason``; a signal after that one raises
        KeyboardInterrupt."""
        def handle(signum: int, frame: Any) -> None:
            if self.reason is not None:
                raise KeyboardInterrupt
            self(reason)
        return handle


def run_loop(scope: Scope, view: ScopeFigure, *, fps: float = 20.0,
             frames: Optional[int] = None, exit_when_idle: Optional[float] = None,
             events: Optional[Callable[[], None]] = None, stop: Optional[_Stop] = None) -> str:
    """Drain, and redraw at most ``fps`` times a second when something new came; until ``frames``
    redraws, ``exit_when_idle`` seconds without a datagram (counted from the first one), or
    ``stop`` is set; ``events`` lets a window handle its events (every 20 ms at least). The reason
    the loop ended: "frames", "idle" or the stop's."""
    stop = stop or _Stop()
    period = 1.0 / fps
    next_frame = time.monotonic()
    last_datagram = math.inf  # idle counts from the first datagram: a run may take a while to start
    fresh = False
    while stop.reason is None:
        if scope.drain(period / 2):
            fresh = True
            last_datagram = time.monotonic()
        now = time.monotonic()
        if fresh and now >= next_frame:
            view.render()
            view.frames += 1
            fresh = False
            next_frame = now + period
            if frames is not None and view.frames >= frames:
                return "frames"
        if exit_when_idle is not None and now - last_datagram >= exit_when_idle:
            return "idle"
        if events is not None:
            events()
        if fresh:  # a frame is due later: gather datagrams until then, waking at 100 Hz, not on each
            if not scope.backlog:
                time.sleep(max(min(next_frame - now, _GATHER), 0.0))
            continue
        timeout = 0.02 if events is not None else 0.25
        if exit_when_idle is not None and last_datagram < math.inf:
            timeout = min(timeout, last_datagram + exit_when_idle - now)
        scope.wait(timeout)
    return stop.reason


def run_scope(arguments: Sequence[str], *, port: int, host: str = "127.0.0.1", window: float = 10.0,
              fps: float = 20.0, save: Optional[str] = None, frames: Optional[int] = None,
              exit_when_idle: Optional[float] = None) -> Tuple[ScopeFigure, str]:
    """The scope from start to end: a window (or, with ``save``, a PNG drawn off screen), fed
    until it is closed, ``frames`` redraws, ``exit_when_idle`` seconds of silence, Ctrl-C,
    SIGTERM or SIGHUP (the reason: "interrupted", "terminated", "hung up"; the picture is saved
    in every case). Prints ``listening HOST:PORT`` first; returns the picture (``.data``, ``.frames``) and
    why it ended. Raises
    BadInput (one line) for a socket that cannot be bound or no display without ``save``."""
    if save is None:
        problem = display_problem()
        if problem:
            raise BadInput(f"{problem}: give --save out.png (with --frames N or --exit-when-idle SECONDS) "
                           "to draw into a file")
    if save is not None:
        from deltafmi.master.results.safe_file import check_writable
        check_writable(Path(save), "picture")
    scope = Scope(arguments, window, host, port)
    stop = _Stop()
    # before the line the master (or a test) waits for: a SIGTERM sent once it is read ends the scope
    # as documented, however long matplotlib then takes to start
    previous = signal.signal(signal.SIGTERM, lambda *_: stop("terminated"))
    # Ctrl-C and a closed terminal end it the same way (SIGHUP not under nohup); a second signal
    # breaks whatever it is doing
    previous_interrupt = signal.signal(signal.SIGINT, stop.on_signal("interrupted"))
    hangup = signal.getsignal(signal.SIGHUP) != signal.SIG_IGN
    previous_hangup = signal.signal(signal.SIGHUP, stop.on_signal("hung up")) if hangup else None
    view: Optional[ScopeFigure] = None
    try:
        address = "%s:%d" % scope.open()
        print(f"listening {address}", flush=True)  # the line the master waits for
        title = f"deltafmi scope · {address}"
        if save is None:
            import matplotlib.pyplot as plt

            figure = plt.figure(figsize=_size(len(scope.data.groups)))
            figure.canvas.mpl_connect("close_event", lambda _: stop("closed"))
            events = figure.canvas.flush_events
        else:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            figure = Figure(figsize=_size(len(scope.data.groups)))
            FigureCanvasAgg(figure)
            events = None
        view = ScopeFigure(scope.data, figure, title=title)
        if save is None:
            plt.show(block=False)
        reason = run_loop(scope, view, fps=fps, frames=frames, exit_when_idle=exit_when_idle,
                          events=events, stop=stop)
        scope.drain(0.0)  # what arrived before the end counts, even where the end came first
    except KeyboardInterrupt:
        if view is None:  # before there was anything to show
            raise
        reason = "interrupted"
    finally:
        signal.signal(signal.SIGTERM, previous)
        signal.signal(signal.SIGINT, previous_interrupt)
        if previous_hangup is not None:
            signal.signal(signal.SIGHUP, previous_hangup)
        scope.close()
    if save is None:
        plt.close(figure)
    else:
        view.update()  # what came after the last frame too
        try:
            view.save(save)
        except OSError as error:
            raise BadInput(f"cannot write {save}: {error.strerror or error}") from None
    return view, reason


def _size(groups: int) -> Tuple[float, float]:
    return 10.0, min(1.2 + 2.2 * groups, 10.0)
