"""Command-line interface: ``deltafmi examples|guides|build|info|run|validate|export-ssp|plot|animate|...``.

The commands live in their own modules of :mod:`deltafmi.apps` (``run_commands``, ``build_commands``, ...); this module
assembles the click group and is the one place where a library error becomes a message and an
exit code (:func:`report`): each :class:`~deltafmi.errors.DeltaFmiError` carries its code (2 bad
input, 1 a failure, 128 + the signal for an interruption).
"""
from __future__ import annotations

import atexit
import contextlib
import errno
import gc
import importlib
import os
import signal
import sys
from typing import TYPE_CHECKING, Any, Dict, Iterator, List, Optional, Tuple

import click

from deltafmi.apps.console import show_progress

if TYPE_CHECKING:
    from deltafmi.errors import DeltaFmiError

__all__ = ["COMMANDS", "main"]


#: errors of a path the user gave (bad input, exit code 2); other OS errors are failures (1)
_PATH_ERRORS = (errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOTDIR, errno.EISDIR, errno.EEXIST, errno.ENOENT,
                errno.ENAMETOOLONG, errno.ELOOP)
#: command name -> (module, attribute, first paragraph of its help): a command's module is imported
#: only when that command runs (or its own --help is asked), so that ``deltafmi --help`` and a
#: command pay for no other command's imports (Dask, matplotlib, the builder, the compatibility
#: trees); tests/apps/test_cli_lazy.py checks each paragraph against the command's docstring
COMMANDS: Dict[str, Tuple[str, str, str]] = {
    "animate": ("deltafmi.apps.animation.commands", "animate",
        'Draw the delta robot of RESULT (.csv, .parquet, .mat) frame by frame: arms, plate, tool, surface.'),
    "build": ("deltafmi.apps.build_commands", "build",
        'Build FMUs (Model Exchange + Co-Simulation) from components.'),
    "compat": ("deltafmi.apps.compat.commands", "compat",
        "FMI compatibility information: our FMUs with reference results, and results of importing others'."),
    "examples": ("deltafmi.apps.examples_command", "examples",
        'The example scenarios and studies shipped with deltafmi.'),
    "export-fmu": ("deltafmi.apps.export_fmu", "export_fmu_command",
        'Export SCENARIO (a shipped example\'s name or a YAML file) as one Co-Simulation FMU.'),
    "export-ssp": ("deltafmi.apps.run_commands", "export_ssp",
        'Pack SCENARIO and its FMUs into an SSP 1.0 archive that other tools load.'),
    "guides": ("deltafmi.apps.guides", "guides_command",
        'Where the guides are (Markdown files: the Python API, writing a component, scenarios, studies, '
        'troubleshooting, ...), each with its title.'),
    "info": ("deltafmi.apps.build_commands", "info",
        "Show an FMU's interfaces, default experiment and variables."),
    "linearize": ("deltafmi.apps.linearize_command", "linearize",
        'Linearize TARGET: an FMU (.fmu, or a component source .py) or a scenario (.yaml, .ssp).'),
    "plot": ("deltafmi.apps.run_commands", "plot",
        'Plot SIGNALS of a RESULT file (.csv, .parquet, .mat) over time.'),
    "plot-study": ("deltafmi.apps.studies.commands", "plot_study_command",
        "Plot the metrics of a study's RESULTS table (.parquet from deltafmi sweep)."),
    "run": ("deltafmi.apps.run_commands", "run",
        'Run the co-simulation SCENARIO (a YAML file, an SSP archive, or one .fmu) and write its results.'),
    "scope": ("deltafmi.apps.scope.command", "scope",
        'Live plot of the signals a run streams as DFMI datagrams (a `streams:` entry `udp:` of a scenario, '
        'or any program that sends them).'),
    "study-case": ("deltafmi.apps.studies.commands", "study_case",
        'Write CASE of STUDY as a plain scenario, to run it alone with deltafmi run.'),
    "sweep": ("deltafmi.apps.studies.commands", "sweep",
        'Run every case of the STUDY (a YAML file, or a shipped example study by name: deltafmi examples '
        'lists them) on a Dask cluster and tabulate the metrics.'),
    "validate": ("deltafmi.apps.run_commands", "validate",
        'Check SCENARIO (a YAML file or an SSP archive) and its FMUs without simulating, or one FMU.'),
}
#: the young generation's collection threshold while a command runs (Python's default: 700)
_GC_THRESHOLD = 50_000
#: set to 1 to see the traceback of an unexpected error instead of its one line
DEBUG_VARIABLE = "DELTAFMI_TRACEBACK"


def report(error: "DeltaFmiError") -> int:
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
    error with its message and code, an OS error naming its file, anything else as a bug.

    Its commands are :data:`COMMANDS`, each imported when first asked for."""

    def list_commands(self, ctx: click.Context) -> List[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> Optional[click.Command]:
        if cmd_name not in COMMANDS:
            return None
        module, attribute, _ = COMMANDS[cmd_name]
        return getattr(importlib.import_module(module), attribute)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command list of ``deltafmi --help`` from :data:`COMMANDS`, importing none of them."""
        limit = formatter.width - 6 - max(map(len, COMMANDS))
        rows = [(name, click.Command(name, help=COMMANDS[name][2]).get_short_help_str(limit)) for name in sorted(COMMANDS)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def invoke(self, ctx: click.Context) -> Any:
        from deltafmi.master.stepping.stop_signals import InterruptOnSignals

        # A command's start creates a few hundred thousand objects that live until it exits
        # (modules, classes, functions of the imports, the FMUs' models): at the default threshold
        # (700 allocations) the young collections walk them again and again, and the interpreter's
        # last collections at exit walk them all once more. Cycles still get collected while the
        # command runs, less often; at exit the memory goes back to the system whole.
        gc.set_threshold(_GC_THRESHOLD, *gc.get_threshold()[1:])
        atexit.unregister(gc.freeze)
        atexit.register(gc.freeze)
        signals = InterruptOnSignals(again=True)  # SIGTERM, SIGHUP outside a run's own handling: one line too
        try:
            with signals, _quiet_swallowed_interrupts():
                result = super().invoke(ctx)
            if signals.received:
                # the KeyboardInterrupt was swallowed where Python cannot pass it on (a __del__,
                # a callback from C): the command went on, but it was asked to stop
                raise KeyboardInterrupt
            return result
        except KeyboardInterrupt:  # Ctrl-C (or a signal) while an FMU was built, a file read or written
            name = signal.Signals(signals.received).name if signals.received else "Ctrl-C"
            click.echo(f"interrupted ({name})", err=True)
            raise click.exceptions.Exit(signals.exit_code) from None
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except Exception as error:  # noqa: BLE001 - the last line of defence: no traceback for a user
            raise click.exceptions.Exit(_reported(error)) from None


@contextlib.contextmanager
def _quiet_swallowed_interrupts() -> Iterator[None]:
    """No "Exception ignored ... Traceback ... KeyboardInterrupt" for a signal that arrived in a
    ``__del__`` or a callback from C: the command's signal handling has noted it and ends the
    command as interrupted; other unraisable exceptions are reported as before."""
    previous = sys.unraisablehook

    def hook(unraisable: Any) -> None:
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):
            previous(unraisable)

    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous


def _reported(error: Exception) -> int:
    """Show ``error`` as :class:`_Commands` does and return its exit code (raise it again, with its
    traceback, when :data:`DEBUG_VARIABLE` asks for that and it is no library error)."""
    library = sys.modules.get("deltafmi.runtime.errors")  # not imported: no library error can have been raised
    if library is not None and isinstance(error, library.DeltaFmiError):
        return report(error)
    if isinstance(error, BrokenPipeError) and _reader_gone():
        # `deltafmi info X.fmu | head -1`: the reader took what it wanted; end as a shell's tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # Python's last flush: nowhere
        return 128 + signal.SIGPIPE
    if os.environ.get(DEBUG_VARIABLE):
        raise error
    return report_os_error(error) if isinstance(error, OSError) else report_unexpected(error)


def _reader_gone() -> bool:
    """Whether the reader of stdout (a pipe) has closed it."""
    import select

    try:
        poll = select.poll()
        poll.register(sys.stdout.fileno(), select.POLLOUT)
        return any(events & select.POLLERR for _, events in poll.poll(0))
    except (OSError, ValueError):  # no stdout, or not a file (a test's captured output)
        return False


@click.group(cls=_Commands)
@click.version_option(package_name="deltafmi")
def main() -> None:
    """deltafmi: Python components as FMI 2.0 FMUs, and a master for closed-loop co-simulation."""
    show_progress()
