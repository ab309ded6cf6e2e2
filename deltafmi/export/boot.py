"""Boot code shipped as ``resources/deltafmi_boot.py`` in every FMU; the native bridge runs it.

It imports the FMU's model under a module name unique to the FMU's resources directory, with the
FMU's own copy of the deltafmi runtime (``resources/python/deltafmi``). That copy is swapped into
``sys.modules`` only while the model is imported (or FMU states are unpickled) and swapped out
again, so FMUs built by different deltafmi versions, a host that imports deltafmi itself, and two
FMUs whose sources share a file name all coexist in one process. Nothing stays on ``sys.path``.
This file must run on its own: it imports nothing from deltafmi at module level.
"""
import contextlib
import hashlib
import importlib
import importlib.util
import json
import os
import sys
import types

# A host may unload the FMU binary and load it again (fmpy's freeInstance does). The models
# imported so far and this file's load() (see the end) live in one process-wide registry module,
# where the reloaded binary finds them instead of running this file and importing all anew.
_REGISTRY = sys.modules.setdefault("_deltafmi_fmu_registry", types.ModuleType("_deltafmi_fmu_registry"))
_LOADED: dict = _REGISTRY.__dict__.setdefault("loaded", {})


class _Bundle:
    """The FMU's private copy of the deltafmi package, active in sys.modules only on demand."""

    def __init__(self, python_dir: str) -> None:
        self.python_dir = python_dir
        self.modules: dict = {}

    @contextlib.contextmanager
    def active(self):
        """Make ``import deltafmi...`` resolve to this FMU's copy inside the block."""
        saved = {k: sys.modules.pop(k) for k in [k for k in sys.modules if _is_deltafmi(k)]}
        sys.modules.update(self.modules)
        sys.path.insert(0, self.python_dir)
        try:
            yield
        finally:
            sys.path.remove(self.python_dir)
            for k in [k for k in sys.modules if _is_deltafmi(k)]:
                self.modules[k] = sys.modules.pop(k)
            sys.modules.update(saved)


def _is_deltafmi(name: str) -> bool:
    return name == "deltafmi" or name.startswith("deltafmi.")


def _import_model(resources_dir: str) -> tuple:
    with open(os.path.join(resources_dir, "deltafmi.json"), encoding="utf-8") as f:
        info = json.load(f)
    bundle = _Bundle(os.path.join(resources_dir, "python"))
    digest = hashlib.sha1(resources_dir.encode()).hexdigest()[:12]
    unique = f"_deltafmi_fmu_{info['model_identifier']}_{digest}"
    with bundle.active():
        runtime = importlib.import_module("deltafmi.component.instance")
        spec = importlib.util.spec_from_file_location(unique, os.path.join(resources_dir, "model", info["source"]))
        module = importlib.util.module_from_spec(spec)
        sys.modules[unique] = module  # pickled FMU states name classes by this module
        spec.loader.exec_module(module)
    return info, getattr(module, info["class_name"]), runtime.FmuInstance, bundle.active


class FmuStartError(RuntimeError):
    """The FMU cannot run in this interpreter; the bridge logs the message alone, no traceback."""


def _missing_module(error: ImportError, resources_dir: str) -> FmuStartError:
    with open(os.path.join(resources_dir, "deltafmi.json"), encoding="utf-8") as f:
        source = json.load(f)["source"]
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    return FmuStartError(
        f"this FMU's model needs the Python module '{error.name}', which the Python it runs in "
        f"({sys.executable or 'embedded'}, CPython {version}) does not have ({error}). Install it there "
        f"(pip install {(error.name or '').split('.')[0]}), or point DELTAFMI_PYTHON and DELTAFMI_LIBPYTHON at a "
        f"Python that has it, or rebuild the FMU with `deltafmi build {source} --portable`, which makes an FMU "
        "that carries its own Python and packages.")


def load(resources_dir: str, instance_name: str, guid: str, fmu_type: int):
    """Create the Python side of one FMU instance (called by the bridge from fmi2Instantiate)."""
    resources_dir = os.path.realpath(resources_dir)
    if resources_dir not in _LOADED:
        try:
            _LOADED[resources_dir] = _import_model(resources_dir)
        except ImportError as exc:
            raise _missing_module(exc, resources_dir) from None
    info, component_class, instance_class, context = _LOADED[resources_dir]
    if guid and guid != info["guid"]:
        raise RuntimeError(f"fmi2Instantiate: GUID {guid} does not match this FMU's {info['guid']} "
                           f"({resources_dir}); the modelDescription.xml and the binary disagree")
    return instance_class(component_class, instance_name, fmu_type, resources_dir, context)


_REGISTRY.__dict__.setdefault("boots", {})[__file__] = load
