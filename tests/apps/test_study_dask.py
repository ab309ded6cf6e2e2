"""Studies on a real Dask LocalCluster of two worker processes (the default of deltafmi sweep).

* every case's metrics equal those of a plain ``deltafmi run`` of the same case (exported with
  ``deltafmi study-case``) to 1e-12, and its stored time series equal the run's CSV: FMUs reset
  between cases on the workers behave as freshly instantiated ones;
* a case that fails (an unreachable start position) is recorded with its error, the others complete;
* a case that kills its worker process is retried once on the restarted worker; one that kills it
  every time is recorded as failed (KilledWorker) and the study goes on;
* ``deltafmi sweep`` interrupted with Ctrl-C keeps what finished, and running it again does only
  the rest;
* the flagship study with its FMUs built as FMI 3.0 (reset with fmi3Reset between cases) gives the
  metrics of the FMI 2.0 study (the two builds step bit for bit alike).
"""
from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pyarrow.dataset as ds
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns as read_columns
from deltafmi.apps.studies.driver import dask_client
from deltafmi.apps.studies.plan import plan_study
from deltafmi.apps.studies.spec import load_study
from signal_runs import interrupt_when

ROOT = Path(__file__).resolve().parents[2]
FLAGSHIP_STUDY = f"""\
scenario: {ROOT / 'scenarios' / 'delta_tracking.yaml'}
vary:
  zip:
    controller.pole: [5, 9, 7, 12]
    plant.payload: [0.0, 2.0, 1.0, 0.5]
    plant.z0[3]: [-1.0, -1.0, -1.6, -1.0]     # case 2 starts out of reach: initialization fails
    experiment.stop: [0.5, 0.5, 0.5, 0.6]
metrics:
  max_error: {{signal: plant.z - trajectory.r, statistic: max}}
  final_error: {{signal: plant.z - trajectory.r, statistic: final}}
  peak_torque: {{signal: controller.u, norm: inf, statistic: max}}
  rms_u1: {{signal: 'controller.u[1]', statistic: rms, window: {{from: 0.1}}}}
  z_at: {{signal: 'plant.z[3]', statistic: at, time: 0.25}}
result: {{timeseries: true}}
"""
CRASHER = '''\
"""Test component: ends its process (a Dask worker) at initialization when told to."""
import os

from deltafmi.component import Component, Experiment, Output, Parameter, State


class Crasher(Component):
    default_experiment = Experiment(stop=0.1, step=1e-2)
    crash = Parameter(0, type=int, description="0 never, 1 the first time (then marker exists), 2 always")
    marker = Parameter("", type=str, description="File recording the first crash")
    x = State(1.0, description="Decays as exp(-t)")
    y = Output(description="x")

    def initialize(self, t):
        if self.crash == 2 or (self.crash == 1 and not os.path.exists(self.marker)):
            open(self.marker, "w").close()
            os._exit(13)

    def derivatives(self, t):
        return [-self.x]

    def outputs(self, t):
        self.y = self.x
'''


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of two single-threaded worker processes, as deltafmi sweep makes it."""
    with dask_client(workers=2) as client:
        yield client.scheduler.address


def sweep(study: Path, scheduler: str, *extra: str):
    """``deltafmi sweep`` on the cluster at ``scheduler``, results next to the study."""
    table = study.with_suffix(".parquet")
    result = CliRunner().invoke(main, ["sweep", str(study), "--scheduler", scheduler, "-o", str(table), *extra])
    assert result.exit_code == 0, result.output
    return result


def plain_run_metrics(study: Path, case: int, folder: Path, planned):
    """Metrics of ``deltafmi run`` of the case exported by ``deltafmi study-case``, and its columns."""
    scenario, csv = folder / f"case{case}.yaml", folder / f"case{case}.csv"
    exported = CliRunner().invoke(main, ["study-case", str(study), str(case), "-o", str(scenario)])
    assert exported.exit_code == 0, exported.output
    ran = CliRunner().invoke(main, ["run", str(scenario), "-o", str(csv), "-q"])
    assert ran.exit_code == 0, ran.output
    columns = read_columns(csv)
    return {m.name: m.value(columns) for m in planned.plan.metrics}, columns


def test_metrics_equal_plain_runs_and_a_failing_case_is_recorded(cluster, tmp_path):
    study = tmp_path / "flagship.yaml"
    study.write_text(FLAGSHIP_STUDY)
    result = sweep(study, cluster)
    assert "4/4 cases done, 3 ok, 1 failed" in result.output
    table = pq.read_table(tmp_path / "flagship.parquet").to_pylist()
    assert [row["case"] for row in table] == [0, 1, 2, 3]
    failed = table[2]
    assert failed["status"] == "failed" and "z0" in failed["error"], failed["error"]
    assert all(math.isnan(failed[m]) for m in ("max_error", "final_error", "peak_torque"))
    assert {row["worker"] for row in table} <= set(_workers(cluster))
    csv_rows = (tmp_path / "flagship.csv").read_text().splitlines()
    assert len(csv_rows) == 5 and csv_rows[0].startswith('"case","controller.pole","plant.payload"')
    series = ds.dataset(tmp_path / "flagship.timeseries", partitioning="hive").to_table()
    planned = plan_study(load_study(study))
    for row in table:
        if row["status"] != "ok":
            continue
        plain, columns = plain_run_metrics(study, row["case"], tmp_path, planned)
        for name, value in plain.items():
            assert row[name] == pytest.approx(value, rel=1e-12, abs=1e-12), (row["case"], name)
        mine = series.filter(ds.field("case") == row["case"])
        for name, column in columns.items():
            assert np.array_equal(mine.column(name).to_numpy(), column), (row["case"], name)


def test_fmi3_study_equals_the_fmi2_study(cluster, tmp_path):
    flagship = (ROOT / "scenarios" / "delta_tracking.yaml").read_text()
    metrics = {}
    for version in (2, 3):
        (tmp_path / f"flagship{version}.yaml").write_text(f"fmi_version: {version}\n{flagship}")
        study = tmp_path / f"study{version}.yaml"
        study.write_text(textwrap.dedent(f"""\
            scenario: flagship{version}.yaml
            vary:
              zip:
                controller.pole: [5, 9, 7, 12]
                plant.payload: [0.0, 2.0, 1.0, 0.5]
                experiment.stop: [0.3, 0.3, 0.3, 0.3]
            metrics:
              max_error: {{signal: plant.z - trajectory.r, statistic: max}}
              peak_torque: {{signal: controller.u, norm: inf, statistic: max}}
              worst_status: {{signal: controller.status, statistic: max}}
            """))
        result = sweep(study, cluster)
        assert "4/4 cases done, 4 ok, 0 failed" in result.output
        metrics[version] = pq.read_table(study.with_suffix(".parquet")).select(
            ["case", "max_error", "peak_torque", "worst_status"]).to_pylist()
    assert metrics[3] == metrics[2]
    assert len({row["max_error"] for row in metrics[3]}) == 4  # the cases differ


def _workers(address: str, wait_for: int = 0):
    from distributed import Client

    with Client(address) as client:
        if wait_for:
            client.wait_for_workers(wait_for, timeout=600)
        return list(client.scheduler_info(n_workers=-1)["workers"])


def test_worker_crash_is_retried_once_then_recorded(cluster, tmp_path):
    """24 short cases: after the first results, tasks carry several cases each (batches.py), so
    the crashing cases 10 and 13 take the other cases of their tasks down with them; those run
    again alone and pass, as does case 10 (crashes once); case 13 (always) is recorded."""
    (tmp_path / "crasher.py").write_text(CRASHER)
    marker = tmp_path / "crashed-once"
    (tmp_path / "crash.yaml").write_text(textwrap.dedent("""\
        experiment: {stop: 0.1, step: 1.0e-2}
        components:
          c: {source: crasher.py, solver: {rtol: 1.0e-10}}
        outputs: [c.y]
        """))
    crash = [0] * 24
    crash[10], crash[13] = 1, 2
    markers = [str(tmp_path / "always") if c == 2 else str(marker) for c in crash]
    study = tmp_path / "crash_study.yaml"
    study.write_text(textwrap.dedent(f"""\
        scenario: crash.yaml
        vary:
          zip:
            c.crash: {crash}
            c.marker: {markers}
        metrics:
          final: {{signal: c.y, statistic: final}}
        """))
    result = sweep(study, cluster)
    rows = pq.read_table(tmp_path / "crash_study.parquet").to_pylist()
    assert [r["status"] for r in rows] == ["failed" if c == 2 else "ok" for c in crash], result.output
    assert marker.exists()  # case 10 did crash its first worker, and passed on the retry
    assert "KilledWorker" in rows[13]["error"]
    for row in rows[:13] + rows[14:]:
        assert row["final"] == pytest.approx(math.exp(-0.1), rel=1e-8)  # x' = -x, CVODE at rtol 1e-10
    assert len(_workers(cluster, wait_for=2)) == 2  # the nannies restarted the dead workers


def test_interrupted_sweep_resumes_without_redoing_cases(cluster, tmp_path):
    (tmp_path / "osc.yaml").write_text(textwrap.dedent(f"""\
        experiment: {{stop: 1.0, step: 1.0e-3}}
        components:
          osc: {{source: {ROOT / 'fmu_src' / 'oscillator.py'}, interface: ME}}
        outputs: [osc.x]
        """))
    study = tmp_path / "osc_study.yaml"
    study.write_text(textwrap.dedent("""\
        scenario: osc.yaml
        vary:
          grid:
            osc.k: {from: 20, to: 60, num: 6}
            osc.c: [0.1, 0.2]
        metrics:
          peak: {signal: osc.x, statistic: max, window: {from: 0.5}}
        """))
    journal = tmp_path / "osc_study.journal.jsonl"
    deltafmi = Path(sys.executable).parent / "deltafmi"
    temporary = tmp_path / "tmp"  # the sweep's and its workers' temporary folder
    temporary.mkdir()
    code, output, _ = interrupt_when([str(deltafmi), "sweep", str(study), "--workers", "2", "-q"],
                                     lambda: _journal_rows(journal) >= 2, signal.SIGINT, cwd=tmp_path,
                                     env={**os.environ, "TMPDIR": str(temporary)}, stderr=subprocess.STDOUT)
    assert code == 130, output
    first = _journal(journal)
    assert 2 <= len(first) < 12, output
    assert pq.read_table(tmp_path / "osc_study.parquet").num_rows == len(first)  # written on the way out
    assert list(temporary.rglob("deltafmi-pool*")) == []  # the workers' FMU folders went with them
    # the same command again (the same interpreter builds the same FMUs), on the test's cluster
    again = subprocess.run([str(deltafmi), "sweep", str(study), "--scheduler", cluster], cwd=tmp_path,
                           capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stdout + again.stderr
    assert f"12/12 cases done, 12 ok, 0 failed ({len(first)} from an earlier run); ran {12 - len(first)}" \
        in again.stdout
    second = _journal(journal)
    keys = [json.dumps(r["values"], sort_keys=True) for r in second]
    assert len(keys) == len(set(keys)) == 12  # no case ran twice
    assert second[:len(first)] == first
    assert pq.read_table(tmp_path / "osc_study.parquet").column("status").to_pylist() == ["ok"] * 12


def _journal(path: Path):
    lines = path.read_text().splitlines()[1:]
    return [json.loads(line) for line in lines if line.endswith("}")]


def _journal_rows(path: Path) -> int:
    return len(_journal(path)) if path.exists() else 0


def test_a_streamed_case_whose_result_never_came_runs_again(cluster):
    """A task that streamed its results returns their case ids only; one of them the client has
    no result of (its event lost) runs again, and the results the task did not stream are kept."""
    from distributed import Client

    from deltafmi.apps.studies.batches import Batch, Batcher
    from deltafmi.apps.studies.cases import Case
    from deltafmi.apps.studies.driver import _results
    from deltafmi.apps.studies.runner import OK, CaseResult

    cases = [Case(i, {"x": float(i)}) for i in range(3)]
    tail = CaseResult(2, {"x": 2.0}, {"m": 1.0}, OK)
    batcher = Batcher([], 1, streamed=True)
    with Client(cluster) as client:
        future = client.submit(lambda: [0, 1, tail], pure=False)
        returned = _results(future, Batch(cases), batcher, recorded={0})
    assert [r.case for r in returned] == [2]
    assert batcher and [c.id for c in batcher.next().cases] == [1]
