"""Where things go in the FMI compatibility-information tree (the FMI Cross-Check layout).

Exported FMUs::

    fmus/<FMI version>/<cs|me>/<platform>/<tool>/<tool version>/<Model>/
        <Model>.fmu  <Model>_ref.csv  <Model>_ref.opt  [<Model>_in.csv]  ReadMe.md

Results of importing them::

    results/<FMI version>/<cs|me>/<platform>/<importing tool>/<its version>/
            <exporting tool>/<its version>/<Model>/
        passed | failed | rejected  [<Model>_out.csv]  ReadMe.md

FMI versions are written ``2.0`` and ``3.0``; platforms are the FMI 2.0 names (``linux64``) for
FMI 2.0 and the FMI 3.0 platform tuples (``x86_64-linux``) for FMI 3.0, as each version names its
``binaries/`` folders. A model folder holding ``notCompliantWithLatestRules`` is left out.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import List

__all__ = ["ModelFolder", "PLATFORMS", "STATUSES", "TOOL", "find_models", "tree_root"]

#: this tool's name in the tree
TOOL = "deltafmi"
#: the platform folder of this machine per FMI version
PLATFORMS = {"2.0": "linux64", "3.0": "x86_64-linux"}
INTERFACES = ("cs", "me")
#: the status files of an import result
STATUSES = ("passed", "failed", "rejected")
NOT_COMPLIANT = "notCompliantWithLatestRules"


@dataclass(frozen=True)
class ModelFolder:
    """One exported model's folder: ``root/fmus/<version>/<interface>/<platform>/<tool>/<tool_version>/<model>``."""

    root: Path
    fmi_version: str
    interface: str
    platform: str
    tool: str
    tool_version: str
    model: str

    @property
    def folder(self) -> Path:
        """The model's folder."""
        return (self.root / "fmus" / self.fmi_version / self.interface / self.platform / self.tool
                / self.tool_version / self.model)

    def file(self, suffix: str) -> Path:
        """``<model><suffix>`` in the folder: ``.fmu``, ``_ref.csv``, ``_ref.opt``, ``_in.csv``."""
        return self.folder / f"{self.model}{suffix}"

    def result_folder(self, importer: str, importer_version: str) -> Path:
        """Where ``importer`` (at ``importer_version``) writes its result of importing this FMU."""
        return (self.root / "results" / self.fmi_version / self.interface / self.platform / importer
                / importer_version / self.tool / self.tool_version / self.model)

    def __str__(self) -> str:
        return "/".join((self.fmi_version, self.interface, self.platform, self.tool, self.tool_version, self.model))


def tree_root(path: Path) -> Path:
    """The root of a tree given as its root or as its ``fmus`` folder."""
    path = Path(path)
    return path.parent if path.name == "fmus" and not (path / "fmus").is_dir() else path


def find_models(root: Path) -> List[ModelFolder]:
    """Every model folder under ``root/fmus`` that holds ``<model>.fmu``, sorted by path; those
    marked ``notCompliantWithLatestRules`` are left out."""
    fmus = root / "fmus"
    found = []
    for fmu in sorted(fmus.glob("*/*/*/*/*/*/*.fmu")):
        folder = fmu.parent
        if fmu.stem != folder.name or (folder / NOT_COMPLIANT).exists():
            continue
        version, interface, platform, tool, tool_version, model = folder.relative_to(fmus).parts
        found.append(ModelFolder(root, version, interface, platform, tool, tool_version, model))
    return found
