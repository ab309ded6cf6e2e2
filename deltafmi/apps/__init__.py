"""The applications on top of the library: the ``deltafmi`` command line and every command, studies
on Dask, plots and animations, compatibility trees. Nothing in deltafmi imports this package.

It is also where the layers meet: the master runs FMUs and never imports the builder, so this
package hands the master the builder as its FMU provider (a scenario component's ``source:``
built into an FMU) when it is first imported. The top-level API (``deltafmi.simulate``, ...)
imports it before it answers a name.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from deltafmi.master.scenario.fmu_source import use_fmu_provider

__all__: list[str] = []


def _built_fmu(source: str, directory: Path, fmi_version: int, resources: Sequence[Path] = ()) -> Path:
    from deltafmi.builder.provider import scenario_fmu  # the builder loads only when a source is built

    return scenario_fmu(source, directory, fmi_version, resources)


use_fmu_provider(_built_fmu)
