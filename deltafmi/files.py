"""Writing result files atomically: readers (another process, a crash) never see half a file."""
from __future__ import annotations

import os
import signal
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

__all__ = ["USER_FILE_MODE", "replaced_atomically", "written_through"]


def _user_file_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


#: the signals that stop a command (held back while a temporary file is made)
_STOPS = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP} if hasattr(signal, "pthread_sigmask") else set()

#: the permissions of any file the user creates (a temporary file is private: 0600)
USER_FILE_MODE = _user_file_mode()


def written_through(path: Path) -> Path:
    """Where writing ``path`` puts the file: the target of a symbolic link (the link stays a link),
    else ``path`` itself."""
    return Path(os.path.realpath(path)) if os.path.islink(path) else Path(path)


@contextmanager
def replaced_atomically(path: Path) -> Iterator[Path]:
    """A temporary file next to ``path`` to write; it replaces ``path`` when the block ends
    without an error, with the user's usual permissions, and is removed when it raises. A symbolic
    link is written through: its target is replaced, the link stays."""
    path = written_through(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    name = ""
    # a signal (Ctrl-C, SIGTERM) between making the file and the try below would leave it behind:
    # held back until its name is known here
    held = signal.pthread_sigmask(signal.SIG_BLOCK, _STOPS) if _STOPS else None
    try:
        handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".part")
        os.close(handle)
        if held is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
            held = None
        yield Path(name)
        os.chmod(name, USER_FILE_MODE)
        os.replace(name, path)
    finally:
        if held is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
        if name and os.path.exists(name):
            os.unlink(name)
