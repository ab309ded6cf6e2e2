"""Compile every native piece the packaged models use into a folder: the wheel's prebuilt layer.

``python -m deltafmi.builder.prebuild DIR`` (run by ``setup.py`` when it builds a wheel, into
``build/lib/deltafmi/_prebuilt``) compiles, with the same functions and under the same relative
paths as the per-user cache (see :mod:`deltafmi.builder.compiler`): the FMU binaries (FMI 2.0 and 3.0), the compiled
value access, the packaged models' compiled kernels (C generated from their Python), the C
pieces of the master and the CSV writer, and the starter of portable FMUs: native C only. An
installed wheel finds them there, so that its user needs no C compiler or Python headers to build and run the packaged models, nor their edited copies (their FMUs carry
the same binary and kernels). Anything that cannot be built is an error: a wheel without a piece
would compile it on the user's machine, the thing the layer is there to avoid. Pieces that the
cache named by ``$DELTAFMI_CACHE_SEED`` holds are copied from it rather than compiled again (see
:mod:`deltafmi.toolchain`).
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

__all__: list[str] = []

#: the ctypes libraries of the co-simulation master and the result writer (package-relative)


def prebuild(target: Path) -> list[Path]:
    """Build every prebuilt piece into ``target`` (emptied first); returns the files made."""
    target = Path(target).resolve()
    if target.exists():
        shutil.rmtree(target)
    target.mkdir(parents=True)
    os.environ["DELTAFMI_CACHE"] = str(target)  # the functions below build into "the cache"
    from deltafmi import toolchain

    if toolchain.PREBUILT_DIR.exists():  # an installed wheel's layer would be found, not rebuilt
        raise SystemExit(f"prebuild: run it from a source tree ({toolchain.PREBUILT_DIR} exists)")
    build_pieces()
    return sorted(path for path in target.rglob("*") if path.is_file())


def build_pieces() -> None:
    """Build every piece of the prebuilt layer into the build cache (``$DELTAFMI_CACHE``), where
    those already there are found rather than built again."""
    from deltafmi import toolchain
    from . import compiler
    from .packager import PLAIN_C_SOURCES, VALUE_ACCESS_SOURCE
    from .portable import starter_library

    package = Path(compiler.__file__).resolve().parent.parent
    for fmi_version in compiler.VERSION_FILES:
        compiler.fmu_binary(fmi_version)
    if sys.version_info >= (3, 11):  # its stable ABI is 3.11's; FMUs built on 3.10 use the Python stand-ins
        toolchain.python_extension(VALUE_ACCESS_SOURCE)
    for relative in PLAIN_C_SOURCES:
        toolchain.plain_c_library(package / relative)
    starter_library()
    models = _this_trees_models()
    from .codegen.component_kernels import component_library
    for name in models.MODELS:  # the packaged models' compiled kernels (C generated from their Python)
        if name in models.PYTHON_ONLY:  # nothing to compile (and an MPC's scipy need not be in the build env)
            continue
        if component_library(getattr(models, name)) is None:
            raise SystemExit(f"prebuild: {name}'s kernels were not compiled")


def _this_trees_models():
    """``deltafmi.models`` from this source tree's ``fmu_src/``, not the models of whatever
    deltafmi an editable install maps the name to (setup.py runs this from a clean copy)."""
    import importlib.util

    from deltafmi.shipped import MODELS_DIR

    loaded = sys.modules.get("deltafmi.models")
    if loaded is not None and Path(loaded.__file__).resolve().parent == MODELS_DIR.resolve():
        return loaded
    spec = importlib.util.spec_from_file_location("deltafmi.models", MODELS_DIR / "__init__.py",
                                                  submodule_search_locations=[str(MODELS_DIR)])
    models = importlib.util.module_from_spec(spec)
    sys.modules["deltafmi.models"] = models
    spec.loader.exec_module(models)
    return models


def main(argv: list[str] | None = None) -> None:
    """Command line: ``python -m deltafmi.builder.prebuild DIR``."""
    parser = argparse.ArgumentParser(prog="python -m deltafmi.builder.prebuild", description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path)
    args = parser.parse_args(argv)
    try:
        files = prebuild(args.directory)
    except Exception as exc:  # noqa: BLE001 - the wheel build prints one clear line and fails
        raise SystemExit(f"prebuild failed: {exc}") from None
    size = sum(path.stat().st_size for path in files)
    print(f"prebuilt {len(files)} files ({size / 1e6:.1f} MB) into {args.directory}", file=sys.stderr)


if __name__ == "__main__":
    main()
