"""Boot code shipped as ``resources/deltafmi_boot.py`` in every FMU; the native bridge runs it.

It imports the FMU's model under a module name unique to the FMU's resources directory, with the
FMU's own copy of the deltafmi runtime (``resources/python/deltafmi``). That copy (the modules it
carries) is swapped into ``sys.modules`` only while the model is imported (or FMU states are
unpickled) and swapped out
again, so FMUs built by different deltafmi versions, a host that imports deltafmi itself, and two
FMUs whose sources share a file name all coexist in one process. Nothing stays on ``sys.path``.
This file must run on its own: it imports nothing from deltafmi at module level.
"""
import _thread
import contextlib
import hashlib
import importlib
import importlib.machinery
import importlib.util
import json
import os
import sys
import types

__all__: list[str] = []

# A host may unload the FMU binary and load it again (fmpy's freeInstance does). The models
# imported so far and this file's load() (see the end) live in one process-wide registry module,
# where the reloaded binary finds them instead of running this file and importing all anew.
_REGISTRY = sys.modules.setdefault("_deltafmi_fmu_registry", types.ModuleType("_deltafmi_fmu_registry"))
_LOADED: dict = _REGISTRY.__dict__.setdefault("loaded", {})
# Host threads may instantiate FMUs at the same time. Swapping deltafmi packages in sys.modules and
# importing a model must not interleave, across all FMUs of every deltafmi version (the registry
# holds the one lock; a dict's setdefault is atomic). Re-entrant: a model import swaps its bundle.
_LOCK = _REGISTRY.__dict__.setdefault("lock", _thread.RLock())


class _Bundle:
    """The FMU's private copy of the deltafmi package, active in sys.modules only on demand.

    Only the modules the FMU carries are swapped: the host's other deltafmi modules stay in
    sys.modules meanwhile, so that the host's other threads keep finding them (a Dask worker
    unpickles tasks that name deltafmi.apps.studies while an FMU starts in its executor thread; had they
    been hidden, its import would have run again, half in the FMU's copy).

    ``shared`` ({module name: key}, recorded at build time by deltafmi.builder.shared_modules)
    names the modules another FMU in the process may lend: one whose key an earlier FMU's module
    has is taken from it (:class:`_ModulePool`) instead of being imported again."""

    def __init__(self, python_dir: str, shared: "dict | None" = None) -> None:
        self.python_dir = python_dir
        self.modules: dict = {}
        self.names = _carried_modules(python_dir)
        self.shared = {name: key for name, key in (shared or {}).items() if name in self.names}

    @contextlib.contextmanager
    def active(self):
        """Make ``import deltafmi...`` resolve to this FMU's copy inside the block (one thread at a time)."""
        with _LOCK:
            pool = _module_pool() if self.shared else None
            # list() copies the keys without running Python code, so no other thread's import can
            # change sys.modules under the iteration (holding the lock does not stop other imports)
            saved = {k: sys.modules.pop(k) for k in self.names.intersection(list(sys.modules))}
            sys.modules.update(self.modules)
            sys.path.insert(0, self.python_dir)
            lending = pool.lend(self.shared) if pool is not None else None
            try:
                yield
            finally:
                if pool is not None:
                    pool.stop_lending(lending)
                sys.path.remove(self.python_dir)
                for k in self.names.intersection(list(sys.modules)):
                    self.modules[k] = sys.modules.pop(k)
                sys.modules.update(saved)
                if pool is not None:
                    pool.keep({key: self.modules[name] for name, key in self.shared.items() if name in self.modules})


class _ModulePool:
    """First on ``sys.meta_path``: deltafmi modules lent from one FMU to another (one per process).

    ``modules`` maps a closure key to the module object first imported with it. While a bundle is
    active on a thread (:meth:`lend`), an import of a module that bundle may share, made on that
    thread, gets the pooled module with the same key instead of executing the FMU's own copy:
    the import system binds it in ``sys.modules`` and as an attribute of the bundle's own package,
    as for a module it loaded. Imports on other threads, and of names the bundle does not share,
    are left to the other finders."""

    def __init__(self) -> None:
        self.modules: dict = {}  # closure key -> module
        self.lending: dict = {}  # thread -> {module name: key} of the bundle active on it

    def lend(self, shared: dict):
        """Serve ``shared`` on this thread until :meth:`stop_lending` (nests); returns what to restore."""
        thread = _thread.get_ident()
        previous = self.lending.get(thread)
        self.lending[thread] = shared
        return thread, previous

    def stop_lending(self, lending) -> None:
        thread, previous = lending
        if previous is None:
            self.lending.pop(thread, None)
        else:
            self.lending[thread] = previous

    def keep(self, modules: dict) -> None:
        """Pool ``modules`` ({key: module}) where no module has their key yet."""
        for key, module in modules.items():
            self.modules.setdefault(key, module)

    def find_spec(self, name, path=None, target=None):
        shared = self.lending.get(_thread.get_ident())
        module = self.modules.get(shared.get(name)) if shared else None
        if module is None:
            return None
        return importlib.machinery.ModuleSpec(name, _Lent(module), origin=getattr(module.__spec__, "origin", None))

    def invalidate_caches(self) -> None:
        pass


class _Lent:
    """Loader of a pooled module: hands out the module as it is, runs nothing."""

    def __init__(self, module) -> None:
        self.module = module
        self.spec = module.__spec__

    def create_module(self, spec):
        return self.module

    def exec_module(self, module) -> None:
        module.__spec__ = self.spec  # the import system set the lending spec: the module keeps its own


def _module_pool() -> _ModulePool:
    """The process-wide pool (one for every FMU and every copy of this file), first on sys.meta_path."""
    pool = _REGISTRY.__dict__.get("module_pool")
    if pool is None:
        pool = _REGISTRY.__dict__.setdefault("module_pool", _ModulePool())
        sys.meta_path.insert(0, pool)
    return pool


def _carried_modules(python_dir: str) -> frozenset:
    """Dotted names of the deltafmi packages and modules (sources and extensions) under ``python_dir``."""
    names = set()
    for folder, dirs, files in os.walk(os.path.join(python_dir, "deltafmi")):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        package = os.path.relpath(folder, python_dir).replace(os.sep, ".")
        names.add(package)
        for file in files:
            stem, _, suffix = file.partition(".")
            if suffix == "py" or file.endswith(".so"):
                names.add(package if stem == "__init__" else f"{package}.{stem}")
    return frozenset(names)


class _BundledSitePackages:
    """Last finder on ``sys.meta_path``: portable FMUs' own third-party packages, for their code only.

    A portable FMU carries the packages its model imports (``resources/python/site-packages``) as
    bytecode and extension modules of the CPython it bundles. In a host running that same CPython
    version, a top-level package the host cannot import itself (scipy in an environment with
    nothing but fmpy) comes from there; in any other version those files cannot load, and the FMU
    is not registered here. Scope, so that the host's own imports behave as without the FMU:
    - the host's packages always win (this finder is last, and is asked only when all others fail);
    - only top-level names (a package's submodules follow its ``__path__``);
    - only for imports made by code under the FMU's resources directory (its model, its deltafmi
      runtime, a package served from its site-packages), each FMU from its own site-packages.
    The one leak is that of a shared ``sys.modules``: once an FMU imported scipy from its bundle,
    the host's ``import scipy`` finds that module too.
    """

    _IMPORT_MACHINERY = ("importlib", "importlib._bootstrap", "importlib._bootstrap_external")

    def __init__(self) -> None:
        self.sites: dict = {}  # resources directory + os.sep -> its site-packages

    def find_spec(self, name, path=None, target=None):
        if path is not None or not self.sites:
            return None
        frame = sys._getframe(1)
        while frame is not None and frame.f_globals.get("__name__") in self._IMPORT_MACHINERY:
            frame = frame.f_back
        importer = (frame.f_globals.get("__file__") or "") if frame is not None else ""
        for root, site in tuple(self.sites.items()):  # a snapshot: another thread may register an FMU
            if importer.startswith(root):
                return importlib.machinery.PathFinder.find_spec(name, [site])
        return None

    def invalidate_caches(self) -> None:
        pass


def _bundled_site_packages() -> _BundledSitePackages:
    """The process-wide finder (one for every FMU and every copy of this file), appended once."""
    finder = _REGISTRY.__dict__.get("site_packages_finder")
    if finder is None:
        finder = _REGISTRY.__dict__.setdefault("site_packages_finder", _BundledSitePackages())
        sys.meta_path.append(finder)
    return finder


def _python_config(resources_dir: str) -> dict:
    """``resources/python.cfg`` (key=value lines written at build time) as a dict."""
    try:
        with open(os.path.join(resources_dir, "python.cfg"), encoding="utf-8") as f:
            return dict(line.rstrip("\n").split("=", 1) for line in f if "=" in line)
    except OSError:
        return {}


def _register_bundled_packages(resources_dir: str) -> None:
    """Let a portable FMU's code import its bundled packages the host lacks, in the bundled version only."""
    config = _python_config(resources_dir)
    site = os.path.join(resources_dir, "python", "site-packages")
    if config.get("portable") == "1" and config.get("version") == _running_version() and os.path.isdir(site):
        sites = _bundled_site_packages().sites
        for gone in [root for root, other in sites.items() if not os.path.isdir(other)]:
            del sites[gone]  # FMUs unpacked, then deleted by the host (fmpy's simulate_fmu does)
        sites[os.path.join(resources_dir, "")] = site


def _borrow_builder_python(resources_dir: str) -> None:
    """A non-portable FMU in the interpreter a portable FMU started (whichever FMU instantiates
    first starts the process's Python): that bundle carries only what its own model needs, so what
    else this FMU imports (standard library modules, numpy's friends, fmpy's SUNDIALS) comes from
    the Python that built it, when it is the same version, from the end of sys.path."""
    config = _python_config(resources_dir)
    stdlib = config.get("stdlib", "")
    in_bundle = os.path.exists(os.path.join(sys.prefix, "lib", "deltafmi-starter.so"))
    if not in_bundle or config.get("portable") == "1" or config.get("version") != _running_version():
        return
    environment = os.path.dirname(os.path.dirname(config.get("executable", "")))
    for path in (stdlib, os.path.join(stdlib, "lib-dynload"), os.path.join(stdlib, "site-packages"),
                 os.path.join(environment, "lib", f"python{_running_version()}", "site-packages")):
        if stdlib and os.path.isdir(path) and path not in sys.path:
            sys.path.append(path)


def _running_version() -> str:
    return f"{sys.version_info.major}.{sys.version_info.minor}"


def _shareable(info: dict, resources_dir: str) -> dict:
    """The modules this FMU may share with other FMUs in the process ({name: key}); none for a
    portable FMU (its modules find the libraries it carries beside themselves), nor for one whose
    carried files differ from what the build recorded the keys of (edited since)."""
    shared = info.get("shared_modules")
    if _python_config(resources_dir).get("portable") == "1" or not isinstance(shared, dict) \
            or not _as_built(os.path.join(resources_dir, "python"), info.get("shared_files")):
        return {}
    return shared


def _as_built(python_dir: str, digests) -> bool:
    """Whether every file of ``digests`` ({path under python_dir: sha256}, recorded at build
    time) is still as the build wrote it."""
    if not isinstance(digests, dict) or not digests:
        return False
    for relative, digest in digests.items():
        try:
            with open(os.path.join(python_dir, *relative.split("/")), "rb") as f:
                if hashlib.sha256(f.read()).hexdigest() != digest:
                    return False
        except OSError:
            return False
    return True


def _import_model(resources_dir: str) -> tuple:
    with open(os.path.join(resources_dir, "deltafmi.json"), encoding="utf-8") as f:
        info = json.load(f)
    bundle = _Bundle(os.path.join(resources_dir, "python"), _shareable(info, resources_dir))
    digest = hashlib.sha1(os.fsencode(resources_dir)).hexdigest()[:12]
    unique = f"_deltafmi_fmu_{info['model_identifier']}_{digest}"
    with bundle.active():
        runtime = importlib.import_module("deltafmi.runtime.instance")
        # the runtime package loads its public names on first use (PEP 562): load them now, from
        # this FMU's copy, not when a model touches one after the copy left sys.modules again
        package = sys.modules["deltafmi.runtime"]
        for name in getattr(package, "__all__", ()):
            getattr(package, name)
        spec = importlib.util.spec_from_file_location(unique, os.path.join(resources_dir, "model", info["source"]))
        module = importlib.util.module_from_spec(spec)
        sys.modules[unique] = module  # pickled FMU states name classes by this module
        spec.loader.exec_module(module)
    return info, getattr(module, info["class_name"]), runtime.FmuInstance, bundle.active


class FmuStartError(RuntimeError):
    """The FMU cannot run in this interpreter; the bridge logs the message alone, no traceback."""


def _missing_module(error: ImportError, resources_dir: str) -> FmuStartError:
    if error.name is None:  # not a module lookup (the solver's libraries not found): its message says it all
        return FmuStartError(str(error))
    with open(os.path.join(resources_dir, "deltafmi.json"), encoding="utf-8") as f:
        info = json.load(f)
    source, version_option = info["source"], _version_option(info)
    version = _running_version()
    bundled = _python_config(resources_dir)
    if bundled.get("portable") == "1" and bundled.get("version") != version:
        version += (f"; the packages this portable FMU carries are for CPython {bundled.get('version')} and "
                    "serve only that version")
    return FmuStartError(
        f"this FMU's model needs the Python module '{error.name}', which the Python it runs in "
        f"({sys.executable or 'embedded'}, CPython {version}) does not have ({error}). Install it there "
        f"(pip install {(error.name or '').split('.')[0]}), or point DELTAFMI_PYTHON and DELTAFMI_LIBPYTHON at a "
        f"Python that has it, or rebuild the FMU with `deltafmi build {source}{version_option} --portable`, which "
        "makes an FMU that carries its own Python and packages.")


def _version_option(info: dict) -> str:
    """The ``deltafmi build`` option that makes an FMU of the recorded FMI version again."""
    return " --fmi-version 3" if info.get("fmi_version") == 3 else ""


def _token_mismatch(info: dict, token: str, fmu_type: int, resources_dir: str) -> RuntimeError:
    """The importer's GUID (FMI 2.0) or instantiationToken (FMI 3.0) is not this FMU's."""
    if info.get("fmi_version") == 3:
        function = ("fmi3InstantiateModelExchange", "fmi3InstantiateCoSimulation",
                    "fmi3InstantiateScheduledExecution")[fmu_type] if 0 <= fmu_type <= 2 else "fmi3Instantiate"
        what = "instantiationToken"
    else:
        function, what = "fmi2Instantiate", "GUID"
    return RuntimeError(f"{function}: {what} {token} does not match this FMU's {info['guid']} "
                        f"({resources_dir}); the modelDescription.xml and the binary disagree")


def load(resources_dir: str, instance_name: str, guid: str, fmu_type: int):
    """Create the Python side of one FMU instance (called by the bridge from fmi2Instantiate or
    fmi3Instantiate*); ``guid`` is the FMI 2.0 GUID or the FMI 3.0 instantiationToken."""
    resources_dir = os.path.realpath(resources_dir)
    with _LOCK:  # a second thread waits for the first one's import instead of importing again
        if resources_dir not in _LOADED:
            try:
                _register_bundled_packages(resources_dir)
                _borrow_builder_python(resources_dir)
                _LOADED[resources_dir] = _import_model(resources_dir)
            except ImportError as exc:
                raise _missing_module(exc, resources_dir) from None
    info, component_class, instance_class, context = _LOADED[resources_dir]
    if guid and guid != info["guid"]:
        raise _token_mismatch(info, guid, fmu_type, resources_dir)
    try:
        return instance_class(component_class, instance_name, fmu_type, resources_dir, context)
    except ImportError as exc:  # what an instance loads when created (the CVODE solver)
        raise _missing_module(exc, resources_dir) from None


_REGISTRY.__dict__.setdefault("boots", {})[__file__] = load
