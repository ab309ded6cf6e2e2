"""Which of an FMU's bundled deltafmi modules another FMU in the same process may share.

Every FMU of ours carries its own copy of the deltafmi modules it runs (``resources/python``), and
``boot.py`` imports them apart from every other FMU's. Several FMUs built by the same deltafmi
carry byte-identical copies, and importing each copy again costs a good part of a run's start-up.
An FMU therefore records, for each module it carries (packages aside), a *closure key*: a hash of
the module's own file and of every bundled module it can reach through its import statements
(transitively, the packages on their paths included), plus the FMU's compiled pieces. Two FMUs
whose keys for a module agree run exactly the same code for it and for everything it imports, so
the boot code lends the first FMU's module object to the second instead of importing it again.
A module whose own file, or any file it reaches, differs (another deltafmi version, an edited
physics module) gets another key, and is imported apart as before.

Packages (``__init__.py``) are never shared: importing a submodule binds it as an attribute of
its package, and a shared package would hand one FMU's submodule to another FMU whose copy of
that submodule differs. Only the runtime, the component API, the physics and the models are
shared: the master's modules a scenario exported as one FMU carries find their compiled loops
beside themselves (``__file__``), in the unpacked folder of the FMU that imported them first.
"""
from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Dict, Iterable, Set, Tuple

from .reach import absolute_imports_of

__all__ = ["PYTHON_PREFIX", "SHAREABLE", "carried_digests", "module_keys"]

#: where an FMU carries its deltafmi modules
PYTHON_PREFIX = "resources/python/"
#: the packages whose modules may be shared (those that look for no file beside themselves)
SHAREABLE = ("deltafmi.runtime.", "deltafmi.component.", "deltafmi.physics.", "deltafmi.models.")


def module_keys(files: Iterable[Tuple[Path, str]]) -> Dict[str, str]:
    """``{module name: closure key}`` of the plain (non-package) deltafmi modules among ``files``,
    the (file, archive name) pairs an FMU carries under ``resources/python/``."""
    sources: Dict[str, Tuple[Path, bool]] = {}  # module name -> (file, is a package)
    others = []  # compiled extension modules and their C: in every key (they are few)
    for path, arcname in files:
        if not arcname.startswith(PYTHON_PREFIX + "deltafmi/"):
            continue
        relative = arcname[len(PYTHON_PREFIX):]
        if relative.endswith(".py"):
            parts = relative[:-3].split("/")
            package = parts[-1] == "__init__"
            sources[".".join(parts[:-1] if package else parts)] = (Path(path), package)
        else:
            others.append(f"{relative}\0{_digest(Path(path))}")
    digests = {name: _digest(path) for name, (path, _) in sources.items()}
    reaches: Dict[str, Set[str]] = {}
    for name, (path, package) in sources.items():
        parents = {".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 1)}
        imported = set(absolute_imports_of(path, name if package else name.rpartition(".")[0]))
        reaches[name] = {target for target in imported | parents if target in sources and target != name}
    extra = "\0".join(sorted(others))
    keys = {}
    for name, (_, package) in sorted(sources.items()):
        if package or not name.startswith(SHAREABLE):
            continue
        closure, pending = {name}, [name]
        while pending:
            for target in reaches[pending.pop()]:
                if target not in closure:
                    closure.add(target)
                    pending.append(target)
        members = "\0".join(f"{member}={digests[member]}" for member in sorted(closure))
        text = f"{name}\0\0{members}\0\0{extra}"  # one closure may hold several modules: the name too
        keys[name] = hashlib.sha256(text.encode()).hexdigest()
    return keys


def carried_digests(files: Iterable[Tuple[Path, str]]) -> Dict[str, str]:
    """``{path under resources/python: sha256}`` of the deltafmi files among ``files`` (every file
    the keys of :func:`module_keys` cover). The keys are recorded at build time: boot.py checks
    these digests first, and an FMU whose files were edited since shares nothing, neither lending
    its modules under keys that no longer describe them nor borrowing in place of its own."""
    return {arcname[len(PYTHON_PREFIX):]: _digest(Path(path)) for path, arcname in files
            if arcname.startswith(PYTHON_PREFIX + "deltafmi/")}


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()
