"""Import others' FMUs from a compatibility-information tree (``deltafmi compat import FOLDER``).

Every FMU of the tree with reference results, for this machine's platform, runs through
deltafmi's master with the settings of its ``X_ref.opt`` and the inputs of its ``X_in.csv``; its
result goes into ``results/.../deltafmi/<version>/<exporting tool>/<its version>/<Model>/``:
``X_out.csv`` (the reference's variables), one status file and ``ReadMe.md``:

- ``passed``: the run reached StopTime and matches ``X_ref.csv`` (:mod:`deltafmi.apps.compat.compare`);
- ``failed``: the run failed, or its result differs from the reference;
- ``rejected``: deltafmi does not import it (FMI 1.0, an interface the FMU lacks, unreadable
  settings or reference files), the reason in the ReadMe.
"""
from __future__ import annotations

import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, List, Optional, Sequence, Tuple

import deltafmi
from deltafmi.errors import BadInput, DeltaFmiError, Interrupted
from deltafmi.files import replaced_atomically

from .compare import DEFAULT_TOLERANCE, mismatches
from .export import INTERFACE_NAMES
from .files import RefOptions, Table, read_options, read_table, write_table
from .layout import PLATFORMS, STATUSES, TOOL, ModelFolder, find_models, tree_root
from .run import run_fmu

__all__ = ["ImportResult", "import_tree"]


@dataclass(frozen=True)
class ImportResult:
    """What happened to one FMU: ``status`` is ``passed``, ``failed`` or ``rejected``."""

    entry: ModelFolder
    status: str
    reason: str
    folder: Path


def import_tree(folder: Path, results_root: Optional[Path] = None, fmi_versions: Sequence[str] = ("2.0", "3.0"),
                interfaces: Sequence[str] = ("cs", "me"), tolerance: float = DEFAULT_TOLERANCE,
                progress: Callable[[str], None] = lambda line: None) -> List[ImportResult]:
    """Import every FMU with reference results in the tree at ``folder`` (its root or its
    ``fmus`` folder) for this platform; results go under ``results_root`` (default: the tree's
    root, next to ``fmus``). ``progress`` gets one line per FMU."""
    root = tree_root(Path(folder))
    if not (root / "fmus").is_dir():
        raise BadInput(f"{folder}: no fmus/ folder (expected fmus/<FMI version>/<cs|me>/<platform>/<tool>/...)")
    results_root = Path(results_root) if results_root is not None else root
    done = []
    for entry in find_models(root):
        if entry.interface not in interfaces or entry.platform not in (PLATFORMS.get(entry.fmi_version), "linux64"):
            continue
        if entry.fmi_version not in fmi_versions and entry.fmi_version != "1.0":
            continue
        if not entry.file("_ref.csv").is_file():
            continue  # the rules ask importers to run FMUs with reference results
        result = _import_one(entry, results_root, tolerance)
        reason = result.reason.splitlines()[0] if result.reason else ""
        progress(f"{result.status:8s} {entry}" + (f": {reason}" if result.status != "passed" else ""))
        done.append(result)
    return done


def _import_one(entry: ModelFolder, results_root: Path, tolerance: float) -> ImportResult:
    out = results_root / entry.result_folder(TOOL, deltafmi.__version__).relative_to(entry.root)
    out.mkdir(parents=True, exist_ok=True)
    # an earlier import's files stay until this one's are written (an interrupted import keeps them)
    earlier_out = out / f"{entry.model}_out.csv"
    earlier_out = earlier_out.stat().st_mtime_ns if earlier_out.exists() else None
    options: Optional[RefOptions] = None
    try:
        reason = _rejection(entry)
        if reason is None:
            options = read_options(entry.file("_ref.opt"))
            reference = read_table(entry.file("_ref.csv"))
            inputs = read_table(entry.file("_in.csv")) if entry.file("_in.csv").is_file() else None
    except BadInput as exc:
        reason = exc.message
    if reason is not None or options is None:
        status = "rejected"
    else:
        status, reason = _run(entry, options, reference, inputs, out, tolerance)
    with replaced_atomically(out / "ReadMe.md") as temporary:
        temporary.write_text(_readme(entry, status, reason, options, tolerance))
    with replaced_atomically(out / status) as temporary:
        temporary.write_text("")
    for stale in STATUSES:
        if stale != status:
            (out / stale).unlink(missing_ok=True)
    written = out / f"{entry.model}_out.csv"
    if written.exists() and written.stat().st_mtime_ns == earlier_out:  # an earlier import's, not this one's
        written.unlink()
    return ImportResult(entry, status, reason or "", out)


def _run(entry: ModelFolder, options: RefOptions, reference: Table, inputs: Optional[Table], out: Path,
         tolerance: float) -> Tuple[str, str]:
    """Run the FMU, write ``X_out.csv`` and compare: (status, reason)."""
    try:
        result = run_fmu(entry.file(".fmu"), entry.interface, options, reference.names, inputs)
    except BadInput as exc:  # an input deltafmi cannot drive from the table
        return "rejected", f"{entry.file('_in.csv')}: {exc.message.removeprefix('input file: ')}"
    except Interrupted:  # Ctrl-C, SIGTERM, SIGHUP: the import stops, not this FMU
        raise
    except DeltaFmiError as exc:
        return "failed", exc.message
    except Exception as exc:  # noqa: BLE001 - whatever an FMU does wrong is a failed import, not a crash
        return "failed", f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=3)}"
    try:
        write_table(out / f"{entry.model}_out.csv", result.time, result.columns)
    except ValueError as exc:  # above the rules' 1 MB: the status stands without the file
        note = f" ({exc}: not written)"
    else:
        note = ""
    problems = mismatches(result, reference, options.stop, tolerance)
    more = f" (and {len(problems) - 5} more)" if len(problems) > 5 else ""
    return ("failed" if problems else "passed"), "; ".join(problems[:5]) + more + note


def _rejection(entry: ModelFolder) -> Optional[str]:
    """Why deltafmi does not import this FMU, or None."""
    from fmpy import read_model_description

    if entry.fmi_version == "1.0":
        return "FMI 1.0: deltafmi's master imports FMI 2.0 and 3.0 FMUs"
    try:
        md = read_model_description(str(entry.file(".fmu")), validate=False)
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions for broken archives
        return f"{entry.model}.fmu is not a readable FMU: {exc}"
    if md.fmiVersion != entry.fmi_version and not md.fmiVersion.startswith(entry.fmi_version[0] + "."):
        return f"the FMU is FMI {md.fmiVersion}, its folder says {entry.fmi_version}"
    if (md.coSimulation if entry.interface == "cs" else md.modelExchange) is None:
        return f"the FMU has no {INTERFACE_NAMES[entry.interface]} interface"
    return None


def _readme(entry: ModelFolder, status: str, reason: Optional[str], options: Optional[RefOptions],
            tolerance: float) -> str:
    lines = [f"# {entry.model}: {status}", "",
             f"Imported by {TOOL} {deltafmi.__version__} (`deltafmi compat import`) from "
             f"fmus/{entry}.", ""]
    if options is not None:
        lines += [f"One run of deltafmi's master through the FMU's {INTERFACE_NAMES[entry.interface]} "
                  + ("interface, integrated by the master's CVODE (BDF)" if entry.interface == "me"
                     else "interface")
                  + f", from StartTime {options.start:g} s to StopTime {options.stop:g} s, communication step "
                  f"{options.step:g} s" + (" (StepSize 0: span / 500)" if options.variable_step else "")
                  + f", relative tolerance RelTol {options.rel_tol:g}"
                  + (f"; inputs from `{entry.model}_in.csv` (linear between rows)" if entry.file("_in.csv").is_file()
                     else "") + ".", "",
                  f"Compared with `{entry.model}_ref.csv`: at each of its time stamps, every signal of the run "
                  f"(interpolated between its rows) within {tolerance:g} of the reference's range of the reference's "
                  "extremes within 0.5 % of the span either side (an event found a little earlier or later); the "
                  "run must reach StopTime.", ""]
    if reason:
        lines += ["## Why " + status, "", "```", reason.strip(), "```", ""]
    return "\n".join(lines)
