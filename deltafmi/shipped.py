"""Where deltafmi's shipped models, scenarios and studies are, and finding a scenario by name.

``deltafmi run delta_tracking`` and ``deltafmi.simulate("delta_tracking")`` run the scenario file
``delta_tracking.yaml`` of the shipped scenarios, ``deltafmi sweep gain_payload`` the study
``studies/gain_payload.yaml``. A clone keeps them in ``scenarios/`` beside the package, an
installed wheel in ``deltafmi/scenarios/`` (setup.py maps the folder into the package); the models
likewise (``fmu_src/``, imported as :mod:`deltafmi.models`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import List, Union


__all__ = ["Example", "MODELS_DIR", "SCENARIOS_DIR", "STUDIES_DIR", "example", "examples", "find_input",
           "is_shipped"]

_PACKAGE = Path(__file__).resolve().parent


def _beside_or_inside(installed: str, clone: str) -> Path:
    inside = _PACKAGE / installed
    return inside if inside.is_dir() else _PACKAGE.parent / clone


#: the shipped example scenarios (and their data files)
SCENARIOS_DIR = _beside_or_inside("scenarios", "scenarios")
#: the shipped example studies
STUDIES_DIR = SCENARIOS_DIR / "studies"
#: the packaged models, :mod:`deltafmi.models`
MODELS_DIR = _beside_or_inside("models", "fmu_src")


@dataclass(frozen=True)
class Example:
    """A shipped scenario (``kind == "scenario"``) or study (``"study"``)."""

    name: str
    kind: str
    path: Path

    @property
    def summary(self) -> str:
        """The first sentence of the file's ``description``, at most 100 characters."""
        import yaml
        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml when there: `deltafmi examples` reads them all
        text = " ".join(str(yaml.load(self.path.read_text(), Loader=loader).get("description", "")).split())
        first = re.split(r"(?<=\.)\s", text, maxsplit=1)[0].rstrip(".")
        return first if len(first) <= 100 else first[:97].rstrip() + "..."


def examples() -> List[Example]:
    """Every shipped example, scenarios first, each group by name."""
    return ([Example(p.stem, "scenario", p) for p in sorted(SCENARIOS_DIR.glob("*.yaml"))]
            + [Example(p.stem, "study", p) for p in sorted(STUDIES_DIR.glob("*.yaml"))])


def example(name: str) -> Example:
    """The example called ``name``; :class:`BadInput` naming the closest ones otherwise."""
    found = {e.name: e for e in examples()}
    if name in found:
        return found[name]
    from deltafmi.errors import BadInput, did_you_mean  # here: deltafmi.errors imports numpy (the runtime)

    raise BadInput(f"no example called '{name}'{did_you_mean(name, found)}; `deltafmi examples` lists them")


def is_shipped(path: Union[str, Path]) -> bool:
    """Whether ``path`` is a shipped scenario, study or model (or lies in the package): what is
    made from it (results, linear models) goes to the current folder, never beside it."""
    parents = Path(path).resolve().parents
    return any(folder in parents for folder in (_PACKAGE, SCENARIOS_DIR.resolve(), MODELS_DIR.resolve()))


def find_input(text: Union[str, Path], kind: str) -> Path:
    """``text`` as a file when it is one; a bare name (no suffix, no folder) is ``NAME.yaml`` in
    the current folder when there is one (a copy made by ``deltafmi examples copy``), else the
    shipped example of that name and ``kind`` ("scenario" or "study"). :class:`BadInput` when
    it is neither."""
    path = Path(text)
    if path.is_file() or path.suffix or len(path.parts) > 1:
        return path  # a file name: its reader reports a missing file
    if path.with_suffix(".yaml").is_file():
        return path.with_suffix(".yaml")
    chosen = example(str(text))
    if chosen.kind != kind:
        from deltafmi.errors import BadInput

        raise BadInput(f"'{text}' is an example {chosen.kind}, not a {kind}"
                       + ("; run it with `deltafmi sweep`" if chosen.kind == "study" else "; sweep needs a study"))
    return chosen.path
