"""Writing result files atomically: readers (another process, a crash) never see half a file."""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

__all__ = ["USER_FILE_MODE", "replaced_atomically"]


def _user_file_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


#: the permissions of any file the user creates (a temporary file is private: 0600)
USER_FILE_MODE = _user_file_mode()


@contextmanager
def replaced_atomically(path: Path) -> Iterator[Path]:
    """A temporary file next to ``path`` to write; it replaces ``path`` when the block ends
    without an error, with the user's usual permissions, and is removed when it raises."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".part")
    os.close(handle)
    try:
        yield Path(name)
        os.chmod(name, USER_FILE_MODE)
        os.replace(name, path)
    finally:
        if os.path.exists(name):
            os.unlink(name)
