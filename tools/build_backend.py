"""The build backend: setuptools', asking for what only a wheel's build needs when a wheel is built.

A wheel's build compiles the packaged models' native pieces (``setup.py`` runs
``deltafmi.builder.prebuild``, which imports the models: numpy, and sympy for the equation
models); an editable install (``pip install -e .``) skips that step, and a source distribution
compiles nothing, so neither needs numpy or sympy in its isolated build environment (installing
them there took most of an editable install's own time).
"""
from setuptools import build_meta as _setuptools
from setuptools.build_meta import *  # noqa: F401,F403  (every hook as setuptools has it)
from setuptools.build_meta import __all__  # noqa: F401

#: what ``setup.py``'s prebuild step imports, beyond setuptools
WHEEL_REQUIRES = ["numpy>=1.24", "sympy>=1.12"]


def get_requires_for_build_wheel(config_settings=None):
    """setuptools' requirements for a wheel, and the prebuild step's."""
    return _setuptools.get_requires_for_build_wheel(config_settings) + WHEEL_REQUIRES
