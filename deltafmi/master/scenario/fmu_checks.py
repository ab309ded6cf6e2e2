"""Whether an FMU archive can run here, read from the archive alone (nothing is loaded).

:func:`binary_problem`: every FMU needs its binary for this platform; :func:`guid_problem`: a
deltafmi FMU's modelDescription.xml and binary must agree on the GUID; :func:`clock_problem`: the
master activates an FMI 3.0 FMU's periodic input Clocks only; :func:`validation_problems`: fmpy's
validation of the model description, kept under the FMU's stamp. ``deltafmi validate`` and
the scenario resolution ask them; the trial instantiation is
:func:`deltafmi.master.stepping.fmu_trial.instantiation_problem`.
"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any, Iterable, List, Optional

__all__ = ["binary_problem", "clock_problem", "clocks_refused", "fmu_stamp", "guid_problem", "validation_problems"]

#: the intervalVariability of the input Clocks the master activates itself (periodic, time-based)
PERIODIC_CLOCKS = ("constant", "fixed", "tunable")
#: a modelDescription.xml packs 4 to 20 times (at most about 50 with deep indentation); one that
#: would unpack to more than this many bytes at more than this ratio is a zip bomb, not read
BOMB_SIZE, BOMB_RATIO = 32 << 20, 200


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


def clock_problem(fmu: Path, interface: str) -> Optional[str]:
    """Why the master cannot drive the Clocks of the FMI 3.0 FMU ``fmu`` run as ``interface``
    ("ME", "CS"), or None (see :func:`clocks_refused`)."""
    import xml.etree.ElementTree as ElementTree  # here: FMI 2.0 runs never need it

    with zipfile.ZipFile(fmu) as archive:
        try:
            root = ElementTree.fromstring(archive.read("modelDescription.xml"))
        except (KeyError, ElementTree.ParseError):
            return None  # reading the FMU tells that
    return clocks_refused(root, interface)


def clocks_refused(root: Any, interface: str) -> Optional[str]:
    """Why the master cannot drive the Clocks of the modelDescription ``root`` (an ElementTree
    element) as ``interface``, or None: it activates periodic input Clocks (constant, fixed,
    tunable), not aperiodic ones; it reads output Clocks (local ones need nothing); and in
    Co-Simulation it needs Event Mode, which FMI 3.0 requires of an FMU with Clocks."""
    used = []
    for clock in root.iterfind("ModelVariables/Clock"):
        name, causality = clock.get("name", ""), clock.get("causality", "local")
        kind = clock.get("intervalVariability") or "?"
        if causality == "input" and kind not in PERIODIC_CLOCKS:
            return (f"its input Clock '{name}' is {kind} (intervalVariability), which the master cannot activate: "
                    f"it drives periodic input Clocks only ({', '.join(PERIODIC_CLOCKS)})")
        if causality in ("input", "output"):
            used.append(name)
    cs = root.find("CoSimulation")
    if used and interface == "CS" and cs is not None and cs.get("hasEventMode") not in ("true", "1"):
        return (f"it has Clocks ({', '.join(used)}) but its <CoSimulation> has no Event Mode (hasEventMode), "
                "which FMI 3.0 requires to use them: run it as Model Exchange (interface: ME)")
    return None


def archive_problem(fmu: Path) -> Optional[str]:
    """Why ``fmu`` is not an FMU deltafmi can read, in words for its user, or None: not a zip
    archive, a damaged one, an entry that would land outside the folder it is unpacked into (an
    absolute path or ``..``), no modelDescription.xml, one that would unpack to far more than
    it could hold (a zip bomb), an FMI 1.0 FMU, or a variable whose
    valueReference is not an unsigned integer (fmpy's own message for these names no variable)."""
    import xml.etree.ElementTree as ElementTree  # here: an FMU read before is not checked again (modelinfo)

    if not zipfile.is_zipfile(fmu):
        return "not a zip archive (an FMU is a zip file holding a modelDescription.xml)"
    try:
        with zipfile.ZipFile(fmu) as archive:
            names = archive.namelist()
            unsafe = next((n for n in names if n.startswith(("/", "\\")) or ":" in n.split("/")[0]
                           or ".." in n.replace("\\", "/").split("/")), None)
            if unsafe is not None:
                return (f"unsafe: its archive entry '{unsafe}' would be unpacked outside the FMU's "
                        "folder (an FMU's entries are relative paths without '..')")
            if "modelDescription.xml" not in names:
                return "its archive has no modelDescription.xml"
            packed = archive.getinfo("modelDescription.xml")
            if packed.file_size > BOMB_SIZE and packed.file_size > BOMB_RATIO * packed.compress_size:
                return (f"its modelDescription.xml would unpack to {packed.file_size >> 20} MB from "
                        f"{packed.compress_size >> 10} KB, {packed.file_size // max(1, packed.compress_size)} times "
                        "its packed size, as a zip bomb does (a model description packs 4 to 20 times)")
            text = archive.read("modelDescription.xml")
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        return f"a damaged zip archive ({exc})"
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as exc:
        return f"modelDescription.xml is not well-formed XML: {exc}"
    version = root.get("fmiVersion") or ""
    if version.startswith("1."):
        return f"an FMI {version} FMU: deltafmi runs FMI 2.0 and FMI 3.0 FMUs (export it as FMI 2.0 or 3.0)"
    if not version.startswith(("2.", "3.")):
        return f"modelDescription.xml: fmiVersion '{version}' is not 2.0 or 3.0"
    variables = root.find("ModelVariables")
    for variable in variables if variables is not None else ():
        reference = variable.get("valueReference")
        if reference is not None and not reference.strip().isdigit():
            return (f"modelDescription.xml: variable '{variable.get('name')}' has valueReference "
                    f"'{reference}', not an unsigned integer")
    return None


def fmu_stamp(fmu: Path) -> Optional[str]:
    """A name for the file ``fmu`` as it is now (its resolved path, size, modification time and
    inode, with fmpy's and Python's versions), under which what was read from it is kept in the
    cache; None for a file that cannot be read. A build replaces an FMU whole (a new inode), so
    that a rebuilt or edited FMU has another stamp."""
    import hashlib
    import sys

    import fmpy

    try:
        status = fmu.stat()
        where = fmu.resolve()
    except OSError:
        return None
    key = (f"{where}\0{status.st_size}\0{status.st_mtime_ns}\0{status.st_ino}\0{fmpy.__version__}"
           f"\0{sys.version_info[:2]}")
    return hashlib.sha256(key.encode("utf-8", "surrogateescape")).hexdigest()[:32]


def validation_problems(fmu: Path) -> List[str]:
    """The problems fmpy's ``validate_fmu`` finds in ``fmu`` (none: an empty list), kept in the
    cache under the FMU's stamp (:func:`fmu_stamp`): parsing every variable name by the structured
    naming convention takes fmpy up to a second per FMU, and the FMUs of the build cache are
    validated by every scenario that uses them. Raises what ``validate_fmu`` raises for an archive
    it cannot read (nothing is kept then)."""
    import os

    from fmpy.validation import validate_fmu

    from deltafmi.toolchain import cache_dir

    stamp = fmu_stamp(fmu)
    kept = None if stamp is None else cache_dir() / "fmu-validations" / stamp
    if kept is not None:
        try:
            problems = json.loads(kept.read_text(encoding="utf-8"))
            if isinstance(problems, list) and all(isinstance(p, str) for p in problems):
                return problems
        except (OSError, ValueError):  # none kept yet (or a torn file): validate
            pass
    problems = [str(problem) for problem in validate_fmu(str(fmu))]
    if kept is not None:
        temporary = kept.with_name(f"{kept.name}.{os.getpid()}.tmp")
        try:
            kept.parent.mkdir(parents=True, exist_ok=True)
            temporary.write_text(json.dumps(problems), encoding="utf-8")
            os.replace(temporary, kept)
        except OSError:  # a read-only cache: validate each time
            temporary.unlink(missing_ok=True)
    return problems
