"""CLI command ``scope``: the live plot window of a run's UDP output stream (:mod:`.window`)."""
from __future__ import annotations

import signal
from typing import Optional, Sequence

import click

from deltafmi.apps.console import output_folders

__all__ = ["scope"]

#: the reasons a signal ends the scope, and the signal
_SIGNALLED = {"interrupted": signal.SIGINT, "terminated": signal.SIGTERM, "hung up": signal.SIGHUP}


@click.command("scope")
@click.argument("signals", nargs=-1, required=True)
@click.option("--port", type=click.IntRange(0, 65535), required=True,
              help="UDP port to listen on (0: a free one); the first line of output says which.")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on (0.0.0.0: every interface, for a run on another machine).")
@click.option("--window", type=click.FloatRange(0.0, min_open=True), default=10.0, show_default=True,
              help="Seconds of the sender's (simulation) time shown.")
@click.option("--fps", type=click.FloatRange(1.0, 60.0), default=20.0, show_default=True,
              help="Most redraws per second.")
@click.option("--save", type=click.Path(dir_okay=False), callback=output_folders, default=None,
              help="Draw off screen (no window) and write the last picture to this PNG file at the end.")
@click.option("--frames", type=click.IntRange(1), default=None,
              help="End after this many redraws (a redraw needs new datagrams).")
@click.option("--exit-when-idle", type=click.FloatRange(0.0, min_open=True), default=None, metavar="SECONDS",
              help="End after this many seconds without a datagram, counted from the first one (default: keep "
                   "the last picture until the window is closed).")
def scope(signals: Sequence[str], port: int, host: str, window: float, fps: float, save: Optional[str],
          frames: Optional[int], exit_when_idle: Optional[float]) -> None:
    """Live plot of the signals a run streams as DFMI datagrams (a `streams:` entry `udp:` of a
    scenario, or any program that sends them).

    Each SIGNAL argument is one subplot: a name, a pattern ('plant.z[*]', 'plant.z[1:3]') or an
    array's name; several patterns in one argument, separated by spaces, share the subplot. The
    time axis follows the newest time received. Closing the window ends the scope, not the run.
    Without a display, --save writes a PNG instead of opening a window.

    \b
    Examples:
      deltafmi scope --port 25001 'plant.z[*]'
      deltafmi scope --port 25001 'plant.z[1] trajectory.r[1]' 'controller.u[*]' --window 5
      deltafmi scope --port 25001 'plant.z[*]' --save z.png --exit-when-idle 2
    """
    from .window import run_scope

    view, reason = run_scope(signals, port=port, host=host, window=window, fps=fps, save=save,
                             frames=frames, exit_when_idle=exit_when_idle)
    for line in view.data.unmatched():
        click.echo(f"scope: warning: {line}", err=True)
    frames = f"{view.frames} frame{'s' * (view.frames != 1)}"
    click.echo(f"scope: {view.data.summary()}; {frames} drawn, ended: {reason}"
               + (f"; wrote {save}" if save else ""), err=True)
    if reason in _SIGNALLED:  # ended by a signal: the picture is saved, the exit code says which
        raise SystemExit(128 + _SIGNALLED[reason])
