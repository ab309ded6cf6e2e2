"""CLI commands of the co-simulation master: ``run``, ``validate``, ``export-ssp`` and ``plot``.

``run`` and ``validate`` take a YAML scenario or an SSP 1.0 archive (``.ssp``, or a bare ``.ssd``).

Bad input (scenario, FMU, signal names) exits with code 2, a failed simulation with code 1; both
print a one-line reason after any per-line diagnostics.
"""
from __future__ import annotations

import sys
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Optional, Sequence, Tuple

import click

from deltafmi.errors import BadInput
from deltafmi.apps.console import output_folders

if TYPE_CHECKING:
    from deltafmi.master.scenario.spec import Scenario

__all__ = ["export_ssp", "load_system", "plot", "run", "validate"]


def load_system(path: str, check_fmus: bool = False, stop: Optional[float] = None,
                overrides: Optional[Callable[[Scenario], Scenario]] = None, quiet: bool = False):
    """Scenario (YAML, an SSP archive, or one FMU on its own) -> resolved system, for a command
    (it needs click's context): prints every diagnostic, raises on errors.

    Loads as :func:`deltafmi.simulate` does (:func:`.simulate.load_any`); the FMUs of an SSP
    archive are unpacked into a temporary folder that lives until the command ends. ``stop``
    stands in for an SSP without a stop time. ``overrides`` changes the loaded scenario before
    it is resolved (run options, see :mod:`.scenario.overrides`); ``quiet``: no warnings. A
    :class:`~deltafmi.errors.ScenarioError` prints every error, one per line.
    """
    from deltafmi.master.scenario.resolve import resolve_system
    from deltafmi.master.simulate import load_any

    scenario = load_any(path, click.get_current_context().with_resource(ExitStack()), stop)
    if overrides is not None:
        scenario = overrides(scenario)
    system = resolve_system(scenario, check_fmus=check_fmus)
    if not quiet:  # -q: nothing on success
        for warning in system.warnings:
            click.echo(str(warning), err=True)
    return system


#: ``--fmi-version`` of the commands that build a scenario's source: components
_FMI_VERSION = click.option("--fmi-version", type=click.Choice(["2", "3"]),
                            help="Build the scenario's source: components as FMI 2.0 or FMI 3.0 FMUs (overriding "
                                 "its fmi_version; a component's own fmi_version stays).")


def _built_as(fmi_version: Optional[str]) -> Callable[[Scenario], Scenario]:
    """The scenario override of ``--fmi-version`` (none when not given)."""
    from deltafmi.master.scenario.overrides import with_overrides
    return lambda loaded: with_overrides(loaded, fmi_version=int(fmi_version) if fmi_version else None, cli=True)


@click.command()
@click.argument("scenario")
@click.option("-o", "--output", type=click.Path(dir_okay=False), callback=output_folders,
              help="Result file: .csv, .parquet (units in its field metadata) or .mat (MATLAB); "
                   "default: result.file of the scenario, else <scenario>.csv here.")
@click.option("--set", "assignments", multiple=True, metavar="NAME=VALUE",
              help="Set a parameter or start value, e.g. controller.pole=10, plant.z0=0.1,0,-1.0 or "
                   "plant.z0[3]=-1.05 (repeatable).")
@click.option("--stop", type=float, help="Stop time [s], overriding experiment.stop.")
@click.option("--step", type=float, help="Communication step [s], overriding experiment.step.")
@click.option("--tolerance", type=float,
              help="Relative tolerance of every component's integration (ME: CVODE rtol; CS: the "
                   "tolerance of fmi2SetupExperiment), overriding their solver.rtol.")
@click.option("--allow-nan", is_flag=True, default=None,
              help="Record NaN or infinite values and go on (master.allow_nan) instead of stopping.")
@click.option("--algorithm", type=click.Choice(["gauss-seidel", "jacobi"]),
              help="Override master.algorithm.")
@click.option("--threads", type=click.IntRange(1, 256), metavar="N",
              help="Step the components that do not depend on each other within a step on N threads "
                   "(master.threads): those whose step runs outside Python (C FMUs); same results, bit for bit.")
@click.option("--record", "record", multiple=True, metavar="PATTERN",
              help="Record the variables matching PATTERN instead of the scenario's outputs: list "
                   "(repeatable), e.g. --record 'plant.z[*]' or, for one FMU, --record 'Oscillator.*'.")
@_FMI_VERSION
@click.option("--realtime/--no-realtime", default=None,
              help="Pace the run to the wall clock (master.realtime): each communication point is released at "
                   "its time; the summary and the columns realtime.lateness, realtime.busy say how well it kept up.")
@click.option("--speed", type=float, help="Simulated seconds per wall-clock second when paced (2: twice as "
                                          "fast as real time); implies --realtime.")
@click.option("--behind", type=click.Choice(["warn", "error"]),
              help="When a paced run falls a whole step behind the wall clock: warn and go on (default) or stop.")
@click.option("--replay", type=click.Path(exists=True, dir_okay=False),
              help="Take the live inputs from the results file of an earlier run of this scenario instead of "
                   "the network or the joystick: the run repeats bit for bit (not paced unless --realtime).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, no summary, no messages from the FMUs.")
@click.option("-v", "--verbose", is_flag=True,
              help="Every message of the FMUs (their debug log categories too), not only warnings and errors.")
def run(scenario: str, output: Optional[str], assignments: Tuple[str, ...], stop: Optional[float],
        step: Optional[float], tolerance: Optional[float], allow_nan: Optional[bool], algorithm: Optional[str],
        threads: Optional[int], record: Tuple[str, ...], fmi_version: Optional[str], realtime: Optional[bool],
        speed: Optional[float], behind: Optional[str], replay: Optional[str], quiet: bool, verbose: bool) -> None:
    """Run the co-simulation SCENARIO (a YAML file, an SSP archive, or one .fmu) and write its results.

    SCENARIO without a suffix is NAME.yaml in the current folder when there is one, else the
    shipped example NAME. A single FMU runs on its default experiment as fmpy's simulate does
    (Co-Simulation when it offers it), its inputs at their start values, every output recorded
    (--record: others). --set, --stop, --step, --tolerance, --algorithm, --record and
    --fmi-version (build the source: components as FMI 3.0 FMUs) change the run, not the file. A NaN or infinite value stops the run with exit code 1, naming the
    variable and the time (--allow-nan: go on). A run that fails before its first row leaves an
    earlier result file as it was.

    The FMUs' warnings and errors are shown on stderr as they log them (-v: all their messages,
    -q: none). A component that ends the simulation itself ends the run there: the results up to
    that time are written and the summary says who ended it and why. Ctrl-C stops the run: the
    rows so far stay in the result file (exit code 130). The result format follows the file's
    extension: .csv, .parquet or .mat.

    Live runs (docs/realtime.md): --realtime paces the run to the wall clock (--speed: faster or
    slower); a scenario's live: sources take inputs from UDP datagrams or a joystick while it
    runs, its streams: send signals out; --replay RESULTS repeats such a run from its results.

    \b
    Example:
      deltafmi run delta_tracking -o tracking.csv --stop 2
      deltafmi run system.ssp
      deltafmi run delta_tracking -o tracking.parquet
      deltafmi run delta_tracking --fmi-version 3
      deltafmi run delta_tracking --set controller.pole=10 --step 0.0005 --tolerance 1e-6
      deltafmi run Oscillator.fmu --set Oscillator.k=100 --stop 2
      deltafmi run Oscillator.fmu --record 'Oscillator.*'
      deltafmi run joystick_tracking --realtime -o live.csv
      deltafmi run joystick_tracking --replay live.csv -o again.csv
    """
    from deltafmi.master.results.writers import writer_for
    from deltafmi.master.scenario.overrides import parse_assignment, with_overrides
    from deltafmi.master.stepping.master import Master

    if quiet and verbose:
        raise BadInput("-q and -v contradict each other: give one")
    if output is not None and not output.strip():
        raise BadInput("-o '': an empty file name; name the result file (r.csv, r.parquet, r.mat)")
    if output:
        writer_for(output)  # an unknown extension fails before any FMU is built or run
    values = dict(parse_assignment(text) for text in assignments)

    def overrides(loaded: Scenario) -> Scenario:
        return with_overrides(loaded, values, stop=stop, step=step, tolerance=tolerance, allow_nan=allow_nan,
                              algorithm=algorithm, threads=threads, record=record or None,
                              fmi_version=int(fmi_version) if fmi_version else None,
                              realtime=False if replay and realtime is None and speed is None else realtime,
                              speed=speed, behind=behind, cli=True)

    from deltafmi.apps.console import RepeatedWarnings, progress_shown

    printer = None if quiet else _FmuMessagePrinter(verbose)
    repeated = RepeatedWarnings()
    with progress_shown(not quiet):  # -q: nothing on success, not even a first build's line
        system = load_system(scenario, stop=stop, overrides=overrides, quiet=quiet)
    master = Master(system, result=Path(output) if output else None,
                    progress=not quiet and sys.stdout.isatty(),
                    progress_lines=not quiet and not sys.stdout.isatty(),  # a log: a line every 30 s
                    warn=(lambda message: None) if quiet else repeated,
                    on_message=printer, debug_logging=verbose, replay=Path(replay) if replay else None)
    reason = ""
    try:
        summary = master.run()
    except BaseException as exc:
        reason = str(exc)
        raise
    finally:
        repeated.close()
        if printer is not None:
            printer.show_errors(reason)
    if not quiet:
        click.echo(str(summary))


_STATUS_LABELS = ("info", "warning", "discard", "error", "fatal", "pending")


class _FmuMessagePrinter:
    """An ``on_message`` for the master: an FMU's message as ``<label>: <component>: <text>`` on
    stderr; warnings and worse only, unless ``verbose`` (which adds the log category).

    Errors are held until the run ends (:meth:`show_errors`): the one a failure quotes is then
    not printed a second time above it."""

    def __init__(self, verbose: bool) -> None:
        self.verbose = verbose
        self.errors: list = []  # (line, the text's last line)
        # on a terminal the progress bar (stdout) shares the line: clear it, the bar redraws below
        self.clear = "\r\x1b[K" if sys.stdout.isatty() and sys.stderr.isatty() else ""

    def __call__(self, component: str, status: int, category: str, text: str) -> None:
        verbose = self.verbose
        if status < 1 and not verbose:
            return
        label = _STATUS_LABELS[status] if 0 <= status < len(_STATUS_LABELS) else f"status {status}"
        lines = text.strip().splitlines() or [""]
        if not verbose and "Traceback (most recent call last)" in text:  # -v shows the whole traceback
            text = f"{lines[0]}: {lines[-1].strip()} (-v shows the traceback)" if len(lines) > 1 else text
        line = f"{self.clear}{label}: {component}: " + (f"[{category}] " if verbose else "") + text
        if status >= 3:
            self.errors.append((line, lines[-1].strip()))
        else:
            click.echo(line, err=True)

    def show_errors(self, reason: str) -> None:
        """Print the errors held, but those whose text ``reason`` (the run's failure) quotes."""
        for line, last in self.errors:
            if self.verbose or not last or last not in reason:
                click.echo(line, err=True)
        self.errors = []


@click.command()
@click.argument("scenario")
@_FMI_VERSION
def validate(scenario: str, fmi_version: Optional[str]) -> None:
    """Check SCENARIO (a YAML file or an SSP archive) and its FMUs without simulating, or one FMU.

    Checks the YAML against the schema, every component, variable, connection (causality, type,
    unit, inputs driven twice, unconnected inputs, algebraic loops) and runs fmpy's validation of
    each FMU's modelDescription. Given a .fmu, runs fmpy's validation and says whether the FMU is
    portable and, if not, which Python it needs and whether this machine has it.

    \b
    Examples:
      deltafmi validate delta_tracking
      deltafmi validate build/fmus/DeltaRobot.fmu
    """
    from deltafmi.master.scenario.fmu_scenario import is_fmu

    if is_fmu(scenario):
        from deltafmi.apps.build_commands import validate_fmu_file
        validate_fmu_file(Path(scenario))
        return
    from deltafmi.master.scenario.resolve import describe

    import re
    import tempfile

    system = load_system(scenario, check_fmus=True, overrides=_built_as(fmi_version))
    # an SSP's FMUs were unpacked into a folder that is gone by now: name them inside the archive
    unpacked = re.compile(re.escape(str(Path(tempfile.gettempdir()).resolve())) + r"/deltafmi-ssp-[^/]+/")
    for line in describe(system):
        click.echo(unpacked.sub(f"{scenario}: ", line))
    click.echo(f"{scenario}: OK")


@click.command("export-ssp")
@click.argument("scenario")
@click.option("-o", "--output", type=click.Path(dir_okay=False), callback=output_folders,
              help="SSP archive to write (default: <scenario name>.ssp here).")
@_FMI_VERSION
def export_ssp(scenario: str, output: Optional[str], fmi_version: Optional[str]) -> None:
    """Pack SCENARIO and its FMUs into an SSP 1.0 archive that other tools load.

    The archive holds SystemStructure.ssd (components, connectors, connections with
    ssc:LinearTransformation for factor/offset, start values as parameter sets, start and
    stop time) and every FMU in resources/ (components given as source: are built). The
    communication step, master algorithm, ME solver options, step_multiple, recorded outputs
    and result settings travel as com.deltafmi annotations, so `deltafmi run` on the archive
    gives the samples the scenario gives.

    \b
    Example:
      deltafmi export-ssp bouncing_ball -o bouncing_ball.ssp
      deltafmi export-ssp delta_tracking --fmi-version 3 -o delta_tracking_fmi3.ssp
    """
    from deltafmi.master.ssp.write import export_ssp as write

    target = Path(output) if output else Path(Path(scenario).stem + ".ssp")
    if target.resolve() == Path(scenario).resolve():
        raise BadInput(f"{target}: that is the scenario itself; write the archive elsewhere with -o")
    from deltafmi.master.results.safe_file import check_writable
    check_writable(target, "SSP archive")
    system = load_system(scenario, overrides=_built_as(fmi_version))
    path = write(system, target)
    click.echo(f"wrote {path} ({len(system.components)} components, {len(system.links)} connections)")


@click.command()
@click.argument("result", type=click.Path(exists=True, dir_okay=False))
@click.argument("signals", nargs=-1, required=True)
@click.option("-o", "--output", type=click.Path(dir_okay=False), callback=output_folders, required=True,
              help="Figure file; its extension picks the format (.png, .pdf, .svg, ...).")
@click.option("--compare", type=click.Path(exists=True, dir_okay=False),
              help="A second result file: plot RESULT minus it, signal by signal.")
@click.option("--separate", is_flag=True, help="One subplot per signal (default: one per unit).")
@click.option("--title", default="", help="Figure title (default: the result file name).")
def plot(result: str, signals: Sequence[str], output: str, compare: Optional[str], separate: bool,
         title: str) -> None:
    """Plot SIGNALS of a RESULT file (.csv, .parquet, .mat) over time.

    A signal is a name, a pattern ('plant.z[*]', 'trajectory.r[1:3]'), an array's name
    ('plant.z': its elements) or a difference 'A - B' (spaces around the minus) of two with the
    same number of elements. Signals of different units go on different axes, differences on
    their own, each axis in a readable unit (um for a tracking error): the units come from a
    .parquet or .mat result (a .csv result has none).

    \b
    Examples:
      deltafmi plot tracking.csv 'plant.z[*]' 'trajectory.r[1:3]' -o tracking.png
      deltafmi plot tracking.parquet 'plant.z' 'trajectory.r' 'plant.z - trajectory.r' -o tracking.png
      deltafmi plot new.csv 'plant.z[*]' --compare old.csv -o change.png
    """
    from deltafmi.master.results.plot import UnknownSignal
    from deltafmi.master.results.result import plot_result

    try:
        path = plot_result(result, signals, output, separate=separate, title=title, compare=compare)
    except UnknownSignal as exc:
        raise BadInput(str(exc)) from None
    click.echo(f"wrote {path}")
