"""Compile deltafmi's numeric kernels with mypyc for the FMUs that bundle them.

The delta robot's derivative function and the controller are hand-written float algebra (see
``deltafmi/mechanics/delta/dynamics.py``): fast for Python, but still a few hundred interpreted
float operations per call. mypyc (the compiler that ships with mypy) turns exactly such typed
modules into C extension modules with unboxed floats and fixed-length tuples, same semantics,
about 3-5x faster. An FMU carries the compiled modules next to their sources in
``resources/python``; Python prefers an extension module over a source file of the same name, and
falls back to the source when the host's Python differs from the one that built the FMU.

The compiled result is cached like the native binaries. Without mypy, or if compilation fails,
FMUs ship the plain Python kernels (same results, slower) and a warning says so.
"""
from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import warnings
from pathlib import Path
from typing import Optional

import deltafmi

from .compiler import build_into, cache_dir

PACKAGE_DIR = Path(deltafmi.__file__).parent
#: modules compiled into FMUs (their imports are type-checked, not compiled)
COMPILED_MODULES = ("mechanics/delta/kinematics.py", "mechanics/delta/dynamics.py",
                    "mechanics/delta/control_law.py", "mechanics/delta/jacobian.py")
_SUFFIX = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
#: export only PyInit_* (mypyc's runtime helpers, CPy*, stay private to each FMU's copy)
_CFLAGS = "-fvisibility=hidden"


def mypyc_version() -> Optional[str]:
    """mypy's version when mypyc can be used here, else None."""
    try:
        import mypy.version
    except ImportError:
        return None
    return mypy.version.__version__ if importlib.util.find_spec("mypyc") else None


def compiled_kernels() -> list[tuple[Path, str]]:
    """(extension module, path relative to ``resources/python``) for the compiled kernels.

    Empty, with a warning, when mypyc is not installed or the compilation failed.
    """
    version = mypyc_version()
    if version is None:
        warnings.warn("mypy (mypyc) is not installed: FMUs ship plain Python kernels "
                      "(same results, several times slower)", stacklevel=2)
        return []
    sources = sorted((PACKAGE_DIR / "mechanics").rglob("*.py"))
    digest = hashlib.sha256(f"{version}|{sys.version}|{COMPILED_MODULES}|{_CFLAGS}".encode())
    for path in sources:
        digest.update(path.relative_to(PACKAGE_DIR).as_posix().encode() + path.read_bytes())
    target = cache_dir() / "kernels" / digest.hexdigest()[:16]
    if not target.is_dir():
        try:
            _compile_into(target)
        except (subprocess.CalledProcessError, OSError) as exc:
            detail = getattr(exc, "stdout", "") or str(exc)
            warnings.warn(f"compiling the kernels with mypyc failed; FMUs ship plain Python kernels:\n"
                          f"{detail[-2000:]}", stacklevel=2)
            return []
    return [(path, path.relative_to(target).as_posix()) for path in sorted(target.rglob(f"*{_SUFFIX}"))]


def _compile_into(target: Path) -> None:
    def build(out: str) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            shutil.copytree(PACKAGE_DIR, work / "deltafmi", ignore=shutil.ignore_patterns("__pycache__", "*.so"))
            modules = [f"deltafmi/{name}" for name in COMPILED_MODULES]
            env = dict(os.environ, CFLAGS=f"{os.environ.get('CFLAGS', '')} {_CFLAGS}".strip())
            subprocess.run([sys.executable, "-m", "mypyc", "--follow-imports=silent", *modules], cwd=work,
                           env=env, check=True, capture_output=True, text=True)
            for library in work.rglob(f"*{_SUFFIX}"):
                if "build" not in library.relative_to(work).parts:
                    destination = Path(out) / library.relative_to(work)
                    destination.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copy2(library, destination)

    build_into(target, build)
