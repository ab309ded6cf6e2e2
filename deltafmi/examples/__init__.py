"""The example scenarios and studies shipped with deltafmi, found by name.

``deltafmi run delta_tracking`` and ``deltafmi.simulate("delta_tracking")`` run the scenario file
``delta_tracking.yaml`` of this folder, ``deltafmi sweep gain_payload`` the study
``studies/gain_payload.yaml``. ``deltafmi examples copy NAME DIR`` writes an example and the
packaged component sources it uses into ``DIR``, as files to edit (:func:`copy_example`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Union

from deltafmi.errors import BadInput, did_you_mean

EXAMPLES_DIR = Path(__file__).parent
STUDIES_DIR = EXAMPLES_DIR / "studies"
_PACKAGED_SOURCE = re.compile(r"^(?P<head>\s*source:\s*)deltafmi\.models:(?P<name>\w+)(?P<tail>.*)$", re.M)
#: a file a scenario reads from its own folder: a live joystick's recorded session
_DATA_FILE = re.compile(r"^\s*session:\s*['\"]?([\w.-]+)['\"]?\s*(?:#.*)?$", re.M)
_STUDY_SCENARIO = re.compile(r"^(?P<head>scenario:\s*)\.\./(?P<file>[\w.-]+\.yaml)(?P<tail>.*)$", re.M)


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
        text = " ".join(str(yaml.safe_load(self.path.read_text()).get("description", "")).split())
        first = re.split(r"(?<=\.)\s", text, maxsplit=1)[0].rstrip(".")
        return first if len(first) <= 100 else first[:97].rstrip() + "..."


def examples() -> List[Example]:
    """Every shipped example, scenarios first, each group by name."""
    return ([Example(p.stem, "scenario", p) for p in sorted(EXAMPLES_DIR.glob("*.yaml"))]
            + [Example(p.stem, "study", p) for p in sorted(STUDIES_DIR.glob("*.yaml"))])


def model_summaries() -> Dict[str, str]:
    """Class name -> the first line of its docstring, for every packaged model (read from the
    sources: nothing is imported)."""
    import ast
    from deltafmi.models import MODELS

    models = Path(__file__).parents[1] / "models"
    summaries = {}
    for name, module in sorted(MODELS.items()):
        tree = ast.parse((models / f"{module}.py").read_text())
        node = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == name)
        summaries[name] = (ast.get_docstring(node) or "").split("\n")[0].rstrip(".")
    return summaries


def example(name: str) -> Example:
    """The example called ``name``; :class:`BadInput` naming the closest ones otherwise."""
    found = {e.name: e for e in examples()}
    if name in found:
        return found[name]
    raise BadInput(f"no example called '{name}'{did_you_mean(name, found)}; `deltafmi examples` lists them")


def is_shipped(path: Union[str, Path]) -> bool:
    """Whether ``path`` lies in the installed deltafmi package (a shipped example or model): what is
    made from it (results, linear models) goes to the current folder, never into the package."""
    return Path(__file__).parents[1].resolve() in Path(path).resolve().parents


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
        raise BadInput(f"'{text}' is an example {chosen.kind}, not a {kind}"
                       + ("; run it with `deltafmi sweep`" if chosen.kind == "study" else "; sweep needs a study"))
    return chosen.path


def copy_example(name: str, directory: Union[str, Path]) -> List[Path]:
    """Write the example ``name`` into ``directory`` ready to edit: its YAML, for a study the
    scenario it varies, the source of every packaged component it uses (``models/*.py``, the
    YAML's ``source:`` pointed at them) and the data files it reads (a joystick's ``session:``).
    Returns the files written; refuses to overwrite any."""
    from deltafmi.models import MODELS

    chosen = example(name)
    directory = Path(directory)
    texts = {chosen.path.name: chosen.path.read_text()}
    if chosen.kind == "study":
        scenarios = _STUDY_SCENARIO.findall(texts[chosen.path.name])
        texts[chosen.path.name] = _STUDY_SCENARIO.sub(r"\g<head>\g<file>\g<tail>", texts[chosen.path.name])
        for _, file, _ in scenarios:
            texts[file] = (EXAMPLES_DIR / file).read_text()
    modules = sorted({MODELS[m["name"]] for text in texts.values() for m in _PACKAGED_SOURCE.finditer(text)})
    for file in list(texts):
        texts[file] = _PACKAGED_SOURCE.sub(lambda m: f"{m['head']}models/{MODELS[m['name']]}.py{m['tail']}",
                                           texts[file])
    models = Path(__file__).parents[1] / "models"
    files = {directory / file: text for file, text in texts.items()}
    files.update({directory / "models" / f"{module}.py": (models / f"{module}.py").read_text() for module in modules})
    # data a scenario reads next to itself (a live joystick's recorded session)
    files.update({directory / m[1]: (EXAMPLES_DIR / m[1]).read_text() for text in texts.values()
                  for m in _DATA_FILE.finditer(text) if (EXAMPLES_DIR / m[1]).is_file()})
    blobs = {directory / relative: source for relative, source in _resource_files(chosen.path, chosen.kind)}
    existing = [str(path) for path in [*files, *blobs] if path.exists()]
    if existing:
        raise BadInput(f"{', '.join(existing)}: already there; copy into an empty folder or remove them")
    for path, text in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    for path, source in blobs.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(source.read_bytes())
    return [*files, *blobs]


def _resource_files(path: Path, kind: str) -> List[tuple[str, Path]]:
    """(name relative to the scenario, file) of every file the components of the example
    ``path`` (a ``kind`` "scenario", or a "study" and the scenario it varies) name under
    ``resources:``; the copy puts each beside its copied scenario. Absolute names stay as they are."""
    import yaml

    scenarios = [path]
    if kind == "study":
        scenarios = [path.parent / yaml.safe_load(path.read_text())["scenario"]]
    found = []
    for scenario in scenarios:
        components = yaml.safe_load(scenario.read_text()).get("components") or {}
        for spec in components.values():
            for item in (spec or {}).get("resources") or ():
                if not Path(item).is_absolute() and ".." not in Path(item).parts:
                    found.append((item, scenario.parent / item))
    return found
