"""Command-line interface: ``deltafmi examples|guides|build|info|run|validate|export-ssp|plot|animate|...``.

The commands live next to what they drive (``export.commands``, ``cosim.commands``); this module
only assembles the click group.
"""
import click

from deltafmi.apps.compat.commands import compat
from deltafmi.apps.console import show_progress
from deltafmi.apps.run_commands import export_ssp, plot, run, validate
from deltafmi.apps.linearize_command import linearize
from deltafmi.apps.scope.command import scope
from deltafmi.apps.examples_command import examples
from deltafmi.apps.build_commands import build, info
from deltafmi.apps.guides import guides_command
from deltafmi.apps.studies.commands import plot_study_command, study_case, sweep
from deltafmi.apps.animation.commands import animate

__all__ = ["main"]


@click.group()
@click.version_option(package_name="deltafmi")
def main() -> None:
    """deltafmi: Python components as FMI 2.0 FMUs, and a master for closed-loop co-simulation."""
    show_progress()


for command in (examples, guides_command, build, info, run, validate, export_ssp, plot, animate, linearize, compat,
                scope):
    main.add_command(command)
for command in (sweep, plot_study_command, study_case):  # parameter studies on Dask
    main.add_command(command)
