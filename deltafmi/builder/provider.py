"""The builder as the master's FMU provider: a scenario component's ``source:`` built into an FMU.

:func:`scenario_fmu` is what :func:`deltafmi.master.scenario.fmu_source.use_fmu_provider` is handed
by the applications (``deltafmi run``, ``deltafmi.simulate``): the source found (a packaged
model ``deltafmi.models:X``, a module ``package.module:Class``, or a file next to the scenario or
in a folder above it), then built once and cached.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence

from deltafmi.errors import FmuSourceError, file_hint

from .build_stamps import file_request, lookup, module_request, stamps_of
from .sources import ComponentSourceError, is_module_reference, split_file_reference

__all__ = ["scenario_fmu"]


def scenario_fmu(source: str, directory: Path, fmi_version: int, resources: Sequence[Path] = ()) -> Path:
    """The FMU built from the component ``source`` of a scenario in ``directory`` (cached: keyed by
    the source, the modules it reaches, ``resources`` and ``fmi_version``).

    A cached FMU whose files are unchanged is found from their stamps, importing neither the
    component's module nor the builder (:mod:`.build_stamps`)."""
    alias = None
    try:
        if is_module_reference(source):
            request = module_request(source, fmi_version, resources)
            found = lookup(request) if request else None
            if found is not None:
                return found
            if request:  # the module's own file is stamped before it is imported
                import importlib.util
                alias = (request, stamps_of([Path(importlib.util.find_spec(source.partition(":")[0]).origin)]))
            from .sources import module_component

            component = module_component(source)
            path, class_name = component.path, component.class_name
        else:
            file, class_name = split_file_reference(source)
            found = _find_upwards(directory, file)
            if found is None:
                raise FmuSourceError(f"source '{file}' not found next to the scenario or in a folder above it"
                                     f"{file_hint(directory / file, '*.py')}")
            path = found
            if resources or not _packaged(path):  # else the packaged model's own resources: the packager's
                cached = lookup(file_request(path, class_name, fmi_version, resources))
                if cached is not None:
                    return cached
    except ComponentSourceError as exc:
        raise FmuSourceError(f"source {exc}") from None
    try:
        from .packager import cached_build  # the builder itself only when the stamps do not answer

        return cached_build(path, class_name=class_name, fmi_version=fmi_version, resources=resources, also=alias)
    except Exception as exc:  # noqa: BLE001 - a build failure is reported as the component's error
        raise FmuSourceError(f"building '{source}' failed: {exc}") from None


def _packaged(path: Path) -> bool:
    """Whether ``path`` is a model of :mod:`deltafmi.models` (its FMU carries shipped resources)."""
    from deltafmi import models

    return path.resolve().parent == Path(models.__file__).resolve().parent


def _find_upwards(base: Path, relative: str) -> Optional[Path]:
    """``relative`` under ``base`` or the nearest of its parents that has it."""
    if Path(relative).is_absolute():
        return Path(relative) if Path(relative).is_file() else None
    for folder in [base.resolve(), *base.resolve().parents]:
        if (folder / relative).is_file():
            return folder / relative
    cwd = Path.cwd() / relative
    return cwd if cwd.is_file() else None

