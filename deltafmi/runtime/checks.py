"""Build-time checks of a component class: mistakes that would only show later, inside an FMU.

The FMU runtime never imports this module; the packager and the modelDescription writer use it.
"""
from __future__ import annotations

import inspect
import os
from typing import Optional

from .base import Component
from .variables import Input, Output

__all__ = ["definition_problem", "feedthrough_of"]


def definition_problem(cls: type[Component]) -> Optional[str]:
    """The first mistake in the definition of ``cls`` as a one-line message, or None."""
    try:
        feedthrough_of(cls)
    except ValueError as exc:
        return str(exc)
    return init_misuse(cls)


def init_misuse(cls: type[Component]) -> Optional[str]:
    """A one-line error when ``cls`` or one of its bases below :class:`Component` (a mixin too)
    defines ``__init__``, else None.

    An FMU creates its component without calling ``__init__`` (fmi2Reset makes a fresh one the
    same way), so anything set there would be missing later; ``setup()`` is the hook for it.
    """
    runtime = set(Component.__mro__)
    for klass in cls.__mro__:
        if klass in runtime or "__init__" not in vars(klass):
            continue
        where = _definition_site(vars(klass)["__init__"]) or _class_site(klass)
        owner = klass.__qualname__ if klass is cls else f"{klass.__qualname__} (a base of {cls.__qualname__})"
        return (f"{where}: {owner} defines __init__, which an FMU never calls: set attributes in "
                f"setup() instead (it runs at instantiation and at every reset; compute values from "
                f"parameters in initialize())")
    return None


def feedthrough_of(cls: type[Component]) -> Optional[dict[str, list[str]]]:
    """``cls.direct_feedthrough`` with outputs and inputs by attribute name (an FMI name such as
    ``lambda`` for ``lam = Output(name="lambda")`` is accepted too); None when not declared.

    Raises ValueError, naming the file and line, for a name that is not an output or an input of
    ``cls``: a misspelt name would silently declare an output independent of its inputs.
    """
    declared = getattr(cls, "direct_feedthrough", None)
    if declared is None:
        return None
    outputs = _names(cls, Output)
    inputs = _names(cls, Input)
    where = _attribute_site(cls, "direct_feedthrough")
    if not isinstance(declared, dict):
        raise ValueError(f"{where}: direct_feedthrough must be a dict from output names to lists of input names")
    resolved: dict[str, list[str]] = {}
    for output, sources in declared.items():
        if output not in outputs:
            raise ValueError(f"{where}: direct_feedthrough names '{output}', which is not an output of "
                             f"{cls.__qualname__} (outputs: {', '.join(sorted(set(outputs.values()))) or 'none'})")
        if isinstance(sources, str) or not all(isinstance(s, str) for s in sources):
            raise ValueError(f"{where}: direct_feedthrough['{output}'] must be a list of input names, "
                             f"got {sources!r}")
        unknown = [s for s in sources if s not in inputs]
        if unknown:
            raise ValueError(f"{where}: direct_feedthrough['{output}'] names '{unknown[0]}', which is not an "
                             f"input of {cls.__qualname__} (inputs: "
                             f"{', '.join(sorted(set(inputs.values()))) or 'none'})")
        resolved[outputs[output]] = [inputs[s] for s in sources]
    return resolved


def _names(cls: type[Component], kind: type) -> dict[str, str]:
    """Attribute name and FMI name -> attribute name, for the declarations of one kind."""
    names: dict[str, str] = {}
    for decl in cls._layout.declarations:
        if isinstance(decl, kind):
            names[decl.name] = names[decl.fmi_name or decl.name] = decl.name
    return names


def _definition_site(function: object) -> Optional[str]:
    """``file:line`` of a function's ``def`` (its first decorator, if any), or None (a C function)."""
    code = getattr(inspect.unwrap(function), "__code__", None) if callable(function) else None
    if code is None or code.co_filename.startswith("<"):  # C, or generated (@dataclass)
        return None
    return f"{_shown(code.co_filename)}:{code.co_firstlineno}"


def _class_site(cls: type) -> str:
    """``file:line`` of a class statement, or the class name."""
    try:
        return f"{_shown(inspect.getsourcefile(cls))}:{inspect.getsourcelines(cls)[1]}"
    except (OSError, TypeError):
        return cls.__qualname__


def _attribute_site(cls: type, attribute: str) -> str:
    """``file:line`` where the class that sets ``attribute`` assigns it, or the class name."""
    owner = next((k for k in cls.__mro__ if attribute in vars(k)), cls)
    try:
        lines, first = inspect.getsourcelines(owner)
        path = inspect.getsourcefile(owner)
    except (OSError, TypeError):
        return owner.__qualname__
    line = next((first + i for i, text in enumerate(lines) if text.lstrip().startswith(attribute)), first)
    return f"{_shown(path)}:{line}"


def _shown(path: Optional[str]) -> str:
    """``path`` relative to the working directory when it lies inside it (as the user typed it)."""
    if not path:
        return "?"
    relative = os.path.relpath(path)
    return path if relative.startswith(os.pardir) else relative
