"""Study results on disk, written as cases finish, so an interrupted study keeps its work.

For ``results/gain.parquet``:

``gain.journal.jsonl``
    one JSON line per finished case, appended and flushed as it arrives (the first line names the
    study's fingerprint). It is what a re-run reads to skip finished cases, matched by their
    varied values, so a grid that grows or a Monte Carlo study asked for more samples reuses
    what is done.
``gain.parquet`` and ``gain.csv``
    the table: case, varied values, metrics, status, error, wall_time (the case on its worker),
    setup_time (loading or resetting and initializing), sim_time (stepping), worker;
    rewritten (atomically) every few seconds and at the end. The Parquet file's metadata
    (key ``deltafmi.apps.studies``) describes the study: targets and how they vary, metrics and units.
``gain.timeseries/case=<id>/part-0.parquet``
    with time series on: every case's recorded signals, a Parquet dataset partitioned by case
    (``pyarrow.dataset.dataset(path, partitioning="hive")``).
"""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence

import numpy as np
import pyarrow as pa
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

from deltafmi.errors import BadInput
from deltafmi.files import replaced_atomically

from .cases import Case, case_key
from .runner import FAILED, CaseResult

__all__ = ["ResultStore", "read_results", "study_metadata"]

METADATA_KEY = b"deltafmi.apps.studies"


def _json_line(line: bytes) -> Any:
    """A journal line's JSON value, or None when it is none (cut short, damaged, not UTF-8)."""
    try:
        return json.loads(line)
    except ValueError:  # JSONDecodeError and UnicodeDecodeError alike
        return None


def _is_row(row: Any) -> bool:
    """Whether a journal line's value is a finished case's row as :meth:`ResultStore.add` writes it."""
    if not isinstance(row, dict):
        return False
    number = (int, float, type(None))
    return (type(row.get("case")) is int and isinstance(row.get("values"), dict)
            and isinstance(row.get("metrics"), dict) and isinstance(row.get("status"), str)
            and isinstance(row.get("error", 0), (str, type(None)))
            and isinstance(row.get("wall_time", ""), number) and isinstance(row.get("setup_time", ""), number))


class ResultStore:
    """The files of one study's results (see the module docstring)."""

    def __init__(self, table: Path, fingerprint: str, targets: Sequence[str], metrics: Sequence[str],
                 metadata: Mapping[str, Any], timeseries: bool = False) -> None:
        self.table = Path(table)
        self.csv = self.table.with_suffix(".csv")
        self.journal = self.table.with_suffix(".journal.jsonl")
        self.timeseries = self.table.with_suffix(".timeseries") if timeseries else None
        self.fingerprint = fingerprint
        self.targets, self.metrics = list(targets), list(metrics)
        self.metadata = dict(metadata)
        #: finished rows by case key (the varied values)
        self.rows: Dict[str, Dict[str, Any]] = {}
        self._file: Optional[Any] = None

    # --- opening ------------------------------------------------------------------------------
    def pending(self, cases: Sequence[Case], fresh: bool = False, retry_failed: bool = False) -> List[Case]:
        """The cases :meth:`open` with the same arguments would leave to run; reads, writes nothing.

        Raises :class:`BadInput` as :meth:`open` does, so a sweep can check its result files
        before it connects to a cluster, and connect before :meth:`open` deletes anything.
        """
        rows = self._earlier(cases, fresh, retry_failed)
        return [c for c in cases if c.key not in rows]

    def open(self, cases: Sequence[Case], fresh: bool = False, retry_failed: bool = False) -> List[Case]:
        """Read what earlier runs finished and start the journal; returns the cases still to run.

        Raises :class:`BadInput` when the files belong to a different study (scenario, FMUs,
        recording or metrics changed) unless ``fresh`` (which deletes them).
        """
        rows = self._earlier(cases, fresh, retry_failed)  # every check before anything is deleted
        if fresh:
            self.delete()
        self.table.parent.mkdir(parents=True, exist_ok=True)
        if not self.journal.is_file():
            self._start_journal()
        self.rows = rows
        self._file = open(self.journal, "a")
        return [c for c in cases if c.key not in self.rows]

    def _earlier(self, cases: Sequence[Case], fresh: bool, retry_failed: bool) -> Dict[str, Dict[str, Any]]:
        """The finished rows an open would keep, checked against ``cases``."""
        rows = self._read_journal() if not fresh and self.journal.is_file() else {}
        if retry_failed:
            rows = {k: r for k, r in rows.items() if r["status"] != FAILED}
        by_key = {c.key: c for c in cases}
        if self.timeseries is not None:
            moved = [(row["case"], by_key[k].id) for k, row in rows.items()
                     if k in by_key and row["case"] != by_key[k].id]
            if moved:
                raise BadInput(f"the cases of {self.table} were numbered differently when their time series were "
                               f"written (case {moved[0][0]} is now case {moved[0][1]}): run with --fresh, or "
                               "write to another file with -o")
        return rows

    def _start_journal(self) -> None:
        with open(self.journal, "w") as file:
            file.write(json.dumps({"deltafmi_study": 1, "fingerprint": self.fingerprint}) + "\n")

    def _read_journal(self) -> Dict[str, Dict[str, Any]]:
        rows: Dict[str, Dict[str, Any]] = {}
        with open(self.journal, "rb") as file:  # a damaged line may not even be UTF-8
            lines = file.read().splitlines()
        header = _json_line(lines[0]) if lines else None
        if not isinstance(header, dict) or header.get("fingerprint") != self.fingerprint:
            raise BadInput(f"{self.table} holds results of a different study (its scenario, FMUs, recorded "
                           f"variables or metrics have changed since): write to another file with -o, or run with "
                           f"--fresh to replace them")
        for line in lines[1:]:
            row = _json_line(line)
            # the last line of a killed run may be cut short; a damaged one is no row (its case runs again)
            if _is_row(row):
                rows[case_key(row["values"])] = row
        return rows

    def delete(self) -> None:
        """Remove every file of these results."""
        for path in (self.table, self.csv, self.journal):
            if path.exists():
                path.unlink()
        folder = self.table.with_suffix(".timeseries")
        if folder.is_dir():
            shutil.rmtree(folder)

    # --- adding -------------------------------------------------------------------------------
    def add(self, result: CaseResult) -> Dict[str, Any]:
        """Record a finished case (journal line, and its time series); returns its row."""
        row = {"case": result.case, "values": result.values, "metrics": result.metrics,
               "status": result.status, "error": result.error, "wall_time": result.wall_time,
               "setup_time": result.setup_time, "sim_time": result.sim_time, "worker": result.worker}
        if self.timeseries is not None and result.timeseries is not None:
            self._write_timeseries(self.timeseries / f"case={result.case}", result.timeseries)
        if self._file is None:
            raise RuntimeError("ResultStore.add before open")
        self._file.write(json.dumps(row) + "\n")
        self._file.flush()
        self.rows[case_key(result.values)] = row
        return row

    def sync_with_journal(self) -> None:
        """Take the finished rows from the journal again: after an interruption that may have
        come between a case's journal line and its row here, the table then holds what the
        journal holds."""
        if self._file is not None:
            self._file.flush()
        self.rows = self._read_journal()

    @staticmethod
    def _write_timeseries(partition: Path, columns: Mapping[str, np.ndarray]) -> None:
        partition.mkdir(parents=True, exist_ok=True)
        table = pa.table({name: pa.array(list(column) if column.dtype == object else column)
                          for name, column in columns.items()})
        _atomic_write(partition / "part-0.parquet", lambda path: pq.write_table(table, path))

    # --- the table ----------------------------------------------------------------------------
    def write_tables(self, cases: Sequence[Case]) -> Optional[pa.Table]:
        """Write the Parquet table and its CSV copy of the finished cases among ``cases``."""
        rows = []
        for case in cases:
            row = self.rows.get(case.key)
            if row is not None:
                rows.append({**row, "case": case.id})
        table = self.build_table(rows)
        _atomic_write(self.table, lambda path: pq.write_table(table, path))
        _atomic_write(self.csv, lambda path: pa_csv.write_csv(table, path))
        return table

    def build_table(self, rows: Sequence[Mapping[str, Any]]) -> pa.Table:
        """The results table of ``rows`` (journal rows), with the study's metadata."""
        columns: Dict[str, pa.Array] = {"case": pa.array([r["case"] for r in rows], pa.int64())}
        for name in self.targets:
            columns[name] = _column([r["values"].get(name) for r in rows])
        for name in self.metrics:
            columns[name] = pa.array([_number(r["metrics"].get(name)) for r in rows], pa.float64())
        columns["status"] = pa.array([r["status"] for r in rows], pa.string())
        columns["error"] = pa.array([r["error"] for r in rows], pa.string())
        columns["wall_time"] = pa.array([r["wall_time"] for r in rows], pa.float64())
        columns["setup_time"] = pa.array([r["setup_time"] for r in rows], pa.float64())
        columns["sim_time"] = pa.array([r.get("sim_time", math.nan) for r in rows], pa.float64())
        columns["worker"] = pa.array([r.get("worker", "") for r in rows], pa.string())
        table = pa.table(columns)
        return table.replace_schema_metadata({METADATA_KEY: json.dumps(self.metadata).encode()})

    def close(self) -> None:
        """Close the journal."""
        if self._file is not None:
            self._file.close()
            self._file = None


def read_results(path: str | Path) -> pa.Table:
    """A study's results table (Parquet). Raises :class:`BadInput` when it cannot be read."""
    try:
        return pq.read_table(path)
    except (OSError, pa.ArrowException) as exc:
        raise BadInput(f"cannot read '{path}' as a study's results (Parquet): {exc}") from None


def study_metadata(table: pa.Table) -> Dict[str, Any]:
    """The study description stored with a results table ({} when absent)."""
    raw = (table.schema.metadata or {}).get(METADATA_KEY)
    return json.loads(raw) if raw else {}


def _column(values: List[Any]) -> pa.Array:
    try:
        return pa.array(values)
    except (pa.ArrowInvalid, pa.ArrowTypeError):  # mixed types: keep them readable
        return pa.array([None if v is None else str(v) for v in values], pa.string())


def _number(value: Any) -> float:
    return math.nan if value is None else float(value)


def _atomic_write(path: Path, write: Any) -> None:
    with replaced_atomically(path) as temporary:
        write(str(temporary))
