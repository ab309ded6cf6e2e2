"""Compile deltafmi's numeric kernels with mypyc for the FMUs that bundle them.

The delta robot's derivative function and the controller are hand-written float algebra (see
``deltafmi/physics/delta/dynamics.py``): fast for Python, but still a few hundred interpreted
float operations per call. mypyc (the compiler that ships with mypy) turns exactly such typed
modules into C extension modules with unboxed floats and fixed-length tuples, same semantics,
about 3-5x faster. An FMU carries the compiled modules next to their sources in
``resources/python``; Python prefers an extension module over a source file of the same name, and
falls back to the source when the host's Python differs from the one that built the FMU.

Kernels that import one another are compiled together, as one mypyc group (one shared library,
native calls between them); unrelated ones in groups of their own, so that an FMU carries only
the groups of the modules its model reaches (the robot's FMU has no controller kernel, the
contact examples' FMUs have none).
The libraries are stripped of their symbol tables (``strip --strip-unneeded``; the dynamic
symbols stay).

The compiled result is cached like the native binaries, and found in the wheel's prebuilt layer
like them (see :mod:`deltafmi.builder.compiler`): a wheel user needs neither mypy nor a compiler.
Where they must be compiled and mypy is missing, or compilation fails, FMUs ship the plain Python
kernels (same results, slower) and a warning says so.
"""
from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import warnings
from pathlib import Path
from typing import Iterable, Optional

import deltafmi

from deltafmi.toolchain import NoCompilerError, abi_tag, build_into, cache_dir, find_built, require_compiler, strip_unneeded
from .reach import direct_imports, module_source, reached_modules

__all__ = ["compiled_kernels", "kernel_groups", "kernel_modules", "kernels_path", "mypyc_version"]

PACKAGE_DIR = Path(deltafmi.__file__).parent
#: modules compiled into FMUs (their imports are type-checked, not compiled)
COMPILED_MODULES = ("physics/delta/kinematics.py", "physics/delta/dynamics.py",
                    "physics/delta/control_law.py", "physics/delta/jacobian.py")
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


def kernel_modules() -> list[str]:
    """Module names of :data:`COMPILED_MODULES`."""
    return ["deltafmi." + name.removesuffix(".py").replace("/", ".") for name in COMPILED_MODULES]


def kernel_groups() -> list[list[str]]:
    """The compiled modules partitioned into mypyc groups: the connected parts of their imports
    of one another (the modules of a group call each other natively)."""
    modules = kernel_modules()
    group_of = {name: {name} for name in modules}
    for name in modules:
        for other in direct_imports(name) & set(modules):
            merged = group_of[name] | group_of[other]
            for member in merged:
                group_of[member] = merged
    groups = {tuple(sorted(group)) for group in group_of.values()}
    return [list(group) for group in sorted(groups)]


def compiled_kernels(modules: Optional[Iterable[str]] = None) -> list[tuple[Path, str]]:
    """(extension module, path relative to ``resources/python``) of the compiled kernels that the
    deltafmi ``modules`` need (all kernels when None): each included kernel module's shim and
    its group's shared library.

    Empty, with a warning, when mypyc is not installed or the compilation failed.
    """
    wanted = set(kernel_modules() if modules is None else modules) & set(kernel_modules())
    if not wanted:
        return []  # no warning either: nothing compiled would go in
    relative = kernels_path()
    target = find_built(relative)
    if target is None:
        if mypyc_version() is None:
            warnings.warn("mypy (mypyc) is not installed: FMUs ship plain Python kernels "
                          "(same results, several times slower)", stacklevel=2)
            return []
        try:
            require_compiler(PACKAGE_DIR / COMPILED_MODULES[0])
        except NoCompilerError as exc:
            warnings.warn(f"FMUs ship plain Python kernels (same results, slower): {exc}", stacklevel=2)
            return []
        target = cache_dir() / relative
        try:
            _compile_into(target, kernel_groups())
        except (subprocess.CalledProcessError, OSError) as exc:
            detail = (getattr(exc, "stdout", "") or "") + (getattr(exc, "stderr", "") or "") or str(exc)
            warnings.warn(f"compiling the kernels with mypyc failed; FMUs ship plain Python kernels:\n"
                          f"{detail[-2000:]}", stacklevel=2)
            return []
    owners: dict[str, list[str]] = json.loads((target / _MANIFEST).read_text())
    return [(target / relative, relative) for relative, owned in sorted(owners.items()) if wanted & set(owned)]


def kernels_path() -> str:
    """Where the compiled kernels of this source tree live, relative to the cache (and to the
    prebuilt layer): keyed by the sources mypyc compiles and type-checks, the groups, the flags
    and this Python's ABI (``SOABI``: version and platform), not by the mypy version, since the
    compiled modules carry mypyc's runtime and need no mypy, nor by the full ``sys.version``:
    kernels built elsewhere for the same CPython ABI serve here."""
    abi = sysconfig.get_config_var("SOABI") or abi_tag()
    digest = hashlib.sha256(f"{abi}|{kernel_groups()}|{_CFLAGS}|{_SETUP}|strip".encode())
    # mypyc type-checks what the kernels import: their sources are part of the compilation
    for name in reached_modules(modules=kernel_modules(), runtime=False):
        digest.update(name.encode() + module_source(name).read_bytes())
    return f"kernels/{digest.hexdigest()[:16]}"


#: which modules each compiled file serves (relative path -> module names), written beside them
_MANIFEST = "kernels.json"


def _group_name(group: list[str]) -> str:
    package = group[0].rpartition(".")[0]
    return package + "." + "_".join(name.rpartition(".")[2] for name in group)


def _compile_into(target: Path, groups: list[list[str]]) -> None:
    def build(out: str) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            shutil.copytree(PACKAGE_DIR, work / "deltafmi",
                            ignore=shutil.ignore_patterns("__pycache__", "*.so", "_prebuilt"))
            separate = [([_source(name) for name in group], _group_name(group)) for group in groups]
            (work / "setup.py").write_text(_SETUP.format(paths=[p for paths, _ in separate for p in paths],
                                                         separate=separate))
            env = dict(os.environ, CFLAGS=f"{os.environ.get('CFLAGS', '')} {_CFLAGS}".strip())
            subprocess.run([sys.executable, "setup.py", "build_ext", "--inplace"], cwd=work,
                           env=env, check=True, capture_output=True, text=True)
            owners = {}
            for group, (_, group_name) in zip(groups, separate):
                files = [(group_name + "__mypyc", group)] + [(name, [name]) for name in group]
                for module, owned in files:
                    relative = module.replace(".", "/") + _SUFFIX
                    destination = Path(out) / relative
                    destination.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copy2(work / relative, destination)
                    strip_unneeded(destination)
                    owners[relative] = owned
            (Path(out) / _MANIFEST).write_text(json.dumps(owners, indent=1))

    build_into(target, build)


def _source(name: str) -> str:
    return name.replace(".", "/") + ".py"


# mypyc's command line (python -m mypyc) cannot choose the groups; this is its setup.py with them
_SETUP = """\
from setuptools import setup
from mypyc.build import mypycify

setup(name="deltafmi_kernels",
      ext_modules=mypycify(["--follow-imports=silent", *{paths!r}], opt_level="3", separate={separate!r}))
"""
