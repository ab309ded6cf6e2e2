"""Two deltafmi installations sharing one build cache each get FMUs built from their own files.

Two copies of the package (two checkouts, or two environments with different deltafmi versions) on
one ``$DELTAFMI_CACHE``: the build records that find a cached FMU from file stamps
(:mod:`deltafmi.builder.build_stamps`) belong to the installation that wrote them, so that the
second copy never takes the FMU the first built from its runtime; copies with the same contents
still share one FMU (found from its content key).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import deltafmi
from deltafmi.toolchain import cache_dir

from conftest import FMU_SRC

PACKAGE = Path(deltafmi.__file__).resolve().parent
#: bytes tree B's FMU binary is compiled with (a string kept in the binary's read-only data)
MARKER = "deltafmi-tree-b-runtime"
#: what tree B's copy of the package calls its version
VERSION_B = f"{deltafmi.__version__}+tree.b"

#: runs in a copy of the package: the FMU of a scenario's component (the path of ``deltafmi run``),
#: then of ``build_cached``, with the package it was built by
_BUILD = """
import json, sys
from pathlib import Path
import deltafmi
from deltafmi.builder import provider
from deltafmi.builder.packager import build_cached
source = Path(sys.argv[1])
run = provider.scenario_fmu(str(source), source.parent, 2)
print(json.dumps({"package": deltafmi.__file__, "run": str(run), "built": str(build_cached(source))}))
"""

def _copy_package(target: Path) -> Path:
    shutil.copytree(PACKAGE, target / "deltafmi", ignore=shutil.ignore_patterns("__pycache__", "_prebuilt"))
    return target


def _build_in(tree: Path, source: Path, cache: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "DELTAFMI_CACHE": str(cache),
           # the native pieces tree A shares with this checkout are copied, not compiled again
           "DELTAFMI_CACHE_SEED": str(cache_dir())}
    done = subprocess.run([sys.executable, "-c", _BUILD, str(source)], cwd=tree, env=env, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert Path(found["package"]).resolve().is_relative_to(tree.resolve())  # that copy, not this checkout
    assert found["run"] == found["built"]
    return {"fmu": Path(found["built"])}


def _made_by(fmu: Path) -> dict:
    """What an FMU says about the deltafmi that built it."""
    with zipfile.ZipFile(fmu) as archive:
        binary = archive.read("binaries/linux64/Oscillator.so")
        info = json.loads(archive.read("resources/deltafmi.json"))
        core = archive.read("sources/core.c").decode()
    return {"tool": fmpy.read_model_description(str(fmu)).generationTool, "version": info["deltafmi_version"],
            "binary_marked": MARKER.encode() in binary, "source_marked": MARKER in core}


def test_a_changed_installation_does_not_take_the_other_installations_fmu(tmp_path):
    source = tmp_path / "component" / "oscillator.py"
    source.parent.mkdir()
    shutil.copy(FMU_SRC / "oscillator.py", source)
    cache = tmp_path / "shared-cache"
    tree_a, tree_b, tree_c = (_copy_package(tmp_path / name) for name in ("a", "b", "c"))
    # tree B: another version, and a runtime C source compiled into different bytes
    init = tree_b / "deltafmi" / "__init__.py"
    init.write_text(init.read_text().replace(f'__version__ = "{deltafmi.__version__}"', f'__version__ = "{VERSION_B}"'))
    core = tree_b / "deltafmi" / "runtime" / "native" / "core.c"
    core.write_text(core.read_text() + f'\n__attribute__((used)) static const char tree_marker[] = "{MARKER}";\n')

    first_a = _build_in(tree_a, source, cache)["fmu"]
    first_b = _build_in(tree_b, source, cache)["fmu"]
    assert first_b != first_a
    assert _made_by(first_a) == {"tool": f"deltafmi {deltafmi.__version__}", "version": deltafmi.__version__,
                                 "binary_marked": False, "source_marked": False}
    assert _made_by(first_b) == {"tool": f"deltafmi {VERSION_B}", "version": VERSION_B,
                                 "binary_marked": True, "source_marked": True}
    # each installation's records stay its own: A finds its FMU again after B's build
    assert _build_in(tree_a, source, cache)["fmu"] == first_a
    assert _build_in(tree_b, source, cache)["fmu"] == first_b
    # an installation with A's contents shares A's FMU (its content key), without a build of its own
    assert _build_in(tree_c, source, cache)["fmu"] == first_a
    assert len(list((cache / "fmus").iterdir())) == 2
