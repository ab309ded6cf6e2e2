"""CLI commands of parameter studies: ``sweep``, ``plot-study`` and ``study-case``.

Bad input (study, scenario, FMU, option) exits with code 2 and a one-line reason after any
per-line diagnostics; a sweep whose cases fail still exits 0 (the failures are results).
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional, Sequence

import click

from deltafmi.errors import BadInput
from deltafmi.apps.console import output_folders

__all__ = ["plot_study_command", "study_case", "sweep"]


def _plan(path: str):
    """Study file -> checked :class:`~deltafmi.apps.studies.plan.PlannedStudy`; prints every diagnostic."""
    from .plan import plan_study
    from .spec import load_study

    return plan_study(load_study(path))  # a ScenarioError shows every error, one per line


def _with_threads(planned, threads: int):
    """``planned`` with its cases stepped on ``threads`` threads (the study's identity unchanged)."""
    import dataclasses

    scenario = planned.plan.scenario
    scenario = dataclasses.replace(scenario, master=dataclasses.replace(scenario.master, threads=threads))
    return dataclasses.replace(planned, plan=dataclasses.replace(planned.plan, scenario=scenario))


def _table_path(planned, output: Optional[str]) -> Path:
    path = Path(output) if output else planned.study.result_file
    suffix = path.suffix.lower()  # as deltafmi run reads a result's format: T.CSV is a CSV
    if suffix == ".csv":  # the CSV is the table's copy: -o t.csv gives t.parquet and t.csv
        return path.with_suffix(".parquet")
    return path if suffix == ".parquet" else path.with_name(path.name + ".parquet")


@click.command()
@click.argument("study")
@click.option("-o", "--output", type=click.Path(dir_okay=False), callback=output_folders,
              help="Results table (.parquet; a .csv name gives the .parquet table beside its CSV copy; "
                   "default: result.file of the study, else <study>.parquet here). The CSV copy, the journal "
                   "and the time series go next to it.")
@click.option("--scheduler", metavar="ADDRESS",
              help="A running Dask scheduler, e.g. tcp://host:8786 or tls://host:8786 (default: a local cluster).")
@click.option("--connect-timeout", type=click.FloatRange(min=0, min_open=True), default=10.0, show_default=True,
              metavar="SECONDS", help="How long to wait for a --scheduler host that does not answer "
                                      "(a refused connection fails at once).")
@click.option("--tls-ca-file", type=click.Path(exists=True, dir_okay=False),
              help="tls:// scheduler: the CA certificate that signed the scheduler's (PEM); default: Dask's "
                   "configuration distributed.comm.tls.ca-file.")
@click.option("--tls-cert", type=click.Path(exists=True, dir_okay=False),
              help="tls:// scheduler: this client's certificate (PEM); default: distributed.comm.tls.client.cert.")
@click.option("--tls-key", type=click.Path(exists=True, dir_okay=False),
              help="tls:// scheduler: this client's private key (PEM), unless --tls-cert holds it; default: "
                   "distributed.comm.tls.client.key.")
@click.option("--workers", type=click.IntRange(min=1),
              help="Worker processes of the local cluster (default: one per core).")
@click.option("--dashboard", metavar="HOST:PORT",
              help="Where the local cluster's Dask dashboard listens, and print its link (default: "
                   "127.0.0.1 on a free port, this machine only; 0.0.0.0:8787 opens it to the network).")
@click.option("--timeseries/--no-timeseries", default=None,
              help="Keep every case's recorded signals (default: result.timeseries of the study).")
@click.option("--fresh", is_flag=True,
              help="Discard earlier results of this study instead of continuing them (once the cluster answers).")
@click.option("--retry-failed", is_flag=True, help="Run again the cases that failed in an earlier run.")
@click.option("--threads", type=click.IntRange(1, 256), metavar="N",
              help="In each case, step the components that do not depend on each other on N threads (the "
                   "scenario's master.threads): those whose step runs outside Python; same results.")
@click.option("--dry-run", is_flag=True, help="Check the study and list its cases; run nothing.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary.")
def sweep(study: str, output: Optional[str], scheduler: Optional[str], connect_timeout: float,
          tls_ca_file: Optional[str], tls_cert: Optional[str], tls_key: Optional[str], workers: Optional[int],
          dashboard: Optional[str], timeseries: Optional[bool], fresh: bool, retry_failed: bool,
          threads: Optional[int], dry_run: bool, quiet: bool) -> None:
    """Run every case of the STUDY (a YAML file, or a shipped example study by name: deltafmi
    examples lists them) on a Dask cluster and tabulate the metrics.

    Each FMU is built once here and shipped to the workers, which keep it loaded and reset it
    between cases. Results are stored as cases finish: run the same command again after an
    interruption and it skips the cases already done.

    \b
    Examples:
      deltafmi sweep gain_payload
      deltafmi sweep study.yaml --scheduler tcp://10.0.0.5:8786 -o results/study.parquet
      deltafmi sweep study.yaml --scheduler tls://10.0.0.5:8786 --tls-ca-file ca.pem --tls-cert me.pem --tls-key me.key
      deltafmi sweep study.yaml --dashboard 0.0.0.0:8787
    """
    from .driver import LOCAL_DASHBOARD, dashboard_address, open_store, summary_lines, sweep_study
    from .remote import tls_security

    if scheduler is not None and workers is not None:
        raise BadInput("--workers sizes the local cluster; a cluster given with --scheduler has its own workers")
    if scheduler is not None and dashboard is not None:
        raise BadInput("--dashboard places the local cluster's dashboard; a cluster given with --scheduler "
                       "serves its own (dask scheduler --dashboard-address)")
    if scheduler is None and (tls_ca_file or tls_cert or tls_key):
        raise BadInput("--tls-ca-file, --tls-cert and --tls-key are for a cluster given with --scheduler tls://...")
    if dashboard is not None:
        dashboard_address(dashboard)  # a malformed address fails here, before any FMU is built
    security = tls_security(tls_ca_file, tls_cert, tls_key)
    if output is not None and not dry_run:  # before the FMUs are built
        from deltafmi.master.results.safe_file import check_writable
        check_writable(Path(output), "results table")
    planned = _plan(study)
    if threads is not None:
        planned = _with_threads(planned, threads)
    if not quiet:  # the scenario's warnings, once for the whole study (the cases run it unchecked)
        for warning in planned.system.warnings:
            click.echo(str(warning), err=True)
    store = open_store(planned, _table_path(planned, output),
                       planned.study.timeseries if timeseries is None else timeseries)
    if dry_run:
        pending = store.pending(planned.cases, fresh=fresh, retry_failed=retry_failed)
        click.echo(f"{study}: OK, {len(planned.cases)} cases varying {', '.join(planned.targets)}; "
                   f"metrics {', '.join(m.name for m in planned.plan.metrics)}")
        for case in planned.cases[:10]:
            click.echo(f"  case {case.id}: {case.describe()}")
        if len(planned.cases) > 10:
            click.echo(f"  ... {len(planned.cases) - 10} more")
        click.echo(f"results: {store.table} ({len(pending)} cases to run, "
                   f"{len(planned.cases) - len(pending)} done in an earlier run)")
        return
    from deltafmi.master.stepping.stop_signals import InterruptOnSignals

    with InterruptOnSignals() as signals:  # SIGINT, SIGTERM, SIGHUP: keep what finished, say so
        try:
            report = sweep_study(planned, store, fresh=fresh, retry_failed=retry_failed, scheduler=scheduler,
                                 workers=workers, security=security, connect_timeout=connect_timeout,
                                 progress=not quiet and sys.stdout.isatty(), dashboard=dashboard or LOCAL_DASHBOARD,
                                 on_dashboard=_announce if dashboard is not None and not quiet else lambda link: None,
                                 progress_lines=not quiet and not sys.stdout.isatty())
        except KeyboardInterrupt:  # while the cluster started or stopped: the journal has every finished case
            click.echo(f"interrupted: run the same command again to continue ({store.journal} keeps what finished)",
                       err=True)
            raise click.exceptions.Exit(signals.exit_code) from None
        finally:
            store.close()
        if not quiet:
            for line in summary_lines(planned, store, report, signals.received):
                click.echo(line)
    if report.interrupted:
        raise click.exceptions.Exit(signals.exit_code)


def _announce(link: str) -> None:
    """Print the dashboard's link (on stderr: stdout carries the progress bar and the summary)."""
    import importlib.util

    note = "" if importlib.util.find_spec("bokeh") else \
        " (Dask serves its pages without the dashboard's plots: pip install bokeh for them)"
    click.echo(f"Dask dashboard: {link}{note}", err=True)


@click.command("plot-study")
@click.argument("results", type=click.Path(exists=True, dir_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), callback=output_folders, required=True,
              help="Figure file (.png, .pdf, .svg).")
@click.option("-m", "--metric", "metrics", multiple=True, help="Metric to draw (repeatable; default: all).")
@click.option("--x", "x", help="Varied parameter on the horizontal axis.")
@click.option("--y", "y", help="Second varied parameter (heat map).")
@click.option("--kind", type=click.Choice(["line", "heatmap", "histogram"]),
              help="Default: line for one swept parameter, heat map for two, histogram for Monte Carlo.")
@click.option("--log", is_flag=True,
              help="Logarithmic scale (axis, or colours of a heat map) for metrics spanning more than a decade.")
@click.option("--title", default="", help="Figure title.")
@click.option("--cell", type=click.Choice(["median", "mean"]), default="median", show_default=True,
              help="Heat map: what a cell shows of the cases that share it (Monte Carlo samples at a grid point); "
              "mean of a 0/1 metric is a success rate.")
def plot_study_command(results: str, output: str, metrics: Sequence[str], x: Optional[str], y: Optional[str],
                       kind: Optional[str], log: bool, title: str, cell: str) -> None:
    """Plot the metrics of a study's RESULTS table (.parquet from deltafmi sweep).

    \b
    Examples:
      deltafmi plot-study gain_payload.parquet -o gain.png --log
      deltafmi plot-study mass_uncertainty.parquet -m steady_state_error -o mc.png
      deltafmi plot-study peg_robustness.parquet -m success --cell mean -o success_map.png
    """
    from .plot import plot_study

    path = plot_study(results, output, metrics, x, y, kind, log, title, cell)
    click.echo(f"wrote {path}")


@click.command("study-case")
@click.argument("study")
@click.argument("case", type=click.IntRange(min=0))
@click.option("-o", "--output", type=click.Path(dir_okay=False), callback=output_folders, required=True, help="Scenario file to write.")
def study_case(study: str, case: int, output: str) -> None:
    """Write CASE of STUDY as a plain scenario, to run it alone with deltafmi run.

    The scenario is the study's with the case's values set, its FMUs named by absolute path, and
    every variable the metrics need recorded.

    \b
    Example:
      deltafmi study-case gain_payload 17 -o case17.yaml && deltafmi run case17.yaml
    """
    from .export import case_scenario

    from deltafmi.files import replaced_atomically
    from deltafmi.master.results.safe_file import check_writable

    check_writable(Path(output), "scenario file")
    planned = _plan(study)
    if case >= len(planned.cases):
        raise BadInput(f"{study} has {len(planned.cases)} cases (0 to {len(planned.cases) - 1}), not case {case}")
    with replaced_atomically(Path(output)) as temporary:
        temporary.write_text(case_scenario(planned, planned.cases[case]), encoding="utf-8")
    click.echo(f"wrote {output} ({planned.cases[case].describe()})")
