"""What an FMU needs to run, read from its ``resources/python.cfg``, and whether this machine has it.

``deltafmi info`` and ``deltafmi validate`` report it: a portable FMU needs only a glibc no older
than its floor; any other FMU needs the Python recorded when it was built (or the one named by
``DELTAFMI_PYTHON`` / ``DELTAFMI_LIBPYTHON``) with numpy, when its host does not run Python itself.
An FMU not built by deltafmi needs nothing of that. (Whether an FMU archive can run here, its binary
and GUID, is the master's question: :mod:`deltafmi.master.scenario.fmu_checks`.)
"""
from __future__ import annotations

import json
import re
import os
import platform
import subprocess
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["read_config", "runtime_requirement"]


#: the first line of the component source ``deltafmi export-fmu`` writes
_EXPORTED = re.compile(r'"""(?P<scenario>\S+) exported as one Co-Simulation FMU by deltafmi export-fmu')


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
    #: the start of the model source the FMU carries
    source_text: str = ""
    fmi_version: int = 2

    @property
    def foreign(self) -> bool:
        """Not built by deltafmi (no ``resources/python.cfg``)."""
        return not self.portable and not self.python_version

    @property
    def runs_here(self) -> bool:
        return not self.missing

    def _build_command(self) -> str:
        """The command (after ``deltafmi``) that built the FMU: ``build SOURCE``, or ``export-fmu
        SCENARIO`` for a scenario exported as one FMU (its source's docstring names the scenario)."""
        exported = _EXPORTED.match(self.source_text)
        if exported:
            return f"export-fmu {exported['scenario']}"
        return f"build {self.source or 'SOURCE'}"

    def describe(self) -> list[str]:
        """Lines for the CLI."""
        if self.foreign:
            return ["not built by deltafmi: runs its own binary, no Python needed"]
        version_option = " --fmi-version 3" if self.fmi_version == 3 else ""
        if self.portable:
            lines = [f"portable: carries CPython {self.python_version} and its packages; needs Linux x86_64 "
                     f"with glibc {self.glibc_floor} or newer, no Python"]
        else:
            lines = [f"not portable: in a host that runs no Python it starts CPython {self.python_version} "
                     f"({self.library}) with the packages of {self.executable}, or what DELTAFMI_LIBPYTHON and "
                     f"DELTAFMI_PYTHON name; a Python host lends its own interpreter, which needs numpy. "
                     f"`deltafmi {self._build_command()}{version_option} --portable` makes one that "
                     f"carries its own Python"]
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


def _source(fmu: Path) -> tuple[str, int, str]:
    """What ``deltafmi build`` takes to build the FMU again: a packaged model's class name when the
    FMU carries that model's source unchanged, else the name of the source file it was built from;
    the FMI version it was built for; the first 200 characters of that source ("" if none)."""
    with zipfile.ZipFile(fmu) as archive:
        try:
            recorded = json.loads(archive.read("resources/deltafmi.json"))
            source = recorded.get("source", "")
            text = archive.read(f"resources/model/{source}") if source else b""
        except (KeyError, ValueError):
            return "", 2, ""
    fmi_version = 3 if recorded.get("fmi_version") == 3 else 2
    start = text[:200].decode(errors="replace")
    from deltafmi import models

    class_name = recorded.get("class_name", "")
    if models.MODELS.get(class_name, "") + ".py" == source:
        packaged = Path(models.__file__).parent / source
        if packaged.is_file() and packaged.read_bytes() == text:
            return class_name, fmi_version, start
    return source, fmi_version, start


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
    source, fmi_version, source_text = _source(fmu)
    requirement = RuntimeRequirement(False, version, library=library, executable=executable, source=source,
                                     source_text=source_text,
                                     fmi_version=fmi_version)
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
