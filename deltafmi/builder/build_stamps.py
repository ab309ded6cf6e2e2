"""The build cache's fast path: a cached FMU found from file stamps, without reading its sources.

The key of a cached FMU (:func:`.packager.content_key`) hashes every file the FMU is made from:
its component source, the runtime modules it carries, the native sources, the code generator.
Reading and hashing them all costs more than the rest of a short run's start-up. So, as Python
checks a ``.pyc`` against its ``.py``, each build request (this component, FMI version and
resources, in this Python, by this installation of deltafmi) records beside the cache the stamp of
every file its key read, and of the folders those files were found in (a module added there may be
reached): size, modification time in nanoseconds and inode. The request names the installation
(:func:`installation`): two checkouts or environments sharing one cache each check the stamps of
their own files, never those another recorded (unchanged there, while this one's runtime may
differ); installations with the same contents still share the FMU, found from its content key. The next request stats them: when no stamp changed it takes the
recorded FMU, read nothing; when one did (an edit, a ``touch``, a checkout), the key is computed
from the contents again and the record renewed, so a stamp that changed with the content unchanged
costs one hash, never a rebuild.

Only the standard library here: the fast path imports none of the builder.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path
from typing import List, Optional, Sequence, Tuple, Union

from deltafmi.files import keep_in_cache
from deltafmi.toolchain import cache_dir, compiler_available

__all__ = ["Stamp", "file_request", "installation", "lookup", "module_request", "recorded", "remember", "stamps_of"]

#: [path, size, mtime_ns, inode] of one file or folder
Stamp = List[Union[str, int]]
#: bump when what a record holds changes
_FORMAT = 1


def stamps_of(paths: Sequence[Path]) -> List[Stamp]:
    """The stamps of ``paths`` as they are now (take them before reading the files: a file
    written between the stamp and the read then shows as changed next time, never the reverse)."""
    found = []
    for path in paths:
        status = os.stat(path)
        found.append([str(path), status.st_size, status.st_mtime_ns, status.st_ino])
    return found


def file_request(source: Path, class_name: Optional[str], fmi_version: int, resources: Sequence[Path]) -> str:
    """The name of the request for the FMU of the component in file ``source``."""
    return _request("file", str(Path(source).resolve()), class_name or "", str(fmi_version),
                    *(str(Path(r).resolve()) for r in resources))


def module_request(reference: str, fmi_version: int, resources: Sequence[Path]) -> Optional[str]:
    """The name of the request for the FMU of ``package.module:Class``, found without importing the
    module (only its packages); None when it cannot be found so (the slow path says why)."""
    import importlib.util

    module = reference.partition(":")[0]
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.origin or not os.path.isfile(spec.origin):
        return None
    return _request("module", reference, spec.origin, str(fmi_version), *(str(Path(r).resolve()) for r in resources))


def lookup(request: str) -> Optional[Path]:
    """The FMU recorded for ``request`` when every stamp recorded with it is unchanged, else None."""
    found = recorded(request)
    return found[0] if found else None


def recorded(request: str) -> Optional[Tuple[Path, List[Stamp]]]:
    """:func:`lookup`'s FMU with the stamps it was recorded with."""
    try:
        record = json.loads(_record_path(request).read_text())
        if record.get("format") != _FORMAT:
            return None
        for path, size, mtime_ns, inode in record["stamps"]:
            status = os.stat(path)
            if (status.st_size, status.st_mtime_ns, status.st_ino) != (size, mtime_ns, inode):
                return None
        fmu = cache_dir() / "fmus" / record["fmu"]
    except (OSError, ValueError, KeyError, TypeError):
        return None  # no record, a file gone, a record half written by an older version: the slow path
    return (fmu, record["stamps"]) if fmu.is_file() else None


def remember(request: str, stamps: Sequence[Stamp], fmu: Path) -> None:
    """Record that ``request`` is answered by ``fmu`` (in the build cache) while ``stamps`` hold."""
    try:
        relative = Path(fmu).resolve().relative_to((cache_dir() / "fmus").resolve())
    except ValueError:
        return  # not in the cache: nothing to find again
    record = json.dumps({"format": _FORMAT, "fmu": relative.as_posix(), "stamps": list(stamps)})
    keep_in_cache(_record_path(request), record.encode("utf-8"))  # a read-only cache: the next run hashes again


def installation() -> Tuple[str, str]:
    """This deltafmi: the folder its package is imported from (symbolic links resolved) and its version.

    Each installation's requests are its own: the stamps a request records are those of the files
    of the installation that made it (its runtime, native sources, code generator), and another
    checkout or environment sharing the cache, whose files may differ, has to check its own."""
    import deltafmi

    return os.path.realpath(os.path.dirname(deltafmi.__file__)), deltafmi.__version__


def _request(*parts: str) -> str:
    # the interpreter and the compiler's presence go into the key (packager.content_key), so into the request
    environment = (sys.prefix, sys.base_prefix, sys.version, str(compiler_available()), *installation())
    return hashlib.sha256("\0".join((*parts, *environment)).encode("utf-8", "surrogateescape")).hexdigest()[:32]


def _record_path(request: str) -> Path:
    return cache_dir() / "fmu-stamps" / f"{request}.json"
