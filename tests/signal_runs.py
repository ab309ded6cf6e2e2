"""Interrupt a real command once it has written something: the tests of runs stopped by signals."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable, Optional, Sequence

#: ``deltafmi`` as a command of this interpreter (the tests' virtual environment)
DELTAFMI = (sys.executable, "-c", "from deltafmi.apps.cli import main; main()")


def interrupt_when(command: Sequence[str], ready: Callable[[], bool], signum: int = signal.SIGINT,
                   timeout: float = 600.0, **popen) -> tuple[int, str, str]:
    """Start ``command``, send it ``signum`` once ``ready()`` holds, and wait for it to end.

    Fails the test if the command ends before it is ready or ``ready`` takes longer than
    ``timeout`` seconds; the process is killed whatever happens. Returns (exit code, stdout, stderr).
    """
    popen.setdefault("stdout", subprocess.PIPE)
    popen.setdefault("stderr", subprocess.PIPE)
    given = popen.pop("preexec_fn", None)

    def start() -> None:  # the signal's default handling, whatever was inherited (nohup ignores SIGHUP)
        if signum != signal.SIGKILL:
            signal.signal(signum, signal.SIG_DFL)
        if given is not None:
            given()

    process = subprocess.Popen(list(command), text=True, preexec_fn=start, **popen)
    try:
        deadline = time.monotonic() + timeout
        while not ready():
            assert process.poll() is None and time.monotonic() < deadline, process.communicate()
            time.sleep(0.05)
        process.send_signal(signum)
        stdout, stderr = process.communicate(timeout=600)  # a hang guard: a loaded machine is slow
    finally:
        if process.poll() is None:
            process.kill()
    return process.returncode, stdout, stderr


def growing(result: Path) -> Optional[Path]:
    """The file a running ``deltafmi run -o RESULT`` writes: a hidden temporary file beside RESULT
    (moved into place when the run ends), or None before the run opened it."""
    found = sorted(result.parent.glob(f".{result.name}.*.tmp"))
    return found[0] if found else None


def rows_in(result: Path) -> int:
    """Lines in the running run's CSV file so far (0 before it opened one)."""
    path = growing(result)
    try:
        return path.read_text().count("\n") if path is not None else 0
    except FileNotFoundError:  # moved into place in between
        return 0


def bytes_in(result: Path) -> int:
    """Bytes in the running run's file so far (0 before it opened one)."""
    path = growing(result)
    try:
        return path.stat().st_size if path is not None else 0
    except FileNotFoundError:
        return 0
