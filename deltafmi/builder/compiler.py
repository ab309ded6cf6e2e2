"""The FMU binary: deltafmi's FMI loader and Python bridge, compiled once per FMI version.

The FMU binary (FMI loader + Python bridge) is the same for every FMU of one FMI version (binaries
export un-prefixed fmi2 or fmi3 names) and binds the Python C API at run time (``native/pyapi.h``),
so it needs no Python headers and is built once per source version and FMI version, then reused
for every FMU and every CPython >= 3.10. The FMI 2.0 and FMI 3.0 binaries share their plumbing
(``native/core.c``) and differ in their API file (``fmi2.c``, ``fmi3.c``); each exports its
version's functions and nothing else (hidden visibility, see ``exported_symbols``). Its sources
are the FMU runtime's (``deltafmi/runtime/native``); :mod:`deltafmi.toolchain` compiles and caches.
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import sysconfig
from pathlib import Path

from deltafmi.toolchain import BuildError, build_into, cache_dir, find_built, require_compiler, run_compiler

__all__ = ["NATIVE_DIR", "VERSION_FILES", "exported_symbols", "fmu_binary", "native_source_files",
           "python_runtime_config"]

NATIVE_DIR = Path(__file__).resolve().parent.parent / "runtime" / "native"  # the FMU binary's C sources
#: what both FMI versions' binaries are made of
SOURCES = ("core.c", "cs_step.c", "bridge.c", "python_start.c", "process_lock.c")
HEADERS = ("core.h", "cs_step.h", "bridge.h", "python_start.h", "process_lock.h", "glibc_floor.h", "pyapi.h")
#: how they are compiled: no fused multiply-add and pow() from libm, so that the Co-Simulation
#: step in C (cs_step.c) computes what the Python step computes, to the bit
CFLAGS = ("-shared", "-fPIC", "-O2", "-ffp-contract=off", "-fno-builtin-pow", "-fvisibility=hidden", "-Wall")
#: each FMI version's API file and the standard's headers it includes
VERSION_FILES = {
    2: ("fmi2.c", "fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
    3: ("fmi3.c", "fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h"),
}


def native_source_files(fmi_version: int = 2) -> list[Path]:
    """Every C source and header that goes into the binary of ``fmi_version`` (2 or 3), and into
    the FMU's sources/."""
    return [NATIVE_DIR / name for name in SOURCES + _version_files(fmi_version) + HEADERS]


def _version_files(fmi_version: int) -> tuple[str, ...]:
    try:
        return VERSION_FILES[fmi_version]
    except KeyError:
        raise ValueError(f"FMI version {fmi_version!r} is not one deltafmi builds (2 or 3)") from None


def fmu_binary(fmi_version: int = 2) -> Path:
    """The compiled FMU binary of ``fmi_version`` (2 or 3), from the cache, the prebuilt layer, or
    freshly built."""
    files = native_source_files(fmi_version)
    digest = hashlib.sha256()
    for path in files:
        digest.update(path.read_bytes())
    digest.update(" ".join(CFLAGS).encode())
    name = "fmu.so" if fmi_version == 2 else f"fmu{fmi_version}.so"
    relative = f"native/{digest.hexdigest()[:16]}/{name}"
    found = find_built(relative)
    if found is not None:
        return found
    api = NATIVE_DIR / _version_files(fmi_version)[0]
    cc = require_compiler(api)
    binary = cache_dir() / relative
    build_into(binary.parent, lambda tmp: run_compiler(
        [*cc, *CFLAGS, f"-I{NATIVE_DIR}", *[str(path) for path in files if path.suffix == ".c"],
         "-o", f"{tmp}/{binary.name}", "-ldl", "-lpthread", "-lm"], api))
    return binary


def exported_symbols(library: Path) -> list[str]:
    """Names of the functions and data a shared library exports (``nm -D --defined-only``)."""
    result = subprocess.run(["nm", "-D", "--defined-only", str(library)], capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(f"nm failed on {library}: {result.stderr.strip()}")
    return sorted(line.split()[-1] for line in result.stdout.splitlines() if line.strip())


def python_runtime_config() -> str:
    """Contents of ``resources/python.cfg``: how a C host finds and starts this Python."""
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    soname = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY") or ""
    library = os.path.join(libdir, soname) if sysconfig.get_config_var("Py_ENABLE_SHARED") else ""
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    stdlib = sysconfig.get_path("stdlib")
    return f"library={library}\nexecutable={sys.executable}\nversion={version}\nstdlib={stdlib}\n"
