"""The C toolchain: compile a C source into a shared library with the system compiler, once, cached.

Every native piece deltafmi compiles (an FMU's binary and kernels, the master's C stepping loop,
its CSV formatter) is looked up under one relative path (``native/<stem>-<digest>/<file>``, the
digest taken over its sources, flags and the Python ABI where it has one) in two places: the
per-user cache ``$DELTAFMI_CACHE`` (default ``~/.cache/deltafmi``), then ``deltafmi/_prebuilt``,
which an installed wheel carries (``deltafmi.builder.prebuild`` fills it at wheel build time). Only
when both miss is it compiled, and only then is a C compiler needed. The keys name no compiler
and no machine path, so that what the wheel's build machine compiled is found on the user's.

``$DELTAFMI_CACHE_SEED`` may name another cache of this machine (read only): a piece found there
under its key is copied instead of compiled again (the wheel test builds its wheel's prebuilt layer
from the pieces its own session has compiled).
"""
from __future__ import annotations

import hashlib
import os
import shlex
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator, Optional, Sequence

__all__ = ["BuildError", "NoCompilerError", "PREBUILT_DIR", "abi_tag", "build_into", "building", "cache_dir", "compiler_available",
           "compiler_name", "compiler_output", "find_built", "no_compiler_message", "plain_c_library",
           "python_extension", "python_include", "require_compiler", "run_compiler", "seeded_file", "single_file_library",
           "strip_unneeded"]

from deltafmi.errors import DeltaFmiError


class BuildError(DeltaFmiError, RuntimeError):
    """The native build failed (no compiler, compiler error, missing Python headers)."""


class NoCompilerError(BuildError):
    """A native piece is neither cached nor prebuilt, and no C compiler is there to build it."""


#: the read-only layer of prebuilt pieces an installed wheel carries (absent in a source checkout)
PREBUILT_DIR = Path(__file__).resolve().parent / "_prebuilt"
#: the most compiler output a BuildError carries (its end: the first error is usually enough, and
#: the last lines say how many followed)
_MAX_OUTPUT_LINES = 30


def cache_dir() -> Path:
    """Root of deltafmi's build cache."""
    return Path(os.environ.get("DELTAFMI_CACHE", Path.home() / ".cache" / "deltafmi"))


def compiler_name() -> str:
    """The C compiler deltafmi would run: ``$CC``, else ``cc`` (whether or not it exists)."""
    return os.environ.get("CC") or "cc"


def no_compiler_message(cc: Optional[str] = None) -> str:
    """What to say when something must be compiled and ``cc`` is not there (one line): from a
    clone, that the wheel carries the packaged models prebuilt; from the wheel (its prebuilt layer
    is there), that those cover the packaged models as shipped, not an edited copy or a new one."""
    missing = f"building needs a C compiler ({cc or compiler_name()} not found; install gcc or set CC)"
    if PREBUILT_DIR.exists():
        return (f"{missing}; this installation's prebuilt pieces cover the packaged models as shipped, not an "
                "edited copy of one or a component of your own")
    return (f"{missing}; the packaged models need none when deltafmi is installed from its wheel, which carries "
            "them prebuilt")


def _compiler_command() -> list[str]:
    return shlex.split(compiler_name()) or ["cc"]  # $CC may carry words, e.g. ``ccache gcc``


def compiler_available() -> bool:
    """Whether the C compiler deltafmi would run is there."""
    return bool(shutil.which(_compiler_command()[0]))


def require_compiler(what: Path) -> list[str]:
    """The compiler's command to build ``what``; :class:`NoCompilerError` naming ``what`` when
    there is none."""
    cc = _compiler_command()
    if not shutil.which(cc[0]):
        raise NoCompilerError(f"{_shown(what)}: {no_compiler_message(cc[0])}")
    return cc


def find_built(relative: str) -> Optional[Path]:
    """``relative`` (a path inside the cache) in the user's cache, else in the prebuilt layer."""
    for root in (cache_dir(), PREBUILT_DIR):
        if (root / relative).exists():
            return root / relative
    return None


def abi_tag() -> str:
    """The Python ABI a piece built against this interpreter's headers works with
    (``cpython-311``), stable across machines, unlike the headers' path."""
    return sys.implementation.cache_tag or sys.implementation.name


def plain_c_library(source: Path) -> Path:
    """A shared library compiled from one self-contained C file (no Python; POSIX threads and
    dlsym at hand), from the cache."""
    return single_file_library(source, f"{source.stem}.so", [], libraries=["-lpthread", "-ldl"])


def python_extension(source: Path) -> Path:
    """A C extension module for this Python's stable ABI (``<name>.abi3.so``), from the cache.

    Raises :class:`BuildError` when it cannot be compiled (no compiler, no Python headers)."""
    return single_file_library(source, f"{source.stem}.abi3.so", [python_include], abi_tag())


def python_include() -> str:
    """This Python's header directory; :class:`BuildError` when it has no headers."""
    include = sysconfig.get_paths()["include"]
    if not Path(include, "Python.h").exists():
        raise BuildError(f"no Python headers in {include} (install the python3-dev package)")
    return include


def single_file_library(source: Path, name: str, includes: Sequence[Callable[[], str]] = (),
                        abi: str = "", flags: Sequence[str] = (), libraries: Sequence[str] = ()) -> Path:
    """``source`` compiled into the shared library ``name``, keyed by the source, ``abi`` (the
    Python ABI it is built for, empty for none), the extra compiler ``flags`` and ``libraries``
    (``-lm``); ``includes`` give its include directories, asked for only when it must be compiled
    (a Python's headers are needed only then)."""
    key = f"\0{name}\0{abi}\0{' '.join(flags)}\0{' '.join(libraries)}"
    digest = hashlib.sha256(source.read_bytes() + key.encode("utf-8", "surrogateescape")).hexdigest()[:16]
    relative = f"native/{source.stem}-{digest}/{name}"
    found = find_built(relative)
    if found is not None:
        return found
    cc = require_compiler(source)
    options = [f"-I{include()}" for include in includes] + list(flags)
    library = cache_dir() / relative
    build_into(library.parent, lambda tmp: run_compiler([*cc, "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall",
                                                  *options, str(source), "-o", f"{tmp}/{name}", *libraries],
                                                 source))
    return library


def build_into(target: Path, build: Callable[[str], object]) -> None:
    """Run ``build(directory)`` in a fresh directory and move it to ``target`` atomically (a
    concurrent build of the same target may win; its result is then used). A ``target`` in the
    cache that the seed cache (``$DELTAFMI_CACHE_SEED``) holds is copied from there instead."""
    target.parent.mkdir(parents=True, exist_ok=True)
    with building(target):
        if target.exists():  # another process built it while this one waited
            return
        _build_into(target, build)


def _build_into(target: Path, build: Callable[[str], object]) -> None:
    seeded = _seeded(target)
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        if seeded is not None:
            shutil.copytree(seeded, tmp, dirs_exist_ok=True)
        else:
            build(tmp)
        try:
            os.rename(tmp, target)  # atomic: parallel builds race harmlessly
        except OSError:
            if not target.exists():
                raise
        else:
            os.makedirs(tmp)  # let TemporaryDirectory clean up the (now empty) name


@contextmanager
def building(target: Path) -> Iterator[None]:
    """Hold the lock of ``target``'s build: processes that build the same piece at once (the
    test suite's workers, a study's) wait for the first one and find its result, rather than
    compiling it side by side. The lock files live in the temporary directory, never in the cache
    (a wheel's prebuilt layer is a cache). Where locks cannot be taken, builds run unlocked and
    race harmlessly (see :func:`build_into`)."""
    try:
        import fcntl
        folder = Path(tempfile.gettempdir()) / "deltafmi-build-locks"
        folder.mkdir(exist_ok=True)
        name = hashlib.sha256(os.fsencode(Path(target).resolve())).hexdigest()[:32]
        handle = open(folder / name, "a")
    except (ImportError, OSError):
        yield
        return
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX)
        except OSError:
            pass
        yield  # closing the file releases the lock


def _in_seed(target: Path) -> Optional[Path]:
    """``target``'s path in the seed cache ``$DELTAFMI_CACHE_SEED`` (same relative path), or None:
    no seed, or ``target`` outside the cache."""
    seed = os.environ.get("DELTAFMI_CACHE_SEED")
    if not seed:
        return None
    try:
        relative = Path(target).resolve().relative_to(cache_dir().resolve())
    except ValueError:
        return None
    return Path(seed) / relative


def _seeded(target: Path) -> Optional[Path]:
    """``target``'s folder in the seed cache ``$DELTAFMI_CACHE_SEED`` (same key, same relative
    path), or None: no seed, ``target`` outside the cache, or not in the seed."""
    found = _in_seed(target)
    return found if found is not None and found.is_dir() and any(found.iterdir()) else None


def seeded_file(target: Path) -> Optional[Path]:
    """The file ``target`` (a path in the cache) in the seed cache ``$DELTAFMI_CACHE_SEED``, or None."""
    found = _in_seed(target)
    return found if found is not None and found.is_file() else None


def strip_unneeded(library: Path) -> None:
    """Drop a shared library's symbol table and debug information in place; its dynamic symbols
    (what dlsym and the loader need) stay. Nothing happens where binutils' strip is missing."""
    if shutil.which("strip"):
        subprocess.run(["strip", "--strip-unneeded", str(library)], check=True, capture_output=True, text=True,
                       errors="replace")


def run_compiler(command: list[str], source: Path) -> None:
    """Run the compiler ``command`` that builds from ``source``; :class:`BuildError` with its messages when it fails."""
    try:
        result = subprocess.run(command, capture_output=True, text=True, errors="replace")  # file names: any bytes
    except OSError as exc:  # found by which, yet not runnable
        raise NoCompilerError(f"{_shown(source)}: {no_compiler_message(command[0])} ({exc.strerror})") from None
    if result.returncode != 0:
        raise BuildError(f"{_shown(source)}: compiling failed ({command[0]} exited with {result.returncode}):\n"
                         f"{compiler_output(result.stdout + result.stderr)}\n$ {' '.join(command)}")


def compiler_output(text: str) -> str:
    """The compiler's messages, at most :data:`_MAX_OUTPUT_LINES` lines (the first ones: the first
    error is the one to fix), or a note that it printed nothing."""
    lines = text.strip().splitlines()
    if not lines:
        return "(the compiler printed nothing)"
    if len(lines) > _MAX_OUTPUT_LINES:
        lines = lines[:_MAX_OUTPUT_LINES] + [f"... ({len(lines) - _MAX_OUTPUT_LINES} more lines)"]
    return "\n".join(lines)


def _shown(path: Path) -> str:
    """``path`` relative to the package when it is inside it (messages stay short)."""
    try:
        return f"deltafmi/{path.resolve().relative_to(Path(__file__).resolve().parent.parent).as_posix()}"
    except ValueError:
        return str(path)
