"""CLI: ``deltafmi compat DIR`` (write the tree of our FMUs) and ``deltafmi compat import FOLDER``."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional, Tuple

import click

from deltafmi.apps.console import folder_output

from .compare import DEFAULT_TOLERANCE

__all__ = ["compat"]

_VERSIONS = {"2": ("2.0",), "3": ("3.0",), "both": ("2.0", "3.0")}
_INTERFACES = {"cs": ("cs",), "me": ("me",), "both": ("cs", "me")}


class _ExportByDefault(click.Group):
    """``compat DIR ...`` means ``compat export DIR ...``: only ``import`` is a word of its own."""

    def parse_args(self, ctx: click.Context, args: List[str]) -> List[str]:
        if args and args[0] not in self.commands and args[0] not in ("--help", "-h"):
            args = ["export", *args]
        return super().parse_args(ctx, args)


@click.group(cls=_ExportByDefault)
def compat() -> None:
    """FMI compatibility information: our FMUs with reference results, and results of importing others'.

    The tree follows the FMI Cross-Check layout (docs/compatibility.md):
    fmus/<FMI version>/<cs|me>/<platform>/<tool>/<version>/<Model>/ with <Model>.fmu, _ref.csv,
    _ref.opt, _in.csv and ReadMe.md; results/... with passed|failed|rejected, _out.csv, ReadMe.md.

    \b
    Examples:
      deltafmi compat xc                          every packaged model, FMI 2.0 and 3.0, CS and ME
      deltafmi compat xc --fmi-version 3 --models DeltaRobot,Oscillator
      deltafmi compat import fmi-cross-check      run others' FMUs through our master
    """


@compat.command("export")
@click.argument("directory", type=click.Path(file_okay=False, path_type=Path), callback=folder_output)
@click.option("--fmi-version", "fmi_version", type=click.Choice(sorted(_VERSIONS)), default="both", show_default=True)
@click.option("--interface", type=click.Choice(sorted(_INTERFACES)), default="both", show_default=True)
@click.option("--models", "models", multiple=True, metavar="NAME",
              help="A packaged model to write (repeat, or comma-separated: DeltaRobot,Oscillator); default: all.")
@click.option("--portable", is_flag=True, help="Write portable FMUs (they carry their own Python).")
def export_command(directory: Path, fmi_version: str, interface: str, models: Tuple[str, ...], portable: bool) -> None:
    """Write our packaged models into DIRECTORY/fmus/ with reference results.

    Runs each FMU through our master for its _ref.csv; every FMU passes fmpy's validation first.

    \b
    Examples:
      deltafmi compat xc
      deltafmi compat xc --fmi-version 2 --interface cs --models DeltaRobot,Oscillator
    """
    from .export import write_tree

    names = [name.strip() for text in models for name in text.split(",") if name.strip()]
    written = write_tree(directory, _VERSIONS[fmi_version], _INTERFACES[interface], names or None,
                         portable=portable, progress=click.echo)
    click.echo(f"{len(written)} model folders in {directory / 'fmus'}")


@compat.command("import")
@click.argument("folder", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--results", "results", type=click.Path(file_okay=False, path_type=Path), callback=folder_output,
              help="Root of the results/ tree to write (default: FOLDER, next to its fmus/).")
@click.option("--fmi-version", "fmi_version", type=click.Choice(sorted(_VERSIONS)), default="both", show_default=True)
@click.option("--interface", type=click.Choice(sorted(_INTERFACES)), default="both", show_default=True)
@click.option("--tolerance", type=click.FloatRange(min=0.0, min_open=True), default=DEFAULT_TOLERANCE,
              show_default=True, help="Band around each reference signal, relative to its range.")
def import_command(folder: Path, results: Optional[Path], fmi_version: str, interface: str, tolerance: float) -> None:
    """Run every FMU with reference results in FOLDER through our master; write passed/failed/rejected.

    FOLDER is a tree in the layout (its root or its fmus/ folder); FMUs for other platforms are
    left out. Exit code 1 when any import failed.

    \b
    Examples:
      deltafmi compat import fmi-cross-check
      deltafmi compat import vendor-repo --results our-results --interface me --tolerance 0.1
    """
    from .importing import import_tree

    done = import_tree(folder, results, _VERSIONS[fmi_version], _INTERFACES[interface], tolerance,
                       progress=click.echo)
    counts = {status: sum(r.status == status for r in done) for status in ("passed", "failed", "rejected")}
    click.echo(", ".join(f"{n} {status}" for status, n in counts.items()) + f" of {len(done)} FMUs")
    if counts["failed"]:
        raise SystemExit(1)
