"""Python sources as the bytecode an FMU carries beside them."""
from __future__ import annotations

import importlib.util
import marshal
from pathlib import Path

__all__ = ["unchecked_hash_pyc"]


def unchecked_hash_pyc(path: Path, arcname: str) -> bytes:
    """``path`` compiled for this Python, as the .pyc ``py_compile`` writes with an unchecked hash
    (PEP 552), named ``arcname`` in tracebacks. An FMU is unpacked afresh for every run, and its
    file times must never make the interpreter compile the sources there (that cost more than the
    rest of loading the runtime). Another Python version ignores the file and compiles the source."""
    text = path.read_bytes()
    code = compile(text, arcname, "exec", dont_inherit=True)
    flags = (0b01).to_bytes(4, "little")  # hash-based, not checked against the source
    return importlib.util.MAGIC_NUMBER + flags + importlib.util.source_hash(text) + marshal.dumps(code)
