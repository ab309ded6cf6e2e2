"""Interrupt a real command once it has written something: the tests of runs stopped by signals."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from typing import Callable, Sequence

#: ``deltafmi`` as a command of this interpreter (the tests' virtual environment)
DELTAFMI = (sys.executable, "-c", "from deltafmi.apps.cli import main; main()")


def interrupt_when(command: Sequence[str], ready: Callable[[], bool], signum: int = signal.SIGINT,
                   timeout: float = 120.0, **popen) -> tuple[int, str, str]:
    """Start ``command``, send it ``signum`` once ``ready()`` holds, and wait for it to end.

    Fails the test if the command ends before it is ready or ``ready`` takes longer than
    ``timeout`` seconds; the process is killed whatever happens. Returns (exit code, stdout, stderr).
    """
    popen.setdefault("stdout", subprocess.PIPE)
    popen.setdefault("stderr", subprocess.PIPE)
    process = subprocess.Popen(list(command), text=True, **popen)
    try:
        deadline = time.monotonic() + timeout
        while not ready():
            assert process.poll() is None and time.monotonic() < deadline, process.communicate()
            time.sleep(0.05)
        process.send_signal(signum)
        stdout, stderr = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    return process.returncode, stdout, stderr
