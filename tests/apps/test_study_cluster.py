"""A study on a real Dask cluster: ``dask scheduler`` and two ``dask worker`` processes started on
127.0.0.1, each worker in its own folder with its own deltafmi cache, so nothing reaches them but
through Dask (``deltafmi sweep --scheduler``). Every case's metrics equal those of a plain
``deltafmi run`` of the same case to 1e-12; each worker holds the FMUs it was sent, by hash."""
from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from dask_processes import DASK, scheduler_address, start_process

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns as read_columns
from deltafmi.apps.studies.plan import plan_study
from deltafmi.apps.studies.spec import load_study

ROOT = Path(__file__).resolve().parents[2]
STUDY = f"""\
scenario: {ROOT / 'scenarios' / 'delta_tracking.yaml'}
vary:
  grid:
    controller.pole: [5, 11]
    plant.payload: [0.0, 3.0]
    experiment.stop: [0.4]
metrics:
  max_error: {{signal: plant.z - trajectory.r, statistic: max}}
  peak_torque: {{signal: controller.u, norm: inf, statistic: max}}
  x_leaves: {{signal: 'plant.z[1]', statistic: first_crossing, level: 0.01, direction: rising}}
  mean_error: {{signal: plant.z - trajectory.r, statistic: mean, window: {{from: 0.1}}}}
"""


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """``tcp://127.0.0.1:port`` of a scheduler with two single-threaded workers; and their caches."""
    root = tmp_path_factory.mktemp("cluster")
    info = root / "scheduler.json"
    processes = [start_process([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                         "--scheduler-file", str(info)], root / "scheduler", dict(os.environ))]
    try:
        address = scheduler_address(info, root / "scheduler" / "log.txt")
        caches = []
        for name in ("w1", "w2"):
            cache = root / name / "cache"
            caches.append(cache)
            processes.append(start_process([str(DASK), "worker", address, "--nthreads", "1", "--nworkers", "1",
                                     "--host", "127.0.0.1", "--no-dashboard", "--name", name],
                                    root / name, {**os.environ, "DELTAFMI_CACHE": str(cache)}))
        from distributed import Client

        with Client(address, timeout="600s") as client:
            client.wait_for_workers(2, timeout=600)
        yield address, caches
    finally:
        for process in processes:
            try:
                os.killpg(process.pid, signal.SIGTERM)  # the session each was started in
                process.wait(timeout=20)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                os.killpg(process.pid, signal.SIGKILL)


def test_study_on_a_scheduler_and_two_workers_equals_plain_runs(cluster, tmp_path):
    address, caches = cluster
    study = tmp_path / "gain.yaml"
    study.write_text(STUDY)
    table_path = tmp_path / "gain.parquet"
    result = CliRunner().invoke(main, ["sweep", str(study), "--scheduler", address, "-o", str(table_path)])
    assert result.exit_code == 0, result.output
    assert "4/4 cases done, 4 ok, 0 failed" in result.output and "on 2 worker(s)" in result.output
    rows = pq.read_table(table_path).to_pylist()
    assert len({row["worker"] for row in rows}) == 2  # both workers ran cases

    planned = plan_study(load_study(study))
    for row in rows:
        scenario, csv = tmp_path / f"case{row['case']}.yaml", tmp_path / f"case{row['case']}.csv"
        assert CliRunner().invoke(main, ["study-case", str(study), str(row["case"]), "-o", str(scenario)]).exit_code == 0
        ran = CliRunner().invoke(main, ["run", str(scenario), "-o", str(csv), "-q"])
        assert ran.exit_code == 0, ran.output
        columns = read_columns(csv)
        for metric in planned.plan.metrics:
            assert row[metric.name] == pytest.approx(metric.value(columns), rel=1e-12, abs=1e-12, nan_ok=False), \
                (row["case"], metric.name)

    # the workers got the FMUs from the client, by content hash, into their own caches
    for cache in caches:
        stored = sorted(p.stem for p in (cache / "study-fmus").glob("*.fmu"))
        assert stored == sorted(planned.fmu_files)
