"""What an FMU needs to run, read from its ``resources/python.cfg``, and whether this machine has it.

``deltafmi info`` and ``deltafmi validate`` report it: a portable FMU needs only a glibc no older
than its floor; any other FMU needs the Python recorded when it was built (or the one named by
``DELTAFMI_PYTHON`` / ``DELTAFMI_LIBPYTHON``) with numpy, when its host does not run Python itself.
An FMU not built by deltafmi needs nothing of that. Every FMU needs its binary for this platform
(:func:`binary_problem`); a deltafmi FMU's modelDescription.xml and binary must agree on the GUID
(:func:`guid_problem`).
"""
from __future__ import annotations

import json
import os
import platform
import subprocess
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Optional


@dataclass
class RuntimeRequirement:
    """The interpreter an FMU runs its model in, and what this machine lacks of it (``python_version``
    empty and not portable: an FMU that was not built by deltafmi, which needs no Python)."""
    portable: bool
    python_version: str
    glibc_floor: str = ""
    library: str = ""
    executable: str = ""
    source: str = ""
    missing: list[str] = field(default_factory=list)

    @property
    def foreign(self) -> bool:
        """Not built by deltafmi (no ``resources/python.cfg``)."""
        return not self.portable and not self.python_version

    @property
    def runs_here(self) -> bool:
        return not self.missing

    def describe(self) -> list[str]:
        """Lines for the CLI."""
        if self.foreign:
            return ["not built by deltafmi: runs its own binary, no Python needed"]
        if self.portable:
            lines = [f"portable: carries CPython {self.python_version} and its packages; needs Linux x86_64 "
                     f"with glibc {self.glibc_floor} or newer, no Python"]
        else:
            lines = [f"not portable: in a host that runs no Python it starts CPython {self.python_version} "
                     f"({self.library}) with the packages of {self.executable}, or what DELTAFMI_LIBPYTHON and "
                     f"DELTAFMI_PYTHON name; a Python host lends its own interpreter, which needs numpy. "
                     f"`deltafmi build {self.source or 'SOURCE'} --portable` makes one that carries its own Python"]
        if self.missing:
            lines += [f"this machine: cannot start it: {problem}" for problem in self.missing]
        else:
            lines.append("this machine: has what it needs")
        return lines


def read_config(fmu: Path) -> dict[str, str]:
    """The key=value lines of the FMU's ``resources/python.cfg`` (empty if it has none)."""
    with zipfile.ZipFile(fmu) as archive:
        try:
            text = archive.read("resources/python.cfg").decode()
        except KeyError:
            return {}
    return dict(line.split("=", 1) for line in text.splitlines() if "=" in line)


def _source(fmu: Path) -> str:
    """The component source file the FMU was built from, as recorded in it."""
    with zipfile.ZipFile(fmu) as archive:
        try:
            return json.loads(archive.read("resources/deltafmi.json")).get("source", "")
        except (KeyError, ValueError):
            return ""


def _version_tuple(text: str) -> tuple[int, ...]:
    return tuple(int(part) for part in text.split(".") if part.isdigit())


def runtime_requirement(fmu: Path) -> RuntimeRequirement:
    """What ``fmu`` needs to start, checked against this machine."""
    cfg = read_config(fmu)
    version = cfg.get("version", "")
    if not cfg:
        return RuntimeRequirement(False, "")
    if cfg.get("portable") == "1":
        requirement = RuntimeRequirement(True, version, glibc_floor=cfg.get("glibc", ""))
        libc, have = platform.libc_ver()
        if platform.system() != "Linux" or platform.machine() != "x86_64":
            requirement.missing.append(f"it runs on Linux x86_64, this is {platform.system()} {platform.machine()}")
        elif libc == "glibc" and _version_tuple(have) < _version_tuple(requirement.glibc_floor):
            requirement.missing.append(f"glibc {have} is older than {requirement.glibc_floor}")
        return requirement
    library = os.environ.get("DELTAFMI_LIBPYTHON") or cfg.get("library", "")
    executable = os.environ.get("DELTAFMI_PYTHON") or cfg.get("executable", "")
    requirement = RuntimeRequirement(False, version, library=library, executable=executable, source=_source(fmu))
    if not library or not Path(library).is_file():
        requirement.missing.append(f"no Python library {library or '(none recorded)'}")
    if not executable or not Path(executable).is_file():
        requirement.missing.append(f"no Python interpreter {executable or '(none recorded)'}")
    else:
        probe = subprocess.run([executable, "-c", "import sys, numpy; print('%d.%d' % sys.version_info[:2])"],
                               capture_output=True, text=True)
        if probe.returncode != 0:
            requirement.missing.append(f"{executable} cannot import numpy")
        elif version and probe.stdout.strip() != version:
            requirement.missing.append(f"{executable} is CPython {probe.stdout.strip()}, the FMU needs {version}")
    return requirement


def binary_problem(fmu: Path, model_identifiers: Iterable[str]) -> Optional[str]:
    """Why ``fmu`` has no binary to load on this platform (``binaries/linux64/<modelIdentifier>.so``
    for each of ``model_identifiers``), or None when it has them all."""
    from fmpy import platform, sharedLibraryExtension

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
    binary checks at fmi2Instantiate (``resources/deltafmi.json``) disagree, or None."""
    with zipfile.ZipFile(fmu) as archive:
        try:
            built = json.loads(archive.read("resources/deltafmi.json")).get("guid", "")
        except (KeyError, ValueError):
            return None
    if built and built != guid:
        return (f"the GUID of modelDescription.xml, {guid}, is not the one its binary was built with, {built}: "
                "fmi2Instantiate will refuse it (rebuild the FMU, or restore its modelDescription.xml)")
    return None


def instantiation_problem(fmu: Path) -> Optional[str]:
    """Load the FMU's binary and instantiate it once (Co-Simulation if it offers it, else Model
    Exchange), then free it: what went wrong, with what the FMU logged, or None.

    This is what catches a GUID its binary refuses in an FMU of any origin (fmpy's validation
    reads only the XML)."""
    import tempfile

    import fmpy
    from fmpy.fmi2 import FMU2Model, FMU2Slave

    from deltafmi.cosim.stepping.unit_base import instantiation_reason, logger_callbacks

    md = fmpy.read_model_description(str(fmu), validate=False)
    interface = md.coSimulation or md.modelExchange
    if interface is None:
        return "it offers neither Co-Simulation nor Model Exchange"
    messages: list = []
    callbacks = logger_callbacks(lambda status, category, text: messages.append((status, category, text)))
    with tempfile.TemporaryDirectory(prefix="deltafmi-validate-") as folder:
        unzipped = fmpy.extract(str(fmu), unzipdir=folder)
        try:
            instance = (FMU2Slave if md.coSimulation else FMU2Model)(
                guid=md.guid, unzipDirectory=unzipped, modelIdentifier=interface.modelIdentifier,
                instanceName="validate")
        except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions
            return f"its binary does not load: {exc}"
        try:
            instance.instantiate(callbacks=callbacks)
        except Exception:  # noqa: BLE001 - fmpy raises a plain Exception when fmi2Instantiate returns NULL
            return f"fmi2Instantiate failed: {instantiation_reason(messages)}"
        instance.freeInstance()
    return None
