"""A result file that never destroys an earlier one: rows go to a temporary file beside the target,
moved into place when the writer closes.

A run that completes, or is interrupted (the rows computed are kept), replaces the target with
a whole, readable file; a run that fails leaves the target as it was and keeps its rows under
the failed name (``r.csv`` -> ``r.failed.csv``), which the failure's message names. A process
killed outright (SIGKILL, power loss) leaves the target untouched and the temporary file
(``.r.csv.<pid>-<n>.tmp``, hidden) behind. The rename is atomic (``os.replace`` on one file system).
A target that is a symbolic link is written through: the file it points to is replaced (the
temporary file beside it), the link stays.
"""
from __future__ import annotations

import itertools
import os
from pathlib import Path
from typing import Optional

from deltafmi.errors import BadInput
from deltafmi.files import written_through

__all__ = ["ResultFile", "failed_name", "check_writable"]

_COUNT = itertools.count(1)


def failed_name(target: Path) -> Path:
    """Where a failed run's rows go: ``r.csv`` -> ``r.failed.csv`` (beside the target)."""
    return target.with_name(f"{target.stem}.failed{target.suffix}")


def check_writable(target: Path, what: str = "result file") -> None:
    """Raise :class:`BadInput` (one line, naming ``what`` and ``target``) when ``target`` cannot be
    written: a file where a folder of its path should be, a folder, a device, a pipe or a socket
    where the file should be (moved into place, the new file would replace it), a folder that
    cannot take files (no permission, a read-only file system). Folders missing on
    the way are not an error: the writer makes them."""
    target = Path(target)
    if target.is_dir():
        raise BadInput(f"{what} '{target}': that is a folder; name a file")
    if target.exists() and not target.is_file():  # the rename into place would replace it by a file
        raise BadInput(f"{what} '{target}': not a regular file (a device, a pipe or a socket); name a file")
    folder = target.parent
    for parent in [target.parent, *target.parent.parents]:
        if parent.exists():
            if not parent.is_dir():
                raise BadInput(f"{what} '{target}': {parent} is a file, not a folder")
            folder = parent
            break
    probe = folder / f".{target.name}.{os.getpid()}.probe"
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError as exc:
        raise BadInput(f"{what} '{target}': cannot write in {folder}: {exc.strerror or exc}") from None
    os.close(fd)
    os.unlink(probe)


class ResultFile:
    """The temporary file a writer writes, and where it goes when the writer closes."""

    def __init__(self, target: str | Path) -> None:
        # a symbolic link is written through: its target replaced beside itself, the link kept
        self.target = written_through(Path(target))
        if self.target != Path(target):
            self.target.parent.mkdir(parents=True, exist_ok=True)
        # the process and a count: two writers of one target (two threads) never share a file
        self.temporary = self.target.with_name(f".{self.target.name}.{os.getpid()}-{next(_COUNT)}.tmp")
        #: set by :meth:`fail`: the rows go to :func:`failed_name` instead of the target
        self.failed = False

    @property
    def final(self) -> Path:
        """Where the rows are once the writer has closed."""
        return failed_name(self.target) if self.failed else self.target

    def fail(self) -> Path:
        """The run failed: the rows go to the failed name (returned), the target stays as it was."""
        self.failed = True
        return self.final

    def finish(self) -> Optional[Path]:
        """Move the temporary file into place (idempotent); its final path, or None when there was
        none (never opened, or removed because unreadable)."""
        if not self.temporary.exists():
            return None
        final = self.final
        try:
            os.replace(self.temporary, final)
        except OSError as exc:  # an immutable or otherwise locked target: the rows stay where they are
            raise BadInput(f"result file '{final}': cannot put the finished file in its place "
                           f"({exc.strerror or exc}); its rows are in {self.temporary}") from None
        return final

    def discard(self) -> None:
        """Remove the temporary file (a file that cannot be made readable)."""
        self.temporary.unlink(missing_ok=True)
