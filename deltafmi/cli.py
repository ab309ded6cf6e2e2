"""Command-line interface: ``deltafmi examples|guides|build|info|run|validate|export-ssp|plot|animate|...``.

The commands live next to what they drive (``export.commands``, ``cosim.commands``); this module
assembles the click group and is the one place where a library error becomes a message and an
exit code (:func:`report`): each :class:`~deltafmi.errors.DeltaFmiError` carries its code (2 bad
input, 1 a failure, 128 + the signal for an interruption).
"""
from typing import Any

import click

from deltafmi.compat.commands import compat
from deltafmi.console import show_progress
from deltafmi.cosim.commands import export_ssp, plot, run, validate
from deltafmi.cosim.linearize.commands import linearize
from deltafmi.cosim.live.scope_commands import scope
from deltafmi.errors import DeltaFmiError
from deltafmi.examples.commands import examples
from deltafmi.export.commands import build, info
from deltafmi.guides import guides_command
from deltafmi.study.commands import plot_study_command, study_case, sweep
from deltafmi.viz.commands import animate


def report(error: DeltaFmiError) -> int:
    """Print ``error`` on stderr the way the command line shows it, and return its exit code."""
    for line in error.lines():
        click.echo(line, err=True)
    return error.exit_code


class _Commands(click.Group):
    """The ``deltafmi`` group: a library error raised by any command (while its options are read
    or while it runs) ends the process with its message and its exit code, never a traceback."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except DeltaFmiError as error:
            raise click.exceptions.Exit(report(error)) from None


@click.group(cls=_Commands)
@click.version_option(package_name="deltafmi")
def main() -> None:
    """deltafmi: Python components as FMI 2.0 FMUs, and a master for closed-loop co-simulation."""
    show_progress()


for command in (examples, guides_command, build, info, run, validate, export_ssp, plot, animate, linearize, compat,
                scope):
    main.add_command(command)
for command in (sweep, plot_study_command, study_case):  # parameter studies on Dask
    main.add_command(command)
