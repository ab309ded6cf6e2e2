"""Copying a shipped example into a folder to edit (``deltafmi examples copy``), and the
packaged models' summaries (``deltafmi examples``)."""
from __future__ import annotations

import re
from pathlib import Path
from typing import Dict, List, Union

from deltafmi.shipped import MODELS_DIR, SCENARIOS_DIR, example

__all__ = ["copy_example", "model_summaries"]

_PACKAGED_SOURCE = re.compile(r"^(?P<head>\s*source:\s*)deltafmi\.models:(?P<name>\w+)(?P<tail>.*)$", re.M)
#: a file a scenario reads from its own folder: a live joystick's recorded session
_DATA_FILE = re.compile(r"^\s*session:\s*['\"]?([\w.-]+)['\"]?\s*(?:#.*)?$", re.M)
_STUDY_SCENARIO = re.compile(r"^(?P<head>scenario:\s*)\.\./(?P<file>[\w.-]+\.yaml)(?P<tail>.*)$", re.M)


def model_summaries() -> Dict[str, str]:
    """Class name -> the first line of its docstring, for every packaged model (read from the
    sources: nothing is imported)."""
    import ast
    from deltafmi.models import MODELS

    models = MODELS_DIR
    summaries = {}
    for name, module in sorted(MODELS.items()):
        tree = ast.parse((models / f"{module}.py").read_text())
        node = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == name)
        summaries[name] = (ast.get_docstring(node) or "").split("\n")[0].rstrip(".")
    return summaries


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
            texts[file] = (SCENARIOS_DIR / file).read_text()
    modules = sorted({MODELS[m["name"]] for text in texts.values() for m in _PACKAGED_SOURCE.finditer(text)})
    for file in list(texts):
        texts[file] = _PACKAGED_SOURCE.sub(lambda m: f"{m['head']}models/{MODELS[m['name']]}.py{m['tail']}",
                                           texts[file])
    models = MODELS_DIR
    files = {directory / file: text for file, text in texts.items()}
    files.update({directory / "models" / f"{module}.py": (models / f"{module}.py").read_text() for module in modules})
    # data a scenario reads next to itself (a live joystick's recorded session)
    files.update({directory / m[1]: (SCENARIOS_DIR / m[1]).read_text() for text in texts.values()
                  for m in _DATA_FILE.finditer(text) if (SCENARIOS_DIR / m[1]).is_file()})
    blobs = {directory / relative: source for relative, source in _resource_files(chosen.path, chosen.kind)}
    existing = [str(path) for path in [*files, *blobs] if path.exists()]
    if existing:
        from deltafmi.errors import BadInput  # here: listing the examples does not import numpy

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
