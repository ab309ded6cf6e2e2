"""CLI command ``animate``: the delta robot of a result file as a GIF or MP4."""
from __future__ import annotations

from typing import Optional

import click

from deltafmi.apps.console import output_folders

__all__ = ["animate"]


@click.command()
@click.argument("result", type=click.Path(exists=True, dir_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), callback=output_folders, required=True,
              help="Animation file: .gif (Pillow) or .mp4 (needs ffmpeg).")
@click.option("--plant", help="Component whose servo angles to draw (default: the only one with y[1..3]).")
@click.option("--fps", type=float, default=20.0, show_default=True, help="Frames per second.")
@click.option("--speed", type=float, default=1.0, show_default=True,
              help="Simulated seconds per second of animation.")
@click.option("--size", type=float, default=8.0, show_default=True, help="Figure width [in] (80 dpi).")
@click.option("--wrist/--no-wrist", default=None,
              help="Draw the spherical wrist and its peg (default: when the result has 'plant.R[*]' or 'plant.qw[*]'); "
              "--wrist fails naming what is missing.")
@click.option("--hole/--no-hole", default=None,
              help="Add the peg-in-hole close-up (default: when the result has DeltaWristPeg's outputs or "
              "'plant.hole_position[*]'); --hole fails naming what is missing.")
@click.option("--set", "settings", multiple=True, metavar="NAME=VALUE[,VALUE...]",
              help="A parameter the result does not record (hole_position, hole_tilt, bore_radius, chamfer_width, "
              "chamfer_angle, hole_depth, tool_radius, tool_length, tool_tip, mount); repeatable.")
def animate(result: str, output: str, plant: Optional[str], fps: float, speed: float, size: float,
            wrist: Optional[bool], hole: Optional[bool], settings: tuple[str, ...]) -> None:
    """Draw the delta robot of RESULT (.csv, .parquet, .mat) frame by frame: arms, plate, tool, surface.

    Needs the servo angles '<plant>.y[*]' in the result; uses the tool, the surface and the contact
    force when recorded ('plant.tool[*]', 'plant.surface_height', 'plant.surface_normal[*]',
    'plant.fn', 'plant.mode').

    With a spherical wrist (DeltaWrist: 'plant.R[*]' or 'plant.qw[*]', 'plant.centre[*]',
    'plant.tip[*]') the peg is drawn along the tool axis; with a hole (DeltaWristPeg: 'plant.depth',
    'plant.contact_force[*]', 'plant.contact_moment[*]', 'plant.lateral_misalignment',
    'plant.angular_misalignment', 'plant.success') a side section through the hole and a top view
    are added. The hole's geometry is read from the result (record the parameters under the
    scenario's outputs:, e.g. 'plant.hole_position[*]'), else from --set, else the model's
    default (the command says which defaults it used); the hole's position has no default.

    \b
    Examples:
      deltafmi animate contact_press.csv -o robot.gif --speed 0.5
      deltafmi animate peg_in_hole.csv -o peg.gif --set hole_position=0.002,0,-1.2
    """
    from .animate import check_output, load_recording, write_animation
    from .columns import parse_settings

    check_output(output, fps, speed, size)
    rec = load_recording(result, plant, parse_settings(settings), wrist, hole)
    if rec.defaults:
        click.echo(f"not in the result, drawn with the model's defaults: {' '.join(rec.defaults)}")
    click.echo(f"wrote {write_animation(rec, output, fps, speed, size)}")
