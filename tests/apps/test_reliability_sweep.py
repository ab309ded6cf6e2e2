"""A sweep stopped by SIGINT, SIGTERM or SIGHUP (a real ``deltafmi sweep`` on a local Dask cluster)
keeps what finished: its table and its journal hold the same cases, the summary says so, and it
exits 128 + the signal; one started in the background of a script (SIGINT ignored) stops on SIGINT
as ``run`` does; without a terminal it prints progress lines."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from signal_runs import interrupt_when

ROOT = Path(__file__).resolve().parents[2]
DELTAFMI = Path(sys.executable).parent / "deltafmi"


def _journal(path: Path) -> list:
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines()[1:] if line.endswith("}")]


@pytest.fixture
def study(tmp_path) -> Path:
    (tmp_path / "osc.yaml").write_text(textwrap.dedent(f"""\
        experiment: {{stop: 2.0, step: 1.0e-3}}
        components:
          osc: {{source: {ROOT / 'fmu_src' / 'oscillator.py'}, interface: ME}}
        outputs: [osc.x]
        """))
    path = tmp_path / "osc_study.yaml"
    path.write_text(textwrap.dedent("""\
        scenario: osc.yaml
        vary:
          grid:
            osc.k: {from: 20, to: 60, num: 40}
            osc.c: [0.1, 0.2]
        metrics:
          peak: {signal: osc.x, statistic: max, window: {from: 0.5}}
        """))
    return path


def _no_sigint() -> None:
    """What a shell does to a command started with ``&`` in a script."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@pytest.mark.parametrize("signum, background", [(signal.SIGTERM, False), (signal.SIGHUP, False),
                                                (signal.SIGINT, True)])
def test_a_stopped_sweep_keeps_the_same_cases_in_its_table_and_its_journal(study, tmp_path, signum, background):
    journal = tmp_path / "osc_study.journal.jsonl"
    code, output, _ = interrupt_when([str(DELTAFMI), "sweep", str(study), "--workers", "1"],
                                     lambda: len(_journal(journal)) >= 2, signum, cwd=tmp_path,
                                     stderr=subprocess.STDOUT, preexec_fn=_no_sigint if background else None)
    assert code == 128 + signum, output
    assert "Traceback" not in output
    kept = _journal(journal)
    assert 2 <= len(kept) < 80, output
    table = pq.read_table(tmp_path / "osc_study.parquet").to_pylist()
    assert sorted(r["case"] for r in table) == sorted(r["case"] for r in kept)  # the same cases, both
    name = signal.Signals(signum).name
    assert (f"interrupted by {name}: the {len(kept)} cases done are kept, in osc_study.parquet "
            f"and osc_study.journal.jsonl alike; run the same command again") in output, output


def test_a_sweep_without_a_terminal_prints_progress_lines(study, tmp_path, monkeypatch):
    from deltafmi.apps.studies import driver

    import io
    stream = io.StringIO()
    progress = driver.StudyProgress(80, 0, False, stream, lines=True)
    progress._next = 0.0  # the first line is due
    from deltafmi.apps.studies.runner import CaseResult
    progress.add(CaseResult(0, {}, {}, "ok", ""))
    progress.add(CaseResult(1, {}, {}, "failed", "x"))  # within LINE_EVERY of the first: no line
    progress.close()
    lines = stream.getvalue().splitlines()
    assert len(lines) == 1 and lines[0].startswith("1/80 cases, 0 failed, ") and "\r" not in stream.getvalue()
    assert driver.LINE_EVERY >= 10  # a modest rate: a line every few tens of seconds
