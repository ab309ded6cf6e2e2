"""Turn a component source file into a real ``.fmu`` (binaries, resources, sources)."""
from .packager import build_cached, build_fmu, load_component_class

__all__ = ["build_cached", "build_fmu", "load_component_class"]
