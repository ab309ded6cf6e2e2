"""The files of the FMI compatibility-information layout: ``X_ref.opt`` and the CSV files
(``X_ref.csv``, ``X_in.csv``, ``X_out.csv``) under the Cross-Check's CSV rules.

CSV rules (FMI Cross-Check rules 4.1, appendix B): comma separator, never at a line's end; the
first line holds the variable names in double quotes, the first of them the time; numbers as C
floating-point literals, Booleans as 0/1, no enumeration labels, no units or comments; the time
never decreases (a time written twice marks a discontinuity); at most 1 MB. An FMI 3.0 array
variable is one column holding its elements separated by spaces, as fmusim and fmpy write it.

``X_ref.opt`` lines are ``Name, value`` with StartTime, StopTime, StepSize (0: variable step) and
RelTol required; AbsTol, SolverType and OutputIntervalLength optional.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence

import numpy as np

from deltafmi.errors import BadInput
from deltafmi.files import replaced_atomically

__all__ = ["RefOptions", "Table", "read_options", "read_table", "write_options", "write_table"]

#: largest CSV file the rules allow [bytes]
MAX_CSV_BYTES = 1_000_000

REQUIRED_OPTIONS = ("StartTime", "StopTime", "StepSize", "RelTol")


@dataclass(frozen=True)
class RefOptions:
    """The settings of ``X_ref.opt``: the run that made the reference and that importers repeat."""

    start: float
    stop: float
    step: float
    rel_tol: float
    abs_tol: Optional[float] = None

    @property
    def variable_step(self) -> bool:
        """StepSize 0 means a variable-step solver."""
        return self.step == 0.0


def write_options(path: Path, options: RefOptions) -> None:
    """Write ``X_ref.opt``."""
    lines = [f"StartTime, {options.start!r}", f"StopTime, {options.stop!r}",
             f"StepSize, {options.step!r}", f"RelTol, {options.rel_tol!r}"]
    if options.abs_tol is not None:
        lines.append(f"AbsTol, {options.abs_tol!r}")
    with replaced_atomically(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def read_options(path: Path) -> RefOptions:
    """Read ``X_ref.opt``; :class:`BadInput` naming the file and line when it breaks the rules."""
    values: Dict[str, float] = {}
    for number, line in enumerate(_text(path).splitlines(), start=1):
        text = line.split("//", 1)[0].strip()
        if not text:
            continue
        name, sep, value = text.partition(",")
        if not sep:
            raise BadInput(f"{path}:{number}: expected 'Name, value', got {line.strip()!r}")
        name = name.strip()
        if name == "SolverType":  # a name, not a number; importers choose their own solver
            continue
        try:
            values[name] = float(value)
        except ValueError:
            raise BadInput(f"{path}:{number}: {name}: {value.strip()!r} is not a number") from None
    missing = [name for name in REQUIRED_OPTIONS if name not in values]
    if missing:
        raise BadInput(f"{path}: missing {', '.join(missing)} (required: {', '.join(REQUIRED_OPTIONS)})")
    options = RefOptions(values["StartTime"], values["StopTime"], values["StepSize"], values["RelTol"],
                         values.get("AbsTol"))
    if not options.start < options.stop:
        raise BadInput(f"{path}: StartTime {options.start} must be below StopTime {options.stop}")
    if not 0.0 <= options.step <= options.stop - options.start:
        raise BadInput(f"{path}: StepSize {options.step} must be in [0, StopTime - StartTime]")
    return options


@dataclass
class Table:
    """A CSV file's content: ``time`` and one array per column (2-D for an FMI 3.0 array column:
    one row per time, one column per element)."""

    time: np.ndarray
    columns: Dict[str, np.ndarray]

    @property
    def names(self) -> List[str]:
        """The column names after the time, in file order."""
        return list(self.columns)


def write_table(path: Path, time: np.ndarray, columns: Mapping[str, np.ndarray], time_name: str = "time") -> int:
    """Write a CSV under the rules; returns its size in bytes. :class:`ValueError` when the file
    would exceed the rules' 1 MB (the caller chooses fewer rows or variables)."""
    names = [time_name, *columns]
    cells: List[Sequence[str]] = [[_number(t) for t in time]]
    for name, values in columns.items():
        values = np.asarray(values)
        if values.ndim == 1:
            cells.append([_number(v) for v in values])
        else:
            cells.append([" ".join(_number(v) for v in row) for row in values])
    lines = [",".join(f'"{name}"' for name in names)]
    lines += [",".join(row) for row in zip(*cells)]
    text = "\n".join(lines) + "\n"
    if len(text) > MAX_CSV_BYTES:
        raise ValueError(f"{path.name} would be {len(text) / 1e6:.2f} MB, above the rules' 1 MB")
    with replaced_atomically(path) as tmp:
        tmp.write_text(text)
    return len(text)


def read_table(path: Path) -> Table:
    """Read a CSV written under the rules; :class:`BadInput` naming file and line otherwise."""
    rows = list(csv.reader(_text(path).splitlines()))
    if not rows or not rows[0]:
        raise BadInput(f"{path}: empty file (expected a header line of quoted variable names)")
    names = [name.strip() for name in rows[0]]
    if len(set(names)) != len(names):
        raise BadInput(f"{path}:1: a variable is named twice")
    data: List[List[List[float]]] = []
    for number, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(names):
            raise BadInput(f"{path}:{number}: {len(row)} values for {len(names)} columns")
        try:
            data.append([[float(v) for v in cell.split()] for cell in row])
        except ValueError:
            raise BadInput(f"{path}:{number}: not a number in {row}") from None
        if any(not cell for cell in data[-1]):
            raise BadInput(f"{path}:{number}: an empty value")
    if not data:
        raise BadInput(f"{path}: no data rows")
    time = np.array([row[0][0] for row in data])
    if np.any(np.diff(time) < 0):
        at = int(np.argmax(np.diff(time) < 0)) + 3
        raise BadInput(f"{path}:{at}: the time ({names[0]}) decreases")
    columns: Dict[str, np.ndarray] = {}
    for j, name in enumerate(names[1:], start=1):
        widths = {len(row[j]) for row in data}
        if len(widths) != 1:
            raise BadInput(f"{path}: column {name!r} changes its number of elements")
        values = np.array([row[j] for row in data])
        columns[name] = values[:, 0] if widths == {1} else values
    return Table(time, columns)


def _number(value: float) -> str:
    """A C floating-point literal that reads back to the same double (integers without '.0')."""
    value = float(value)
    if value.is_integer() and abs(value) < 1e15:
        return str(int(value))
    return repr(value)


def _text(path: Path) -> str:
    try:
        return Path(path).read_text()
    except FileNotFoundError:
        raise BadInput(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInput(f"{path}: cannot read it: {exc}") from None
