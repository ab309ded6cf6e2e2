"""The public API, pinned: the names ``import deltafmi`` offers (resolved lazily through its _API
table), the names a component's source imports from ``deltafmi.component``, and an ``__all__`` in
every public module of the package (the names it offers other modules, tests and docs).

Adding or removing a public name is a decision: it changes this file."""
from __future__ import annotations

import importlib
import inspect
from pathlib import Path

import pytest

import deltafmi
import deltafmi.models

#: the top-level API, sorted as deltafmi.__all__ is
TOP_LEVEL = [
    "BadInput", "BuildError", "ComponentSourceError", "DeltaFmiError", "Interrupted", "LinearModel", "Master",
    "Result",
    "ResultWriteError", "Scenario", "ScenarioError", "SimulationError", "System", "build_cached", "build_fmu",
    "export_fmu", "export_ssp", "linearize_fmu", "linearize_scenario", "load_scenario", "load_ssp", "load_study", "open_store",
    "plan_study", "plot_result", "read_result", "resolve_system", "simulate", "sweep_study",
]

#: what a component's source imports: ``from deltafmi.component import ...``
COMPONENT = ["Clock", "Component", "Experiment", "Function", "HybridSystemComponent", "Input", "Kernel", "NativeKernels", "Output",
             "Parameter", "SampledComponent", "State"]


def test_the_top_level_names_are_exactly_these():
    assert deltafmi.__all__ == TOP_LEVEL
    assert sorted(deltafmi._API) == TOP_LEVEL  # nothing in the table that __all__ leaves out


@pytest.mark.parametrize("name", TOP_LEVEL)
def test_each_top_level_name_resolves_to_what_its_module_defines(name):
    module = importlib.import_module(deltafmi._API[name])
    assert getattr(deltafmi, name) is getattr(module, name)
    assert name in module.__all__, f"{module.__name__} does not offer {name} in its __all__"


def test_dir_shows_the_public_names_before_any_is_loaded():
    assert set(TOP_LEVEL) | {"__version__"} <= set(dir(deltafmi))
    assert dir(deltafmi) == sorted(dir(deltafmi))


def test_an_unknown_top_level_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="module 'deltafmi' has no attribute 'simulat'"):
        deltafmi.simulat  # noqa: B018


def test_the_component_api_is_exactly_these_and_the_runtime_defines_them():
    import deltafmi.component
    import deltafmi.runtime

    assert sorted(deltafmi.runtime.__all__) == COMPONENT
    for name in COMPONENT:
        assert getattr(deltafmi.component, name) is getattr(deltafmi.runtime, name), name
    assert set(COMPONENT) <= set(dir(deltafmi.component))


def _public_modules() -> list[str]:
    """Every module of the package whose name (and whose packages' names) do not start with "_",
    found from the files: the package's folder, and the models' (fmu_src/ in a clone, where
    deltafmi/models does not exist)."""
    found = set()
    for root, prefix in ((Path(deltafmi.__file__).parent, "deltafmi"),
                         (Path(deltafmi.models.__file__).parent, "deltafmi.models")):
        for path in root.rglob("*.py"):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            if any(part.startswith("_") for part in parts):
                continue
            found.add(".".join([prefix, *parts]))
    return sorted(found)


PUBLIC_MODULES = _public_modules()


def test_the_module_search_finds_every_layer():
    layers = {"deltafmi.apps", "deltafmi.builder", "deltafmi.master", "deltafmi.runtime", "deltafmi.physics",
              "deltafmi.component", "deltafmi.models", "deltafmi.errors", "deltafmi.files", "deltafmi.shipped",
              "deltafmi.toolchain"}
    assert layers <= set(PUBLIC_MODULES)
    assert "deltafmi.models.wrist_declarations" in PUBLIC_MODULES and len(PUBLIC_MODULES) > 200


@pytest.mark.parametrize("name", PUBLIC_MODULES)
def test_every_public_module_declares_what_it_offers(name):
    module = importlib.import_module(name)
    assert "__all__" in vars(module), f"{name} has no __all__"
    offered = module.__all__
    assert isinstance(offered, list) and all(isinstance(n, str) for n in offered), name
    assert len(set(offered)) == len(offered), f"{name}.__all__ repeats a name"
    missing = [n for n in offered if not hasattr(module, n)]
    assert not missing, f"{name}.__all__ names what it does not define: {missing}"
    private = [n for n in offered if n.startswith("_")]
    assert not private, f"{name}.__all__ offers private names: {private}"
    modules = [n for n in offered if inspect.ismodule(getattr(module, n))]
    assert not modules, f"{name}.__all__ offers modules, not names: {modules}"
