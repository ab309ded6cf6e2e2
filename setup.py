"""Wheel build: the package plus its prebuilt native pieces (see deltafmi/builder/prebuild.py).

Everything else is declared in pyproject.toml. This file only (1) compiles the packaged models'
native pieces into the wheel's ``deltafmi/_prebuilt`` after the sources are copied and copies the
guides (docs/*.md and their figures) into ``deltafmi/docs``, and (2) marks
the wheel as a platform wheel (``cpXY-cpXY-<platform>``), since those pieces are machine code (the
compiled value access and the portable FMUs' starter are built against this CPython's headers). An editable install (``pip install -e .``) skips (1):
a source checkout compiles on demand into the per-user cache. ``DELTAFMI_NO_PREBUILD=1`` skips
it too (a pure-source wheel that compiles on the user's machine; it still gets a platform tag).
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Distribution, find_packages, setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent


class BuildPyWithPrebuilt(build_py):
    """``build_py``, then ``python -m deltafmi.builder.prebuild <build_lib>/deltafmi/_prebuilt``."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return
        # the guides and their figures (`deltafmi guides` says where): the README links to them
        docs = Path(self.build_lib) / "deltafmi" / "docs"
        docs.mkdir(parents=True, exist_ok=True)
        for path in (HERE / "docs").iterdir():
            if path.suffix in (".md", ".png", ".gif"):
                shutil.copy2(path, docs / path.name)
        if os.environ.get("DELTAFMI_NO_PREBUILD"):
            return
        target = Path(self.build_lib).resolve() / "deltafmi" / "_prebuilt"
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]))
        env.pop("DELTAFMI_CACHE", None)
        subprocess.run([sys.executable, "-m", "deltafmi.builder.prebuild", str(target)], cwd=HERE, env=env,
                       check=True)


class PlatformDistribution(Distribution):
    """A distribution with machine code: bdist_wheel then tags the wheel for this CPython and platform."""

    def has_ext_modules(self) -> bool:
        return True


#: the design's top level: the models (fmu_src/) and the example scenarios (scenarios/) sit beside
#: the package in a clone, and inside it once installed (``deltafmi.models``, ``deltafmi.scenarios``)
MAPPED = {"deltafmi.models": "fmu_src", "deltafmi.scenarios": "scenarios"}

setup(cmdclass={"build_py": BuildPyWithPrebuilt}, distclass=PlatformDistribution,
      packages=find_packages(include=["deltafmi", "deltafmi.*"]) + list(MAPPED), package_dir=MAPPED)
