"""The rough edges of ``deltafmi sweep`` a new user meets (issue 30):

* a shipped study is named, not found by path, from any folder, and its results land in the
  working folder, never inside the installed package;
* ``--fresh`` against a scheduler that refuses the connection changes no file of the earlier
  results, and says so in one line naming the address (exit 2, no traceback); against a cluster
  that answers it does discard them;
* a sweep leaves no ``deltafmi-pool-*`` folder behind;
* the scenario's warnings (an unconnected input) show once per study, not once per case.
"""
from __future__ import annotations

import math
import os
import socket
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.shipped import STUDIES_DIR
from oscillator_study import check_closed_form, write_study

DELTAFMI = Path(sys.executable).parent / "deltafmi"


def _earlier_results(folder: Path) -> dict:
    """Files standing for the results of an earlier sweep: {path: bytes}."""
    files = {folder / "osc_study.parquet": b"PAR1 earlier table",
             folder / "osc_study.csv": b'"case","osc.k"\n0,20\n',
             folder / "osc_study.journal.jsonl": b'{"deltafmi_study": 1, "fingerprint": "earlier"}\n',
             folder / "osc_study.timeseries" / "case=0" / "part-0.parquet": b"PAR1 earlier series"}
    for path, data in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return files


def _refused_address() -> str:
    """tcp://127.0.0.1:PORT where nothing listens (a port just bound and released)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    return f"tcp://127.0.0.1:{port}"


def test_shipped_study_by_name_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    shipped = sorted(p.name for p in STUDIES_DIR.iterdir())
    runner = CliRunner()
    dry = runner.invoke(main, ["sweep", "gain_payload", "--dry-run"])
    assert dry.exit_code == 0, dry.output
    assert "gain_payload: OK, 91 cases varying controller.pole, plant.payload" in dry.output
    assert "results: gain_payload.parquet (91 cases to run, 0 done in an earlier run)" in dry.output

    case = runner.invoke(main, ["study-case", "gain_payload", "3", "-o", "x.yaml"])
    assert case.exit_code == 0, case.output
    assert "wrote x.yaml (controller.pole=3, plant.payload=3)" in case.output
    scenario = yaml.safe_load((tmp_path / "x.yaml").read_text())
    assert scenario["components"]["controller"]["parameters"]["pole"] == 3
    assert scenario["components"]["plant"]["parameters"]["payload"] == 3
    assert all(Path(c["fmu"]).is_absolute() for c in scenario["components"].values())

    wrong = runner.invoke(main, ["sweep", "delta_tracking"])
    assert wrong.exit_code == 2 and "'delta_tracking' is an example scenario, not a study" in wrong.output
    assert sorted(p.name for p in STUDIES_DIR.iterdir()) == shipped  # nothing written into the package


def test_fresh_against_a_refused_scheduler_keeps_earlier_results(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    study = write_study(tmp_path)
    earlier = _earlier_results(tmp_path)
    address = _refused_address()
    result = CliRunner().invoke(main, ["sweep", str(study), "--fresh", "--scheduler", address])
    assert result.exit_code == 2, result.output
    for path, data in earlier.items():
        assert path.read_bytes() == data, path  # bit-identical
    last = result.output.strip().splitlines()[-1]
    assert last == (f"Error: cannot reach the Dask scheduler at {address}: connection refused (no scheduler "
                    f"listens on port {address.rsplit(':', 1)[1]} of 127.0.0.1; is `dask scheduler` running there?)")
    assert "Traceback" not in result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["osc.yaml", "osc_study.yaml", "osc_study.parquet", "osc_study.csv", "osc_study.journal.jsonl",
         "osc_study.timeseries"])


def test_a_server_that_is_no_dask_scheduler(tmp_path):
    """Something answers at the address, but not Dask (here: an HTTP server's error replies)."""
    study = write_study(tmp_path)
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()

    def answer() -> None:
        with server:
            while True:
                try:
                    connection, _ = server.accept()
                except OSError:
                    return
                with connection:
                    connection.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4)

    thread = threading.Thread(target=answer, daemon=True)
    thread.start()
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    try:
        result = CliRunner().invoke(main, ["sweep", str(study), "--scheduler", address, "--connect-timeout", "5"])
    finally:
        server.close()
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines()[-1].startswith(
        f"Error: cannot connect to the Dask scheduler at {address}: what answers there is no Dask scheduler")
    assert not (tmp_path / "osc_study.journal.jsonl").exists()


def test_tls_options_need_a_tls_scheduler(tmp_path):
    study = write_study(tmp_path)
    ca = tmp_path / "ca.pem"
    ca.write_text("not read")
    local = CliRunner().invoke(main, ["sweep", str(study), "--tls-ca-file", str(ca), "--tls-cert", str(ca)])
    assert local.exit_code == 2 and "are for a cluster given with --scheduler tls://" in local.output
    tcp = CliRunner().invoke(main, ["sweep", str(study), "--scheduler", _refused_address(), "--tls-ca-file", str(ca)])
    assert tcp.exit_code == 2 and "--tls-ca-file and --tls-cert go together" in tcp.output


def test_fresh_sweep_on_a_local_cluster_discards_warns_once_and_leaves_no_pool_folder(tmp_path):
    study = write_study(tmp_path)
    _earlier_results(tmp_path)
    temporary = tmp_path / "tmp"  # the sweep's and its workers' temporary folder: what is left there is theirs
    temporary.mkdir()
    done = subprocess.run([str(DELTAFMI), "sweep", str(study), "--fresh", "--workers", "2"], cwd=tmp_path,
                          env={**os.environ, "TMPDIR": str(temporary)}, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "3/3 cases done, 3 ok, 0 failed (0 from an earlier run)" in done.stdout
    # the scenario leaves osc.F unconnected: said once for the study, not once per case
    assert done.stderr.count("not connected") == 1, done.stderr
    assert not (tmp_path / "osc_study.timeseries").exists()  # the earlier time series went with --fresh
    check_closed_form(tmp_path / "osc_study.parquet")
    journal = (tmp_path / "osc_study.journal.jsonl").read_text().splitlines()
    assert "earlier" not in journal[0] and len(journal) == 4
    assert sorted(str(p.relative_to(temporary)) for p in temporary.rglob("deltafmi-pool*")) == []


FAILER = '''\
"""Test component: x' = -x, whose initialization fails when told to."""
from deltafmi.component import Component, Experiment, Output, Parameter, State


class Failer(Component):
    default_experiment = Experiment(stop=0.1, step=1e-2)
    fail = Parameter(0, type=int, description="1: initialization raises")
    x = State(1.0, description="Decays as exp(-t)")
    y = Output(description="x")

    def initialize(self, t):
        if self.fail:
            raise ValueError("told to fail")

    def derivatives(self, t):
        return [-self.x]

    def outputs(self, t):
        self.y = self.x
'''


def test_a_failed_case_leaves_no_pool_folder(tmp_path):
    """A case that fails frees its FMUs on the worker; the others go on; nothing is left in TMPDIR."""
    (tmp_path / "failer.py").write_text(FAILER)
    (tmp_path / "f.yaml").write_text(textwrap.dedent("""\
        experiment: {stop: 0.1, step: 1.0e-2}
        components:
          f: {source: failer.py, solver: {rtol: 1.0e-10}}
        outputs: [f.y]
        """))
    study = tmp_path / "f_study.yaml"
    study.write_text(textwrap.dedent("""\
        scenario: f.yaml
        vary:
          zip:
            f.fail: [0, 1, 0]
        metrics:
          final: {signal: f.y, statistic: final}
        """))
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    done = subprocess.run([str(DELTAFMI), "sweep", str(study), "--workers", "1", "-q"], cwd=tmp_path,
                          env={**os.environ, "TMPDIR": str(temporary)}, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    rows = pq.read_table(tmp_path / "f_study.parquet").to_pylist()
    assert [row["status"] for row in rows] == ["ok", "failed", "ok"]
    assert "told to fail" in rows[1]["error"]
    for row in (rows[0], rows[2]):
        assert row["final"] == pytest.approx(math.exp(-0.1), rel=1e-8)
    assert list(temporary.rglob("deltafmi-pool*")) == []


@pytest.mark.parametrize(("output", "table"), [("t.csv", "t.parquet"), ("t.parquet", "t.parquet"),
                                                ("runs/t", "runs/t.parquet"), ("t.v2", "t.v2.parquet"),
                                                ("T.CSV", "T.parquet"), ("T.Parquet", "T.Parquet")])
def test_the_output_name_gives_the_table_beside_its_csv_copy(output, table):
    # -o t.csv used to write t.csv.parquet and its CSV copy t.csv.csv
    from deltafmi.apps.studies.commands import _table_path

    assert _table_path(None, output) == Path(table)


def test_a_damaged_journal_line_is_run_again_and_the_rest_kept(tmp_path):
    """The journal of an earlier sweep with damaged lines after its first case: bytes that are
    not UTF-8, JSON that is no row, a row missing its status. They made an "internal error" (a
    UnicodeDecodeError, a KeyError); they are not rows: their cases run again, the finished one
    is kept, and the table holds every case against the closed form."""
    study = write_study(tmp_path)
    done = subprocess.run([str(DELTAFMI), "sweep", str(study), "--workers", "1"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    journal = tmp_path / "osc_study.journal.jsonl"
    lines = journal.read_bytes().splitlines(keepends=True)
    assert len(lines) == 4
    without_status = lines[3].replace(b'"status"', b'"statux"')
    journal.write_bytes(b"".join(lines[:2]) + b'\xff\xfe{"case": 1\n' + b"[1, 2]\n" + without_status)
    again = subprocess.run([str(DELTAFMI), "sweep", str(study), "--workers", "1"], cwd=tmp_path,
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "3/3 cases done, 3 ok, 0 failed (1 from an earlier run)" in again.stdout, again.stdout
    check_closed_form(tmp_path / "osc_study.parquet")
