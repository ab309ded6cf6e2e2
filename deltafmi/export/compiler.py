"""Compile the FMU binary (FMI loader + Python bridge) with the system C compiler, once, cached.

The binary is the same for every FMU (FMI 2.0 binaries export un-prefixed fmi2 names) and binds
the Python C API at run time (``native/pyapi.h``), so it needs no Python headers and is built once
per source version and compiler, then reused for every FMU and every CPython >= 3.10. It exports
the fmi2 functions and nothing else (hidden visibility, see ``exported_symbols``). The cache lives
in ``$DELTAFMI_CACHE`` (default ``~/.cache/deltafmi``).
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path
from typing import Callable

NATIVE_DIR = Path(__file__).parent / "native"
SOURCES = ("loader.c", "bridge.c", "python_start.c", "process_lock.c")
HEADERS = ("bridge.h", "python_start.h", "process_lock.h", "glibc_floor.h", "pyapi.h", "fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")


class BuildError(RuntimeError):
    """The native build failed (no compiler, compiler error, missing Python headers)."""


def cache_dir() -> Path:
    """Root of deltafmi's build cache."""
    return Path(os.environ.get("DELTAFMI_CACHE", Path.home() / ".cache" / "deltafmi"))


def native_source_files() -> list[Path]:
    """Every C source and header that goes into the binary (and into the FMU's sources/)."""
    return [NATIVE_DIR / name for name in SOURCES + HEADERS]


def _compiler() -> str:
    cc = os.environ.get("CC", "cc")
    if not shutil.which(cc):
        raise BuildError(f"no C compiler found (looked for '{cc}'; set $CC). deltafmi compiles the FMU "
                         "binary with the system C compiler.")
    return cc


def fmu_binary() -> Path:
    """The compiled FMU binary, from the cache or freshly built."""
    cc = _compiler()
    digest = hashlib.sha256()
    for path in native_source_files():
        digest.update(path.read_bytes())
    digest.update(cc.encode())
    target = cache_dir() / "native" / digest.hexdigest()[:16]
    binary = target / "fmu.so"
    if not binary.exists():
        build_into(target, lambda tmp: _run(
            [cc, "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall", f"-I{NATIVE_DIR}",
             *[str(NATIVE_DIR / name) for name in SOURCES], "-o", f"{tmp}/{binary.name}",
             "-ldl", "-lpthread", "-lm"]))
    return binary


def exported_symbols(library: Path) -> list[str]:
    """Names of the functions and data a shared library exports (``nm -D --defined-only``)."""
    result = subprocess.run(["nm", "-D", "--defined-only", str(library)], capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(f"nm failed on {library}: {result.stderr.strip()}")
    return sorted(line.split()[-1] for line in result.stdout.splitlines() if line.strip())


def plain_c_library(source: Path) -> Path:
    """A shared library compiled from one self-contained C file (no Python), from the cache."""
    return single_file_library(source, f"{source.stem}.so", [])


def python_extension(source: Path) -> Path:
    """A C extension module for this Python's stable ABI (``<name>.abi3.so``), from the cache.

    Raises :class:`BuildError` when it cannot be compiled (no compiler, no Python headers)."""
    return single_file_library(source, f"{source.stem}.abi3.so", [f"-I{python_include()}"])


def python_include() -> str:
    """This Python's header directory; :class:`BuildError` when it has no headers."""
    include = sysconfig.get_paths()["include"]
    if not Path(include, "Python.h").exists():
        raise BuildError(f"no Python headers in {include} (install the python3-dev package)")
    return include


def single_file_library(source: Path, name: str, flags: list[str]) -> Path:
    """``source`` compiled into the shared library ``name``, cached by source, compiler and flags."""
    cc = _compiler()
    digest = hashlib.sha256(source.read_bytes() + cc.encode() + " ".join(flags).encode()).hexdigest()[:16]
    target = cache_dir() / "native" / f"{source.stem}-{digest}"
    library = target / name
    if not library.exists():
        build_into(target, lambda tmp: _run([cc, "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall", *flags,
                                              str(source), "-o", f"{tmp}/{name}"]))
    return library


def build_into(target: Path, build: Callable[[str], object]) -> None:
    """Run ``build(directory)`` in a fresh directory and move it to ``target`` atomically (a
    concurrent build of the same target may win; its result is then used)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        build(tmp)
        try:
            os.rename(tmp, target)  # atomic: parallel builds race harmlessly
        except OSError:
            if not target.exists():
                raise
        else:
            os.makedirs(tmp)  # let TemporaryDirectory clean up the (now empty) name


def strip_unneeded(library: Path) -> None:
    """Drop a shared library's symbol table and debug information in place; its dynamic symbols
    (what dlsym and the loader need) stay. Nothing happens where binutils' strip is missing."""
    if shutil.which("strip"):
        subprocess.run(["strip", "--strip-unneeded", str(library)], check=True, capture_output=True, text=True)


def _run(command: list[str]) -> None:
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(f"compiling a native library failed:\n$ {' '.join(command)}\n{result.stderr}")


def python_runtime_config() -> str:
    """Contents of ``resources/python.cfg``: how a C host finds and starts this Python."""
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    soname = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY") or ""
    library = os.path.join(libdir, soname) if sysconfig.get_config_var("Py_ENABLE_SHARED") else ""
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    stdlib = sysconfig.get_path("stdlib")
    return f"library={library}\nexecutable={sys.executable}\nversion={version}\nstdlib={stdlib}\n"
