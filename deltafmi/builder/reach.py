"""Which of deltafmi's modules an FMU runs, found by reading import statements (no code runs).

An FMU carries only the deltafmi modules its model and the runtime can reach, so that a model
that imports no delta-robot code carries none of it. The set is found statically, from the
import statements of the model's source and of ``boot.py``, followed transitively through
deltafmi's own modules, and not by importing the model and recording ``sys.modules``: a runtime
trace sees only the branches that ran (an import inside a function called only after an event,
in an ``except`` clause, or for one parameter value), and an FMU built from it would fail later,
in a user's importer, the moment such a branch runs. Reading every import statement errs the
other way: a module imported by a branch that never runs is carried anyway, which costs bytes,
not failures.

What counts, anywhere in a module (module level, functions, classes, ``try``/``except``):

- ``import a.b.c``, ``from a.b import c`` (absolute or relative) and
  ``importlib.import_module("a.b.c")`` with a literal name; only deltafmi's modules are followed;
- importing a module runs every package ``__init__`` on its path;
- ``from P import name`` reaches the submodule ``P.name`` when there is one;
- not what is under ``if TYPE_CHECKING:`` (it never runs).

Not seen: imports of computed names (``import_module(variable)``, ``__import__``); deltafmi's
runtime and mechanics use none. Packages an FMU carries stay eager rather than lazy (PEP 562
``__getattr__``): an import that runs when a model first touches an attribute runs after
``boot.py`` has taken the FMU's deltafmi out of ``sys.modules`` again, and would fail, or bind to
a host's own deltafmi. The one exception is :mod:`deltafmi.runtime` itself, whose names
``boot.py`` loads while the FMU's copy is active (its ``__getattr__`` imports them literally, and
so are followed here).
"""
from __future__ import annotations

import ast
from pathlib import Path
from typing import Iterable, Iterator, Optional

import deltafmi
from deltafmi.shipped import MODELS_DIR

__all__ = ["BOOT_SOURCE", "absolute_imports", "absolute_imports_of", "direct_imports", "module_archive_name",
           "module_source", "reached_modules"]

PACKAGE = "deltafmi"
PACKAGE_DIR = Path(deltafmi.__file__).parent
#: the code the native bridge runs first; it imports the runtime (deltafmi.runtime.instance)
BOOT_SOURCE = PACKAGE_DIR / "runtime" / "boot.py"


def module_file(name: str) -> Optional[Path]:
    """The source file of deltafmi module ``name``: its ``.py`` or package ``__init__.py``."""
    parts = name.split(".")
    if parts[0] != PACKAGE:
        return None
    if parts[1:2] == ["models"]:  # fmu_src/ in a clone (setup.py maps it into the package)
        base = MODELS_DIR.joinpath(*parts[2:])
    else:
        base = PACKAGE_DIR.joinpath(*parts[1:])
    for candidate in (base / "__init__.py", base.with_suffix(".py") if len(parts) > 1 else None):
        if candidate is not None and candidate.is_file():
            return candidate
    return None


def module_archive_name(name: str) -> str:
    """Where deltafmi module ``name`` sits in an installed package (``deltafmi/models/x.py`` for a
    model of ``fmu_src/``): its path in an FMU's ``resources/python``."""
    path = module_source(name)
    return "/".join(name.split(".")) + ("/__init__.py" if path.name == "__init__.py" else ".py")


def module_source(name: str) -> Path:
    """:func:`module_file` of a module known to exist (one :func:`reached_modules` returned)."""
    path = module_file(name)
    if path is None:
        raise ValueError(f"{name} is not a module of the deltafmi package ({PACKAGE_DIR})")
    return path


def reached_modules(sources: Iterable[Path] = (), modules: Iterable[str] = (), runtime: bool = True) -> list[str]:
    """Names of the deltafmi modules reached from ``sources`` (files outside the package, such as a
    component source), from the deltafmi ``modules`` themselves and, with ``runtime``, from
    ``boot.py`` (the FMU runtime), sorted."""
    pending = list(modules)
    for source in ([BOOT_SOURCE] if runtime else []) + list(sources):
        pending.extend(_imports(Path(source), None))
    reached: set[str] = set()
    while pending:
        name = pending.pop()
        if name in reached or module_file(name) is None:
            continue  # seen, outside deltafmi, or an extension module (component._values ships separately)
        reached.add(name)
        pending.extend(".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 1))
        pending.extend(_module_imports(name))
    return sorted(reached)


def absolute_imports(path: Path) -> list[str]:
    """Every absolute module name the import statements of the file at ``path`` name, inside or
    outside deltafmi (``from a import b`` gives ``a`` and ``a.b``: ``b`` may be a submodule)."""
    return list(_imports(Path(path), None))


def absolute_imports_of(path: Path, package: Optional[str]) -> list[str]:
    """:func:`absolute_imports` of the file at ``path`` as module of ``package`` (relative imports
    resolved against it): the file need not be in deltafmi's own folder (a copy in an FMU)."""
    return list(_imports(Path(path), package))


def direct_imports(name: str) -> set[str]:
    """The deltafmi modules that module ``name``'s own import statements name (not transitively)."""
    return {target for target in _module_imports(name) if module_file(target) is not None}


def _module_imports(name: str) -> list[str]:
    path = module_source(name)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    return list(_imports(path, package))


def _imports(path: Path, package: Optional[str]) -> list[str]:
    """The modules every import in the file at ``path`` names; ``package`` resolves relative imports."""
    stat = path.stat()
    key = (str(path), stat.st_mtime_ns, stat.st_size, package)
    if key not in _PARSED:
        _PARSED[key] = list(_parse_imports(path.read_bytes(), str(path), package))
    return _PARSED[key]


#: parsed files (path, mtime, size, package) -> the modules they import; a build reads each many times
_PARSED: dict[tuple[str, int, int, Optional[str]], list[str]] = {}


def _parse_imports(source: bytes, filename: str, package: Optional[str]) -> Iterator[str]:
    try:
        tree = ast.parse(source, filename=filename)
    except (SyntaxError, ValueError) as exc:  # a user's source that is not Python (null bytes: ValueError)
        from .source_error import ComponentSourceError, import_failure
        raise ComponentSourceError(f"{filename}: importing it failed: {import_failure(exc)}") from None
    for node in _statements(tree.body):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(node.module, node.level, package)
            if base is not None:
                yield base
                yield from (f"{base}.{alias.name}" for alias in node.names if alias.name != "*")
    if b"import_module" in source:  # the only import hidden in an expression; rare, so walk then
        for call in ast.walk(tree):
            if isinstance(call, ast.Call) and _is_import_module(call.func) and call.args:
                first = call.args[0]
                if isinstance(first, ast.Constant) and isinstance(first.value, str) and not first.value.startswith("."):
                    yield first.value


def _statements(nodes: list) -> Iterator[ast.AST]:
    """Every statement in ``nodes`` and in the blocks nested in them (not in expressions), except
    the body of an ``if TYPE_CHECKING:``, which never runs."""
    for node in nodes:
        yield node
        for field in ("body", "orelse", "finalbody", "handlers", "cases"):
            if field == "body" and isinstance(node, ast.If) and _is_type_checking(node.test):
                continue
            yield from _statements(getattr(node, field, None) or [])


def _absolute(module: Optional[str], level: int, package: Optional[str]) -> Optional[str]:
    if level == 0:
        return module
    if package is None:
        return None  # a relative import outside any package fails when the model is loaded
    parts = package.split(".")
    if level - 1 >= len(parts):
        return None
    base = ".".join(parts[:len(parts) - (level - 1)])
    return f"{base}.{module}" if module else base


def _is_type_checking(test: ast.expr) -> bool:
    return ((isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
            or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"))


def _is_import_module(func: ast.expr) -> bool:
    return ((isinstance(func, ast.Attribute) and func.attr == "import_module")
            or (isinstance(func, ast.Name) and func.id == "import_module"))
