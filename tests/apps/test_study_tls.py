"""A study on a Dask cluster that speaks only TLS (mutual: every side shows a certificate).

A CA, and certificates signed by it for the scheduler, the worker and the client, are made here
with the ``openssl`` command; a real ``dask scheduler --protocol tls`` and ``dask worker`` run
on 127.0.0.1. ``deltafmi sweep --scheduler tls://...`` with the client's files (options, or Dask's
own configuration in environment variables) runs Oscillator cases to the closed-form solution;
a client without certificates, or with one of another CA, is refused in one line naming the
address (exit 2, no traceback), and so is a scheduler whose certificate this client cannot trust.
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from dask_processes import DASK, scheduler_address, start_process
from oscillator_study import check_closed_form, write_study

DELTAFMI = Path(sys.executable).parent / "deltafmi"

pytestmark = pytest.mark.skipif(shutil.which("openssl") is None, reason="needs the openssl command")


def _openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


def make_certificates(folder: Path, prefix: str = "") -> None:
    """``{prefix}ca.pem`` (a CA), and ``{prefix}{who}.pem`` / ``.key`` signed by it for scheduler,
    worker and client (elliptic-curve keys, valid for a day)."""
    folder.mkdir(parents=True, exist_ok=True)
    new_key = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    _openssl("req", "-x509", *new_key, "-keyout", f"{prefix}ca.key", "-out", f"{prefix}ca.pem", "-days", "1",
             "-subj", f"/CN={prefix}deltafmi test CA", cwd=folder)
    for serial, who in enumerate(("scheduler", "worker", "client"), start=1):
        _openssl("req", *new_key, "-keyout", f"{prefix}{who}.key", "-out", f"{prefix}{who}.csr",
                 "-subj", f"/CN={who}", cwd=folder)
        _openssl("x509", "-req", "-in", f"{prefix}{who}.csr", "-CA", f"{prefix}ca.pem", "-CAkey", f"{prefix}ca.key",
                 "-set_serial", str(serial), "-days", "1", "-out", f"{prefix}{who}.pem", cwd=folder)


def tls_options(folder: Path, who: str, prefix: str = "") -> list:
    """The ``--tls-*`` options of ``dask scheduler``/``dask worker``, the same for deltafmi sweep."""
    return ["--tls-ca-file", str(folder / f"{prefix}ca.pem"), "--tls-cert", str(folder / f"{prefix}{who}.pem"),
            "--tls-key", str(folder / f"{prefix}{who}.key")]


@pytest.fixture(scope="module")
def tls_cluster(tmp_path_factory):
    """(``tls://127.0.0.1:port``, the certificates' folder) of a TLS-only scheduler with one worker."""
    root = tmp_path_factory.mktemp("tls")
    certs = root / "certs"
    make_certificates(certs)
    make_certificates(certs, prefix="other-")  # a CA the cluster does not know
    info = root / "scheduler.json"
    processes = [start_process([str(DASK), "scheduler", "--protocol", "tls", "--host", "127.0.0.1", "--port", "0",
                         "--no-dashboard", "--scheduler-file", str(info), *tls_options(certs, "scheduler")],
                        root / "scheduler")]
    try:
        address = scheduler_address(info, root / "scheduler" / "log.txt")
        processes.append(start_process([str(DASK), "worker", address, "--nthreads", "1", "--nworkers", "1",
                                 "--host", "127.0.0.1", "--no-dashboard", *tls_options(certs, "worker")],
                                root / "worker"))
        from distributed import Client
        from distributed.security import Security

        security = Security(tls_ca_file=str(certs / "ca.pem"), tls_client_cert=str(certs / "client.pem"),
                            tls_client_key=str(certs / "client.key"), require_encryption=True)
        with Client(address, security=security, timeout="600s") as client:
            client.wait_for_workers(1, timeout=600)
        yield address, certs
    finally:
        for process in processes:
            try:
                os.killpg(process.pid, signal.SIGTERM)
                process.wait(timeout=20)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                os.killpg(process.pid, signal.SIGKILL)


def test_sweep_over_tls_with_the_options(tls_cluster, tmp_path):
    address, certs = tls_cluster
    study = write_study(tmp_path)
    result = CliRunner().invoke(main, ["sweep", str(study), "--scheduler", address, "-o", str(tmp_path / "r.parquet"),
                                       *tls_options(certs, "client")])
    assert result.exit_code == 0, result.output
    assert "3/3 cases done, 3 ok, 0 failed" in result.output and "on 1 worker(s)" in result.output
    check_closed_form(tmp_path / "r.parquet")


def test_sweep_over_tls_with_dask_configuration(tls_cluster, tmp_path):
    """Dask's own configuration, as environment variables: no deltafmi option at all."""
    address, certs = tls_cluster
    study = write_study(tmp_path)
    env = {**os.environ, "DASK_DISTRIBUTED__COMM__TLS__CA_FILE": str(certs / "ca.pem"),
           "DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT": str(certs / "client.pem"),
           "DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY": str(certs / "client.key")}
    done = subprocess.run([str(DELTAFMI), "sweep", str(study), "--scheduler", address, "-q"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    check_closed_form(tmp_path / "osc_study.parquet")


@pytest.mark.parametrize("client, expected", [
    (None, "the Dask scheduler at {address} speaks TLS: give this client's certificate with --tls-ca-file"),
    ("other-client", "cannot connect to the Dask scheduler at {address}: the scheduler refused this client's "
                     "certificate"),
    ("other-ca", "cannot connect to the Dask scheduler at {address}: the scheduler's certificate is not signed "
                 "by the CA this client trusts (--tls-ca-file)"),
])
def test_a_client_without_the_clusters_certificates_is_refused(tls_cluster, tmp_path, client, expected):
    address, certs = tls_cluster
    study = write_study(tmp_path)
    options = {None: [],
               "other-client": ["--tls-ca-file", str(certs / "ca.pem"), "--tls-cert", str(certs / "other-client.pem"),
                                "--tls-key", str(certs / "other-client.key")],
               "other-ca": tls_options(certs, "client", prefix="other-")}[client]
    result = CliRunner().invoke(main, ["sweep", str(study), "--scheduler", address, *options])
    assert result.exit_code == 2, result.output
    last = result.output.strip().splitlines()[-1]
    assert last.startswith("Error: " + expected.format(address=address)), last
    assert "Traceback" not in result.output
    assert not (tmp_path / "osc_study.journal.jsonl").exists()  # nothing written before the cluster answered
