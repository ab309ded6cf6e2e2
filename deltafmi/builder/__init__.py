"""Turn a component source file into a real ``.fmu`` (binaries, resources, sources).

The names below load :mod:`.packager` on first use (PEP 562), so that a module of the builder
(the build cache's fast path, :mod:`.build_stamps`) imports without the packager and the code
generator behind it. The builder is never bundled into an FMU, so laziness is safe here.
"""
from typing import Any

__all__ = ["build_cached", "build_fmu", "load_component_class"]


def __getattr__(name: str) -> Any:
    if name not in __all__:
        raise AttributeError(f"module 'deltafmi.builder' has no attribute '{name}'")
    from . import packager

    return getattr(packager, name)


def __dir__() -> list:
    return sorted(set(globals()) | set(__all__))
