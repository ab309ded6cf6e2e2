"""The equation compiler: equation models (deltafmi.runtime.equations) -> generated kernels.

Importing it registers :func:`compile_to_cache` with the runtime, which calls it at class
creation when a model's generated module is not built yet. sympy does the symbolic work (imported
only when an equation model is compiled, so that other builds do not pay for it).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

from deltafmi.runtime.equations import component as _component
from deltafmi.toolchain import building, cache_dir, find_built, seeded_file
from deltafmi.runtime.equations.model import EquationModelError, FlatModel

#: the compiler's own files: what a generated module depends on besides the model
SOURCES = sorted(Path(__file__).parent.glob("*.py"))


def compile_to_cache(cls: type, flat: FlatModel, name: str) -> Path:
    """The generated module ``name`` of ``flat`` in the build cache, generated when missing
    (where :func:`deltafmi.runtime.equations.component.equations_cache` finds it)."""
    path = _component.equations_cache(name)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists():
        return path
    # processes that need the same module at once wait for the first one's (the symbolic work
    # takes seconds); one that the seed cache holds (the wheel's build), or an installed wheel's
    # prebuilt layer (the packaged models'), is copied from there
    with building(path):
        if path.exists():
            return path
        seeded = seeded_file(path) or find_built(path.relative_to(cache_dir()).as_posix())
        if seeded is not None:
            source = seeded.read_text()
        else:
            try:
                import sympy  # noqa: F401  (the symbolic work; imported only for equation models)
            except ImportError:  # pragma: no cover - sympy is one of deltafmi's dependencies
                raise EquationModelError(f"{cls.__name__}: compiling an equation model needs sympy: "
                                         f"pip install sympy") from None
            from .emit import generate

            source = generate(flat, name, getattr(cls, "constraint_pole", 0.0))
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)
    return path


def generated_files(cls: type) -> list[tuple[Path, str]]:
    """(file, archive name) of the generated modules the FMU of ``cls`` carries: those of every
    equation component its module defines or imports (the FMU imports that module, and each of
    them is compiled as its class is made), ``cls``'s first; none for other components."""
    namespace = vars(sys.modules[cls.__module__]) if cls.__module__ in sys.modules else {}
    classes = [cls] + [c for c in namespace.values() if isinstance(c, type) and c is not cls]
    files: dict = {}
    for c in classes:
        found = _component.generated_file(c) if "_equations" in vars(c) else None
        if found is not None:
            path, module = found
            files.setdefault(Path(path), "resources/python/" + module.replace(".", "/") + ".py")
    return list(files.items())


if not _component.COMPILER:
    _component.COMPILER.append(compile_to_cache)

__all__ = ["compile_to_cache", "generated_files", "EquationModelError"]
