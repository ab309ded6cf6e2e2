"""Writing result files and cache entries atomically: readers (another process, a crash) never see half a file."""
from __future__ import annotations

import atexit
import os
import signal
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

__all__ = ["USER_FILE_MODE", "keep_in_cache", "replaced_atomically", "written_through"]


def _user_file_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


#: the signals that stop a command (held back while a temporary file is made)
_STOPS = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP} if hasattr(signal, "pthread_sigmask") else set()

#: the permissions of any file the user creates (a temporary file is private: 0600)
USER_FILE_MODE = _user_file_mode()


#: temporary files made and not yet replaced or removed: a signal's KeyboardInterrupt can land
#: between a ``with`` statement's ``__enter__`` and its block (in contextlib's own code), where no
#: ``finally`` of ours runs; the process then ends and removes them here (only its own: a forked
#: child that exits must not remove its parent's)
_UNFINISHED: set = set()


@atexit.register
def _remove_unfinished() -> None:
    for pid, name in list(_UNFINISHED):
        if pid == os.getpid():
            try:
                os.unlink(name)
            except OSError:
                pass


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
        # the name is known before the file exists: the block above holds the signals back in
        # this thread only, and another thread's receiving one lets its KeyboardInterrupt land
        # anywhere here (in mkstemp it came after the file was made, before its name was returned)
        while True:
            name = str(path.parent / f".{path.name}.{os.urandom(6).hex()}.part")
            try:
                handle = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
                break
            except FileExistsError:  # another's: never ours to remove
                name = ""
        _UNFINISHED.add((os.getpid(), name))
        os.close(handle)
        if held is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
            held = None
        try:
            yield Path(name)
        except OSError as error:
            if error.filename is None or str(error.filename) == name:  # a full disk: the file it was for
                error.filename = str(path)
            raise
        os.chmod(name, USER_FILE_MODE)
        os.replace(name, path)
    finally:
        if held is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
        if name and os.path.exists(name):
            os.unlink(name)
        _UNFINISHED.discard((os.getpid(), name))


def keep_in_cache(path: Path, data: bytes) -> bool:
    """``data`` kept at ``path``, an entry of a cache that is only ever replaced whole: written to
    a temporary file of this process and thread next to it, then renamed over it, so that readers
    see the old entry or the new one. False when it could not be kept (a read-only cache: the
    caller works it out again next time)."""
    temporary = path.with_name(f"{path.name}.{os.getpid()}-{threading.get_ident()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary.write_bytes(data)
        os.replace(temporary, path)
    except OSError:
        try:
            temporary.unlink()
        except OSError:  # never made (or not in a folder at all)
            pass
        return False
    return True
