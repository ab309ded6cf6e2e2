"""``deltafmi compat`` (export and import) and the live scope stopped by SIGINT, SIGTERM or SIGHUP:
one line, no traceback, exit code 128 + the signal, and the files they write never lost (an
earlier file of the same name intact, or replaced by a whole, readable one; no temporary file left)."""
from __future__ import annotations

import re
import shutil
import signal
import socket
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from deltafmi.apps.compat.files import read_options, read_table
from deltafmi.master.live.datagram import Encoder

DELTAFMI = [sys.executable, "-c", "from deltafmi.apps.cli import main; main()"]
SIGNALS = [signal.SIGINT, signal.SIGTERM, signal.SIGHUP]


def _stop_at(args, line_pattern: str, signum: int, cwd: Path):
    """Run ``deltafmi args``, send ``signum`` when a line of its stdout matches ``line_pattern``;
    (exit code, stdout, stderr)."""
    process = subprocess.Popen([*DELTAFMI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               cwd=cwd)
    lines = []
    try:
        for line in process.stdout:
            lines.append(line)
            if re.search(line_pattern, line):
                process.send_signal(signum)
                break
        out, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert any(re.search(line_pattern, line) for line in lines), (lines, process.stderr.read() if False else "")
    return process.returncode, "".join(lines) + out, err


def _check_tree(root: Path) -> dict:
    """Every file of a compat tree whole and readable; {relative path: bytes}."""
    leftovers = [p for p in root.rglob(".*") if p.is_file()]
    assert not leftovers, leftovers  # no temporary file behind
    files = {}
    for path in sorted(p for p in root.rglob("*") if p.is_file()):
        if path.suffix == ".fmu":
            assert zipfile.ZipFile(path).testzip() is None
        elif path.name.endswith(".csv"):
            assert len(read_table(path).time) > 1
        elif path.suffix == ".opt":
            read_options(path)
        elif path.name == "ReadMe.md":
            assert path.read_text().endswith("\n") and len(path.read_text()) > 100
        files[str(path.relative_to(root))] = path.read_bytes()
    return files


@pytest.fixture(scope="module")
def tree(tmp_path_factory) -> Path:
    """A complete tree of the Oscillator (FMI 2.0, CS and ME) and of its import."""
    root = tmp_path_factory.mktemp("compat") / "xc"
    for args in (["compat", str(root), "--models", "Oscillator,BouncingBall", "--fmi-version", "2"],
                 ["compat", "import", str(root)]):
        done = subprocess.run([*DELTAFMI, *args], capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
    return root


def _interrupted(code: int, err: str, signum: int) -> None:
    assert code == 128 + signum, err
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1] == f"interrupted ({signal.Signals(signum).name})", err


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_an_interrupted_compat_export_keeps_every_file_whole(tree, tmp_path, signum):
    root = tmp_path / "xc"
    shutil.copytree(tree, root)
    before = _check_tree(root)
    code, out, err = _stop_at(["compat", str(root), "--models", "Oscillator,BouncingBall", "--fmi-version", "2"],
                              r"^wrote ", signum, tmp_path)
    _interrupted(code, err, signum)
    after = _check_tree(root)
    assert set(after) == set(before)  # every earlier file still there, each whole


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_an_interrupted_compat_import_keeps_every_result_whole(tree, tmp_path, signum):
    root = tmp_path / "xc"
    shutil.copytree(tree, root)
    before = _check_tree(root / "results")
    code, out, err = _stop_at(["compat", "import", str(root)], r"^passed ", signum, tmp_path)
    _interrupted(code, err, signum)
    after = _check_tree(root / "results")
    assert set(after) == set(before)  # the earlier statuses and outputs kept, none half-written
    for folder in {p.parent for p in (root / "results").rglob("ReadMe.md")}:
        assert [p.name for p in folder.iterdir() if p.name in ("passed", "failed", "rejected")] == ["passed"]


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_a_scope_stopped_by_a_signal_saves_its_picture_and_says_why(tmp_path, signum):
    picture = tmp_path / "scope.png"
    picture.write_bytes(b"an earlier picture, not a PNG")
    process = subprocess.Popen([*DELTAFMI, "scope", "--port", "0", "--save", str(picture), "x"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        line = process.stdout.readline()
        match = re.fullmatch(r"listening 127\.0\.0\.1:(\d+)\n", line)
        assert match, (line, process.stderr.read() if process.poll() is not None else "")
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            sender.sendto(Encoder(["x"]).encode([1.0], 0.0, 0), ("127.0.0.1", int(match[1])))
        process.send_signal(signum)
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 128 + signum, err
    assert "Traceback" not in err
    reason = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated", signal.SIGHUP: "hung up"}[signum]
    last = err.strip().splitlines()[-1]
    assert last.startswith("scope: 1 datagram") and last.endswith(f"ended: {reason}; wrote {picture}"), err
    from matplotlib.image import imread
    assert imread(picture).shape[0] > 100  # replaced by a whole picture
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
