"""Command-line interface: ``deltafmi examples|guides|build|info|run|validate|export-ssp|plot|animate|...``.

The commands live in their own modules of :mod:`deltafmi.apps` (``run_commands``, ``build_commands``, ...); this module
assembles the click group and is the one place where a library error becomes a message and an
exit code (:func:`report`): each :class:`~deltafmi.errors.DeltaFmiError` carries its code (2 bad
input, 1 a failure, 128 + the signal for an interruption).
"""
import errno
import os
import signal
from typing import Any

import click

from deltafmi.apps.compat.commands import compat
from deltafmi.apps.console import show_progress
from deltafmi.apps.run_commands import export_ssp, plot, run, validate
from deltafmi.apps.linearize_command import linearize
from deltafmi.apps.scope.command import scope
from deltafmi.errors import DeltaFmiError
from deltafmi.apps.examples_command import examples
from deltafmi.apps.build_commands import build, info
from deltafmi.apps.export_fmu import export_fmu_command
from deltafmi.apps.guides import guides_command
from deltafmi.apps.studies.commands import plot_study_command, study_case, sweep
from deltafmi.apps.animation.commands import animate

__all__ = ["main"]


#: errors of a path the user gave (bad input, exit code 2); other OS errors are failures (1)
_PATH_ERRORS = (errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOTDIR, errno.EISDIR, errno.EEXIST, errno.ENOENT,
                errno.ENAMETOOLONG, errno.ELOOP)
#: set to 1 to see the traceback of an unexpected error instead of its one line
DEBUG_VARIABLE = "DELTAFMI_TRACEBACK"


def report(error: DeltaFmiError) -> int:
    """Print ``error`` on stderr the way the command line shows it, and return its exit code."""
    for line in error.lines():
        click.echo(line, err=True)
    return error.exit_code


def report_os_error(error: OSError) -> int:
    """An operating-system error no command turned into its own message (a folder that cannot
    be written, a file that vanished): one line naming the file; exit code 2 for a path the user
    gave, 1 otherwise (a full disk)."""
    names = [str(n) for n in (error.filename, error.filename2) if n is not None]
    where = f"{' -> '.join(names)}: " if names else ""
    click.echo(f"Error: {where}{error.strerror or error}", err=True)
    return 2 if error.errno in _PATH_ERRORS else 1


def report_unexpected(error: Exception) -> int:
    """A bug: one line that says so and how to see the traceback (exit code 1)."""
    text = " ".join(str(error).split()) or "(no message)"
    click.echo(f"Error: internal error, {type(error).__name__}: {text} (this is a bug in deltafmi; "
               f"{DEBUG_VARIABLE}=1 shows where)", err=True)
    return 1


class _Commands(click.Group):
    """The ``deltafmi`` group: an error raised by any command (while its options are read or while
    it runs) ends the process with one line and its exit code, never a traceback: a library
    error with its message and code, an OS error naming its file, anything else as a bug."""

    def invoke(self, ctx: click.Context) -> Any:
        from deltafmi.master.stepping.stop_signals import InterruptOnSignals

        signals = InterruptOnSignals(again=True)  # SIGTERM, SIGHUP outside a run's own handling: one line too
        try:
            with signals:
                return super().invoke(ctx)
        except KeyboardInterrupt:  # Ctrl-C (or a signal) while an FMU was built, a file read or written
            name = signal.Signals(signals.received).name if signals.received else "Ctrl-C"
            click.echo(f"interrupted ({name})", err=True)
            raise click.exceptions.Exit(signals.exit_code) from None
        except DeltaFmiError as error:
            raise click.exceptions.Exit(report(error)) from None
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except OSError as error:
            if os.environ.get(DEBUG_VARIABLE):
                raise
            raise click.exceptions.Exit(report_os_error(error)) from None
        except Exception as error:  # noqa: BLE001 - the last line of defence: no traceback for a user
            if os.environ.get(DEBUG_VARIABLE):
                raise
            raise click.exceptions.Exit(report_unexpected(error)) from None


@click.group(cls=_Commands)
@click.version_option(package_name="deltafmi")
def main() -> None:
    """deltafmi: Python components as FMI 2.0 FMUs, and a master for closed-loop co-simulation."""
    show_progress()


for command in (examples, guides_command, build, info, run, validate, export_ssp, export_fmu_command, plot, animate,
                linearize, compat, scope):
    main.add_command(command)
for command in (sweep, plot_study_command, study_case):  # parameter studies on Dask
    main.add_command(command)
