"""Unpacked copies of the FMUs in deltafmi's build cache, kept, so that a run does not unzip them again.

An FMU has to be unpacked before it is loaded (FMI 2.0 section 2.1.7: the importer unzips it and
passes the folder as ``fmuResourceLocation``). An FMU of the build cache never changes under its
name (its folder is its content key), so its unpacked copy can be kept beside it and shared by
every later run, as the cache keeps the FMU itself. A copy is made in a fresh folder and renamed
into place in one step: a run sees the whole copy or none, and two runs that unpack at once keep
one copy. FMUs elsewhere (a user's ``.fmu``) are unpacked for the run, into its own temporary folder.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Optional

import fmpy

from deltafmi.toolchain import cache_dir

__all__ = ["kept_unpacked"]


def kept_unpacked(fmu: Path) -> Optional[str]:
    """The folder of the kept unpacked copy of ``fmu``, made now when there is none, if ``fmu`` is
    in the build cache; None for any other FMU (and when the cache cannot be written)."""
    built = (cache_dir() / "fmus").resolve()
    try:
        relative = Path(fmu).resolve().relative_to(built)
        status = os.stat(fmu)
    except (ValueError, OSError):
        return None
    # the stamp too: an FMU rebuilt in place (its cache entry removed by hand) gets a fresh copy
    name = hashlib.sha256(f"{relative.as_posix()}\0{status.st_size}\0{status.st_mtime_ns}".encode()).hexdigest()[:24]
    target = cache_dir() / "unpacked" / name
    if target.is_dir():
        return str(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fresh = tempfile.mkdtemp(prefix=f".{name}-", dir=target.parent)
    except OSError:
        return None
    try:
        fmpy.extract(str(fmu), unzipdir=fresh)
    except BaseException:
        shutil.rmtree(fresh, ignore_errors=True)
        raise
    try:
        os.rename(fresh, target)
    except OSError:
        shutil.rmtree(fresh, ignore_errors=True)
        return str(target) if target.is_dir() else None  # another run renamed its copy first
    return str(target)
