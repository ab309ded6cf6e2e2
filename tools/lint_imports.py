"""Check the import contracts (pyproject.toml's [tool.importlinter]) on the package as installed,
and that no module imports itself through others (no import cycle, imports inside functions counted).

The models live in fmu_src/ and are the package deltafmi.models only once installed (setup.py
maps the folder); import-linter reads a package from its folder, so this lays the package out
as a wheel does (links into a temporary folder) and runs ``lint-imports`` on that, then looks for
cycles among all modules in the same import graph (grimp's, which import-linter reads: every
import statement, at module level or in a function, except under ``if TYPE_CHECKING:``). Exit
code 0 when every contract holds and there is no cycle, 1 otherwise.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: package folder -> where it is in a clone (setup.py's MAPPED)
MAPPED = {"deltafmi/models": "fmu_src"}


def _link_tree(source: Path, target: Path) -> None:
    for folder, dirs, files in os.walk(source):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        relative = Path(folder).relative_to(source)
        (target / relative).mkdir(parents=True, exist_ok=True)
        for name in files:
            if name.endswith(".py"):
                os.symlink(Path(folder) / name, target / relative / name)


def main() -> int:
    with tempfile.TemporaryDirectory(prefix="deltafmi-layers-") as work:
        staged = Path(work)
        _link_tree(ROOT / "deltafmi", staged / "deltafmi")
        for package, folder in MAPPED.items():
            _link_tree(ROOT / folder, staged / package)
        env = dict(os.environ, PYTHONPATH=str(staged))
        command = [sys.executable, "-c", "from importlinter.cli import lint_imports_command; lint_imports_command()",
                   str(ROOT / "pyproject.toml"), "--no-cache"]
        contracts = subprocess.run(command, cwd=staged, env=env).returncode
        cycles = subprocess.run([sys.executable, __file__, "--cycles"], cwd=staged, env=env).returncode
        return 1 if contracts or cycles else 0


def report_cycles() -> int:
    """Print every import cycle among deltafmi's modules (strongly connected components); 1 if any."""
    import grimp

    from deltafmi.master.scenario.graph import strongly_connected  # the master's own (Tarjan), reused

    graph = grimp.build_graph("deltafmi", exclude_type_checking_imports=True, cache_dir=None)
    imports = {module: sorted(graph.find_modules_directly_imported_by(module)) for module in graph.modules}
    cycles = [sorted(c) for c in strongly_connected(imports) if len(c) > 1]
    for cycle in cycles:
        print("import cycle: " + " <-> ".join(cycle))
    print(f"{len(cycles)} import cycle(s) among {len(imports)} modules")
    return 1 if cycles else 0


if __name__ == "__main__":
    sys.exit(report_cycles() if sys.argv[1:] == ["--cycles"] else main())
