"""Build component sources into FMUs on demand, cached by content.

The cache key is the SHA-256 of the component source and of the deltafmi runtime that gets packed
into the FMU (``deltafmi/__init__.py``, ``component/``, ``export/``, ``mechanics/``), so editing either
rebuilds, and nothing else does. Cache folder: ``$DELTAFMI_CACHE`` or ``~/.cache/deltafmi``.
"""
from __future__ import annotations

import hashlib
import os
import tempfile
from functools import lru_cache
from pathlib import Path

import deltafmi

_RUNTIME_PARTS = ("__init__.py", "component", "export", "mechanics")


def cache_dir() -> Path:
    """Folder holding the built FMUs."""
    root = os.environ.get("DELTAFMI_CACHE") or Path.home() / ".cache" / "deltafmi"
    return Path(root) / "fmus"


@lru_cache(maxsize=1)
def runtime_fingerprint() -> str:
    """SHA-256 over the runtime files that every built FMU contains."""
    package = Path(deltafmi.__file__).parent
    digest = hashlib.sha256(deltafmi.__version__.encode())
    for part in _RUNTIME_PARTS:
        root = package / part
        files = [root] if root.is_file() else sorted(
            p for p in root.rglob("*") if p.is_file() and p.suffix in (".py", ".c", ".h", ".json"))
        for file in files:
            digest.update(str(file.relative_to(package)).encode())
            digest.update(file.read_bytes())
    return digest.hexdigest()


def cache_key(source: Path) -> str:
    """Hex key of ``source`` built with the current runtime."""
    digest = hashlib.sha256(Path(source).read_bytes())
    digest.update(runtime_fingerprint().encode())
    return digest.hexdigest()[:24]


def built_fmu(source: str | Path) -> Path:
    """Path of the FMU built from ``source``, building it first unless the cache has it."""
    from deltafmi.export.build import build_fmu  # the lead's build API; imported late (heavy)

    source = Path(source).resolve()
    target = cache_dir() / cache_key(source) / (source.stem + ".fmu")
    if target.exists():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    # build beside the target and rename: concurrent runs never see a half-written FMU
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        built = Path(build_fmu(source, Path(tmp) / target.name))
        os.replace(built, target)
    return target
