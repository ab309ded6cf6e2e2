"""Write deltafmi's exported FMUs into a compatibility-information tree (``deltafmi compat DIR``).

Per packaged model, FMI version and interface: the FMU, ``X_in.csv`` when the model has inputs,
``X_ref.opt``, ``X_ref.csv`` (deltafmi's master running that FMU through that interface: its own
CVODE for Model Exchange, the FMU's solver for Co-Simulation) and ``ReadMe.md``. Every FMU passes
fmpy's validation before it goes into the tree.
"""
from __future__ import annotations

import inspect
import shutil
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence

import numpy as np

import deltafmi
from deltafmi.errors import BadInput
from deltafmi.files import replaced_atomically

from .cases import Case, case_for
from .files import RefOptions, Table, write_options, write_table
from .layout import PLATFORMS, TOOL, ModelFolder
from .run import run_fmu

__all__ = ["INTERFACE_NAMES", "write_tree"]

INTERFACE_NAMES = {"cs": "Co-Simulation", "me": "Model Exchange"}


def write_tree(root: Path, fmi_versions: Sequence[str] = ("2.0", "3.0"), interfaces: Sequence[str] = ("cs", "me"),
               models: Optional[Sequence[str]] = None, portable: bool = False,
               progress: Callable[[str], None] = lambda line: None) -> List[ModelFolder]:
    """Write the exported-FMU part of the tree under ``root`` for ``models`` (default: every
    packaged model) in ``fmi_versions`` (``"2.0"``, ``"3.0"``) and ``interfaces`` (``"cs"``,
    ``"me"``); returns the model folders written. ``progress`` gets one line per folder."""
    from deltafmi.models import MODELS

    unknown = [m for m in models or () if m not in MODELS]
    if unknown:
        raise BadInput(f"{', '.join(unknown)}: not a packaged model (known: {', '.join(sorted(MODELS))})")
    written = []
    for model in models or sorted(MODELS):
        for version in fmi_versions:
            fmu = _build(model, version, portable)
            _check_valid(fmu)
            from fmpy import read_model_description
            md = read_model_description(str(fmu), validate=False)
            case = case_for(model, md)
            options = RefOptions(case.start, case.stop, case.step, case.tolerance)
            inputs = _input_table(case, md)
            names = [name for base in case.record for name in _fmi_names(md, base)]
            for interface in interfaces:
                if (md.coSimulation if interface == "cs" else md.modelExchange) is None:
                    continue
                entry = ModelFolder(root, version, interface, PLATFORMS[version], TOOL, deltafmi.__version__, fmu.stem)
                _write_model(entry, fmu, md, options, inputs, names, portable)
                progress(f"wrote {entry.folder}")
                written.append(entry)
    return written


def _write_model(entry: ModelFolder, fmu: Path, md: Any, options: RefOptions, inputs: Optional[Table],
                 names: List[str], portable: bool) -> None:
    entry.folder.mkdir(parents=True, exist_ok=True)
    with replaced_atomically(entry.file(".fmu")) as temporary:
        shutil.copyfile(fmu, temporary)
    if inputs is not None:
        write_table(entry.file("_in.csv"), inputs.time, inputs.columns)
    elif entry.file("_in.csv").exists():
        entry.file("_in.csv").unlink()
    write_options(entry.file("_ref.opt"), options)
    reference = run_fmu(entry.file(".fmu"), entry.interface, options, names, inputs)
    write_table(entry.file("_ref.csv"), reference.time, reference.columns)
    with replaced_atomically(entry.folder / "ReadMe.md") as temporary:
        temporary.write_text(_readme(entry, md, options, inputs, names, portable))


def _build(model: str, version: str, portable: bool) -> Path:
    from deltafmi.toolchain import BuildError
    from deltafmi.builder.packager import build_cached

    try:
        if version == "2.0":
            return build_cached(model, portable=portable)
        if "fmi_version" not in inspect.signature(build_cached).parameters:
            raise BadInput("FMI 3.0: this deltafmi does not export FMI 3.0 yet")
        return build_cached(model, portable=portable, fmi_version=3)  # type: ignore[call-arg]
    except BuildError as exc:
        raise BadInput(f"{model}: {exc}") from None


def _check_valid(fmu: Path) -> None:
    from fmpy.validation import validate_fmu

    problems = validate_fmu(str(fmu))
    if problems:
        raise BadInput(f"{fmu}: fmpy's validation found problems: {'; '.join(problems)}")


def _fmi_names(md: Any, base: str) -> List[str]:
    """The FMI variables of the declaration ``base``: itself (a scalar, or an FMI 3.0 array),
    or its elements ``base[1]``, ``base[2]``, ... (FMI 2.0)."""
    names = [v.name for v in md.modelVariables]
    if base in names:
        return [base]
    elements = [name for name in names if name.startswith(base + "[") and name[len(base) + 1:-1].isdigit()]
    if not elements:
        raise BadInput(f"{md.modelName}: no variable {base!r} to record")
    return sorted(elements, key=lambda name: int(name[len(base) + 1:-1]))


def _input_table(case: Case, md: Any) -> Optional[Table]:
    """``X_in.csv``'s content: every input of the FMU, on the communication grid (but Clocks and
    Binaries, which no CSV value stands for: an FMI 3.0 model's periodic Clock ticks by itself)."""
    inputs = [v for v in md.modelVariables if v.causality == "input" and v.type not in ("Clock", "Binary")]
    if not inputs:
        return None
    n = int(round((case.stop - case.start) / case.step))
    t = case.start + case.step * np.arange(n + 1)
    given = case.inputs(t) if case.inputs else {}
    columns: Dict[str, np.ndarray] = {}
    for variable in inputs:
        base, _, index = variable.name.partition("[")
        signal = given.get(base)
        if signal is not None and np.ndim(signal) == 2 and index:
            columns[variable.name] = np.asarray(signal)[:, int(index[:-1]) - 1]
        elif signal is not None:
            columns[variable.name] = np.asarray(signal)
        else:
            words = str(variable.start if variable.start is not None else 0).split()
            start = np.array([float({"true": 1, "false": 0}.get(word, word)) for word in words])
            columns[variable.name] = np.tile(start, (len(t), 1)) if len(start) > 1 else np.full(len(t), start[0])
    return Table(t, columns)


def _readme(entry: ModelFolder, md: Any, options: RefOptions, inputs: Optional[Table], names: List[str],
            portable: bool) -> str:
    from deltafmi.builder.requirements import runtime_requirement

    solver = ("deltafmi's master integrating the FMU with CVODE (BDF, relative tolerance RelTol"
              + ("; communicating every StepSize / 10, each input held at its value in the middle of "
                 "that step" if inputs is not None else "") + ")"
              if entry.interface == "me" else
              "deltafmi's master stepping the FMU (its own solver, relative tolerance RelTol) every StepSize")
    lines = [
        f"# {entry.model}", "",
        md.description or "", "",
        f"Exported by {TOOL} {deltafmi.__version__} as an FMI {entry.fmi_version} FMU "
        f"({', '.join(n for k, n in INTERFACE_NAMES.items() if (md.coSimulation if k == 'cs' else md.modelExchange))}"
        f" in one binary); this folder is its {INTERFACE_NAMES[entry.interface]} test.", "",
        "## Reference results", "",
        f"`{entry.model}_ref.csv` comes from {solver}, from StartTime {options.start:g} s to StopTime "
        f"{options.stop:g} s, one row per StepSize {options.step:g} s (two rows with one time stamp at an event), "
        f"RelTol {options.rel_tol:g}. Variables: {', '.join(f'`{n}`' for n in names)}.", "",
    ]
    if inputs is not None:
        lines += [f"`{entry.model}_in.csv` gives every input on the same grid: linear interpolation between "
                  "its rows reproduces the signals the reference run saw at the communication points.", ""]
    lines += [
        "## Running it", "",
        *[f"- {line}" for line in runtime_requirement(entry.file(".fmu")).describe()
          if not line.startswith("this machine")],  # the machine that wrote the tree is no reader's
        "- Checked with fmpy's validation (no problems) before it went into this folder.",
        "- Regenerate: `deltafmi compat DIR --fmi-version "
        f"{entry.fmi_version[0]} --interface {entry.interface} --models {entry.model}"
        f"{' --portable' if portable else ''}`.", "",
    ]
    return "\n".join(lines)
