"""Where the master gets the FMU of a scenario component that names a ``source:`` rather than an ``fmu:``.

The master runs FMUs; it does not build them. Whoever sits above it (the ``deltafmi`` command,
the top-level API ``deltafmi.simulate``, ...) hands in a provider, a function that turns a
component's source into an FMU file: deltafmi's builder does (:func:`deltafmi.builder.provider.scenario_fmu`).
Without one, a component named by its source is an error and FMU files run as ever.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Optional, Sequence

__all__ = ["FmuProvider", "provided_fmu", "use_fmu_provider"]

#: ``provider(source, directory, fmi_version, resources) -> Path``: the FMU built from ``source``
#: (``file.py[:Class]``, ``package.module:Class``) of a scenario in ``directory``, for FMI
#: ``fmi_version``, carrying ``resources``; raises :class:`~deltafmi.errors.FmuSourceError`
FmuProvider = Callable[[str, Path, int, Sequence[Path]], Path]

_provider: Optional[FmuProvider] = None


def use_fmu_provider(provider: Optional[FmuProvider]) -> Optional[FmuProvider]:
    """Make ``provider`` the one every scenario resolves its sources with; returns the one before."""
    global _provider
    before, _provider = _provider, provider
    return before


def provided_fmu(source: str, directory: Path, fmi_version: int, resources: Sequence[Path] = ()) -> Path:
    """The FMU of ``source`` from the provider set up; :class:`FmuSourceError` when there is none."""
    if _provider is None:
        from deltafmi.errors import FmuSourceError  # here: importing this module (every command does) stays cheap

        raise FmuSourceError(f"source '{source}' names a component to build, and this master has no FMU "
                             "builder: run it with `deltafmi run` or deltafmi.simulate(), or give an `fmu:` file")
    return _provider(source, directory, fmi_version, resources)
