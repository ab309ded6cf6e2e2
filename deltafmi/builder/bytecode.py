"""Python sources as the bytecode an FMU carries beside them."""
from __future__ import annotations

import hashlib
import importlib.util
import marshal
import os
import tempfile
from pathlib import Path

from deltafmi.toolchain import cache_dir

__all__ = ["unchecked_hash_pyc"]


def unchecked_hash_pyc(path: Path, arcname: str) -> bytes:
    """``path`` compiled for this Python, as the .pyc ``py_compile`` writes with an unchecked hash
    (PEP 552), named ``arcname`` in tracebacks. An FMU is unpacked afresh for every run, and its
    file times must never make the interpreter compile the sources there (that cost more than the
    rest of loading the runtime). Another Python version ignores the file and compiles the source.

    Every FMU carries the runtime's sources and a portable one whole packages: the bytecode is kept
    in the build cache, keyed by this Python's magic number, ``arcname`` and the source's bytes."""
    text = path.read_bytes()
    key = hashlib.sha256(importlib.util.MAGIC_NUMBER + arcname.encode() + b"\0" + text).hexdigest()
    cached = cache_dir() / "pyc" / key[:2] / f"{key[2:]}.pyc"
    try:
        return cached.read_bytes()
    except OSError:
        pass
    code = compile(text, arcname, "exec", dont_inherit=True)
    flags = (0b01).to_bytes(4, "little")  # hash-based, not checked against the source
    pyc = importlib.util.MAGIC_NUMBER + flags + importlib.util.source_hash(text) + marshal.dumps(code)
    _store(cached, pyc)
    return pyc


def _store(target: Path, data: bytes) -> None:
    """Write ``data`` to ``target`` whole (renamed into place: a concurrent writer of the same key
    writes the same bytes); a cache that cannot be written is only slower."""
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=target.parent, suffix=".tmp")
        with os.fdopen(fd, "wb") as out:
            out.write(data)
        os.replace(tmp, target)
    except OSError:
        pass
