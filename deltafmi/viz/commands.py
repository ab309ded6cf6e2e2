"""CLI command ``animate``: the delta robot of a result file as a GIF or MP4."""
from __future__ import annotations

from typing import Optional

import click


@click.command()
@click.argument("result", type=click.Path(exists=True, dir_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True,
              help="Animation file: .gif (Pillow) or .mp4 (needs ffmpeg).")
@click.option("--plant", help="Component whose servo angles to draw (default: the only one with y[1..3]).")
@click.option("--fps", type=float, default=20.0, show_default=True, help="Frames per second.")
@click.option("--speed", type=float, default=1.0, show_default=True,
              help="Simulated seconds per second of animation.")
@click.option("--size", type=float, default=8.0, show_default=True, help="Figure width [in] (80 dpi).")
def animate(result: str, output: str, plant: Optional[str], fps: float, speed: float, size: float) -> None:
    """Draw the delta robot of RESULT (.csv, .parquet, .mat) frame by frame: arms, plate, tool, surface.

    Needs the servo angles '<plant>.y[*]' in the result; uses the tool, the surface and the contact
    force when recorded ('plant.tool[*]', 'plant.surface_height', 'plant.surface_normal[*]',
    'plant.fn', 'plant.mode').

    \b
    Example:
      deltafmi animate contact_press.csv -o robot.gif --speed 0.5
    """
    from .animate import animate_result

    path = animate_result(result, output, plant=plant, fps=fps, speed=speed, size=size)
    click.echo(f"wrote {path}")
