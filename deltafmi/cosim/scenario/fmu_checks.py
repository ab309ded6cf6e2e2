"""Whether an FMU archive can run here, read from the archive alone (nothing is loaded).

:func:`binary_problem`: every FMU needs its binary for this platform; :func:`guid_problem`: a
deltafmi FMU's modelDescription.xml and binary must agree on the GUID. ``deltafmi validate`` and
the scenario resolution ask them; the trial instantiation is
:func:`deltafmi.cosim.stepping.fmu_trial.instantiation_problem`.
"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Iterable, Optional


def binary_problem(fmu: Path, model_identifiers: Iterable[str], fmi3: bool = False) -> Optional[str]:
    """Why ``fmu`` has no binary to load on this platform (``binaries/linux64/<modelIdentifier>.so``
    for each of ``model_identifiers``; FMI 3.0, ``fmi3``: ``binaries/x86_64-linux/...``), or None
    when it has them all."""
    from fmpy import platform as platform2, platform_tuple, sharedLibraryExtension
    platform = platform_tuple if fmi3 else platform2

    with zipfile.ZipFile(fmu) as archive:
        names = archive.namelist()
    binaries = [name for name in names if name.startswith("binaries/") and not name.endswith("/")]
    for identifier in dict.fromkeys(model_identifiers):
        expected = f"binaries/{platform}/{identifier}{sharedLibraryExtension}"
        if expected not in names:
            has = ", ".join(binaries[:6]) + (", ..." if len(binaries) > 6 else "") if binaries else "none"
            return f"no binary for this platform: {expected} is missing (its binaries: {has})"
    return None


def guid_problem(fmu: Path, guid: str) -> Optional[str]:
    """For a deltafmi FMU: how the GUID of its modelDescription.xml (``guid``) and the one its
    binary checks when instantiated (``resources/deltafmi.json``) disagree, or None."""
    with zipfile.ZipFile(fmu) as archive:
        try:
            built = json.loads(archive.read("resources/deltafmi.json")).get("guid", "")
        except (KeyError, ValueError):
            return None
    if built and built != guid:
        return (f"the GUID of modelDescription.xml, {guid}, is not the one its binary was built with, {built}: "
                "its instantiation will refuse it (rebuild the FMU, or restore its modelDescription.xml)")
    return None
