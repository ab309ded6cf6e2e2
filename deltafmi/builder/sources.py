"""What names a component to build: a source file, or a class in an importable module.

``path/to/model.py`` (the one component it defines), ``path/to/model.py:Class``,
``package.module:Class`` (``deltafmi.models:DeltaRobot``), or the bare class name of a packaged
model (``DeltaRobot``, for the CLI).
"""
from __future__ import annotations

import importlib
import inspect
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from .source_error import ComponentSourceError

__all__ = ["ComponentSourceError", "find_component", "is_module_reference", "module_component", "packaged_model_names",
           "split_file_reference"]

_MODULE_REFERENCE = re.compile(r"(?P<module>[A-Za-z_][\w.]*):(?P<name>[A-Za-z_]\w*)")


@dataclass(frozen=True)
class ComponentSource:
    """A component's source file and, where the file may define several, the class to build."""

    path: Path
    class_name: Optional[str] = None

    def __str__(self) -> str:
        return f"{self.path}:{self.class_name}" if self.class_name else str(self.path)


def split_file_reference(text: str) -> tuple[str, Optional[str]]:
    """``'model.py:Class'`` -> ``('model.py', 'Class')``; ``'model.py'`` -> ``('model.py', None)``
    (a Modelica file too: ``'models.mo:Ball'``)."""
    file, colon, name = text.rpartition(":")
    if colon and file.endswith((".py", ".mo")) and re.fullmatch(r"[A-Za-z_]\w*", name):
        return file, name
    return text, None


def is_module_reference(text: str) -> bool:
    """Whether ``text`` names a class in a module (``package.module:Class``), not a file."""
    match = _MODULE_REFERENCE.fullmatch(text)
    return bool(match) and not match["module"].endswith(".py")


def packaged_model_names() -> list[str]:
    """Class names of the models shipped in :mod:`deltafmi.models`."""
    from deltafmi.models import MODELS
    return sorted(MODELS)


def module_component(reference: str) -> ComponentSource:
    """The source of ``package.module:Class``, or of a packaged model given by its class name."""
    if ":" not in reference:
        if reference not in packaged_model_names():
            from deltafmi.errors import did_you_mean
            hint = did_you_mean(reference, packaged_model_names()) or \
                f" (packaged models: {', '.join(packaged_model_names())})"
            raise ComponentSourceError(f"'{reference}' is neither a file nor a packaged model{hint}")
        reference = f"deltafmi.models:{reference}"
    if not is_module_reference(reference):
        raise ComponentSourceError(f"'{reference}': expected package.module:ClassName")
    module_name, _, class_name = reference.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        file = module_name.replace(".", "/") + ".py"
        raise ComponentSourceError(f"'{reference}': cannot import {module_name}: {exc} (install its package, put "
                                   f"its folder on PYTHONPATH, or name the file: {file}:{class_name})") from None
    except Exception as exc:  # noqa: BLE001 - the user's module failed while importing
        raise ComponentSourceError(f"'{reference}': importing {module_name} failed: {exc!r}") from None
    from deltafmi.runtime import Component
    cls = getattr(module, class_name, None)
    if not (isinstance(cls, type) and issubclass(cls, Component)):
        if hasattr(module, "__getattr__") and hasattr(module, "__all__"):
            # a module that imports its attributes when asked (deltafmi.models: a module per model)
            # names them in __all__: suggest from those names rather than importing every one
            names = list(module.__all__)
        else:
            names = [n for n in dir(module) if isinstance(getattr(module, n, None), type)
                     and issubclass(getattr(module, n), Component) and getattr(module, n) is not Component]
        from deltafmi.errors import did_you_mean
        raise ComponentSourceError(f"'{reference}': {module_name} has no component class '{class_name}'"
                                   f"{did_you_mean(class_name, names)}")
    path = inspect.getsourcefile(cls)
    if path is None:
        raise ComponentSourceError(f"'{reference}': the source file of {class_name} is not available")
    defining = sys.modules[cls.__module__]
    others = [obj for obj in vars(defining).values() if isinstance(obj, type) and issubclass(obj, Component)
              and obj.__module__ == cls.__module__ and obj is not cls]
    # the class is named only where its file defines several: the same FMU (and cache entry) as
    # the file named alone, or a copy of it (`deltafmi examples copy`)
    return ComponentSource(Path(path), cls.__name__ if others else None)


def find_component(text: str) -> ComponentSource:
    """A component named on the command line: a file (``x.py``, ``x.py:Class``), a module
    reference (``package.module:Class``) or a packaged model's class name."""
    file, class_name = split_file_reference(text)
    if file.endswith(".mo") and Path(file).is_file():
        from .compiler import cache_dir
        from .equations.modelica import python_source_for
        return ComponentSource(*python_source_for(Path(file), class_name, cache_dir() / "modelica"))
    if Path(file).is_file():
        return ComponentSource(Path(file), class_name)
    if is_module_reference(text) or not Path(file).suffix and len(Path(file).parts) == 1:
        return module_component(text)
    raise ComponentSourceError(f"{file}: no such file")
