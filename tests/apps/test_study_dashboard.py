"""Where the local Dask cluster of ``deltafmi sweep`` listens.

Its scheduler's HTTP server (the dashboard, and Dask's pages of worker logs, call stacks and task
details) listens on 127.0.0.1 unless ``--dashboard HOST:PORT`` says otherwise. The sockets are
read from the kernel (psutil) for this process and the worker processes it starts, so the test
sees what the network sees, not what Dask says it did (Dask's ``dashboard_link`` names 127.0.0.1
even when it listens on every interface).
"""
from __future__ import annotations

import socket
import urllib.error
import urllib.request
from pathlib import Path

import psutil
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.apps.studies.driver import dashboard_address, dashboard_link, dask_client

ROOT = Path(__file__).resolve().parents[2]
STUDY = f"""\
scenario: {ROOT / 'scenarios' / 'bouncing_ball.yaml'}
vary:
  grid:
    restitution.e: [0.5, 0.8]
    experiment.stop: [0.05]
metrics:
  q_end: {{signal: restitution.q, statistic: final}}
"""


def listening() -> set:
    """(pid, ip, port) of every listening TCP socket of this process and its children."""
    me = psutil.Process()
    found = set()
    for process in [me] + me.children(recursive=True):
        try:
            connections = process.net_connections(kind="inet")
        except psutil.NoSuchProcess:
            continue
        found |= {(process.pid, c.laddr.ip, c.laddr.port) for c in connections if c.status == psutil.CONN_LISTEN}
    return found


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def health(host: str, port: int) -> str:
    """The body of Dask's /health page at host:port ("ok"), or the connection error's name."""
    try:
        with urllib.request.urlopen(f"http://{host}:{port}/health", timeout=600) as response:
            return response.read().decode()
    except urllib.error.URLError as exc:
        return type(exc.reason).__name__


def test_local_cluster_listens_on_loopback_only():
    before = listening()
    with dask_client(workers=1) as client:
        opened = listening() - before
        port = client.cluster.scheduler.http_server.port
        assert health("127.0.0.1", port) == "ok"
    ips = {ip for _, ip, _ in opened}
    assert port in {p for _, _, p in opened}, opened  # the dashboard is among the sockets checked
    assert ips == {"127.0.0.1"}, opened  # the scheduler, the dashboard, the nanny, the worker


def non_loopback_ipv4() -> str:
    for addresses in psutil.net_if_addrs().values():
        for address in addresses:
            if address.family == socket.AF_INET and not address.address.startswith("127."):
                return address.address
    pytest.skip("this machine has no IPv4 address besides loopback")


@pytest.mark.parametrize("where", ["a fixed port", "every interface", "one other interface"])
def test_dashboard_listens_where_asked(where):
    host = {"a fixed port": "127.0.0.1", "every interface": "0.0.0.0"}.get(where) or non_loopback_ipv4()
    port = free_port() if where == "a fixed port" else 0
    before = listening()
    with dask_client(workers=1, dashboard=f"{host}:{port}") as client:
        server = client.cluster.scheduler.http_server
        opened = listening() - before
        bound = {(ip, p) for _, ip, p in opened if p == server.port}
        assert bound == {(host, port or server.port)}
        if host != "0.0.0.0":
            assert dashboard_link(client) == f"http://{host}:{server.port}/status"
        # reachable where asked; bound to another interface, not on loopback
        assert health(host if host != "0.0.0.0" else "127.0.0.1", server.port) == "ok"
        if where == "one other interface":
            assert health("127.0.0.1", server.port) == "ConnectionRefusedError"
    # the rest of the cluster stays on loopback whatever the dashboard does
    assert {ip for _, ip, p in opened if p != server.port} == {"127.0.0.1"}


def test_sweep_prints_the_link_of_the_dashboard_it_was_given(tmp_path, monkeypatch):
    monkeypatch.setenv("DELTAFMI_CACHE", str(tmp_path / "cache"))  # a bouncing-ball build: ~2 s
    study = tmp_path / "balls.yaml"
    study.write_text(STUDY)
    port = free_port()
    result = CliRunner().invoke(main, ["sweep", str(study), "--workers", "1", "--dashboard", f"127.0.0.1:{port}",
                                       "-o", str(tmp_path / "balls.parquet")])
    assert result.exit_code == 0, result.output
    assert f"Dask dashboard: http://127.0.0.1:{port}/status" in result.output
    assert "2/2 cases done, 2 ok" in result.output


@pytest.mark.parametrize("address, expected", [
    ("0.0.0.0:8787", ("0.0.0.0", 8787)), ("8787", ("127.0.0.1", 8787)), ("localhost", ("localhost", 0)),
    ("[::1]:8787", ("::1", 8787)), ("[::]", ("::", 0)), (" 10.0.0.5:0 ", ("10.0.0.5", 0)),
])
def test_addresses_read_as_documented(address, expected):
    assert dashboard_address(address) == expected


@pytest.mark.parametrize("address, message", [
    (":8787", "no host (Dask would listen on every interface)"),
    ("localhost:http", "the port 'http' is not a number from 0 to 65535"),
    ("127.0.0.1:70000", "the port '70000' is not a number from 0 to 65535"),
    ("::1:8787", "an IPv6 address goes in brackets"),
])
def test_a_malformed_address_is_refused_before_anything_runs(tmp_path, address, message):
    study = tmp_path / "balls.yaml"
    study.write_text(STUDY)
    result = CliRunner().invoke(main, ["sweep", str(study), "--dashboard", address])
    assert result.exit_code == 2, result.output
    assert message in result.output and "HOST:PORT" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "balls.parquet").exists()


def test_dashboard_and_scheduler_together_are_refused(tmp_path):
    result = CliRunner().invoke(main, ["sweep", str(tmp_path / "x.yaml"), "--scheduler", "tcp://127.0.0.1:1",
                                       "--dashboard", "0.0.0.0:8787"])
    assert result.exit_code == 2 and "--dashboard" in result.output and "--scheduler" in result.output


def test_an_address_not_of_this_machine_is_a_clear_error():
    from deltafmi.errors import BadInput

    with pytest.raises(BadInput, match=r"cannot start the Dask dashboard at 203\.0\.113\.7:0: Cannot assign"):
        with dask_client(workers=1, dashboard="203.0.113.7:0"):  # TEST-NET-3: documentation only
            pass
