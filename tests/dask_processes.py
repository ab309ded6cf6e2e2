"""Dask schedulers and workers as separate processes (`dask scheduler`, `dask worker`), as a user
starts them on a cluster: shared by the study tests that need a real remote cluster."""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Optional

DASK = Path(sys.executable).parent / "dask"


def start_process(command: list, folder: Path, env: Optional[dict] = None) -> subprocess.Popen:
    """``command`` started in ``folder`` (made if missing), its output in ``folder/log.txt``."""
    folder.mkdir(parents=True, exist_ok=True)
    return subprocess.Popen(command, cwd=folder, env=env, stdout=open(folder / "log.txt", "w"),
                            stderr=subprocess.STDOUT, start_new_session=True)


def scheduler_address(info: Path, log: Path, timeout: float = 600.0) -> str:
    """The address the scheduler writes to its ``--scheduler-file`` once it listens (the file may
    be partial while it is written)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            return json.loads(info.read_text())["address"]
        except (OSError, ValueError, KeyError):
            time.sleep(0.1)
    raise TimeoutError(f"the Dask scheduler did not start (see {log})")
