"""Pack a component source file into a ``.fmu``: model description, binaries, resources, sources."""
from __future__ import annotations

import hashlib
import importlib.util
import json
import keyword
import logging
import re
import sys
import uuid
import warnings
import zipfile
from pathlib import Path
from typing import Optional, Sequence

import deltafmi
from deltafmi.runtime import Component
from deltafmi.runtime.checks import definition_problem
from deltafmi.runtime.model_description import model_description_xml
from deltafmi.runtime.clocks import clock_driven
from deltafmi.runtime.model_description3 import model_description3_xml
from deltafmi.runtime.native_kernels import DESCRIPTION as NATIVE_KERNELS
from ..files import replaced_atomically
from deltafmi.toolchain import (BuildError, NoCompilerError, building, cache_dir, compiler_available, no_compiler_message,
                                plain_c_library, python_extension)
from .compiler import CFLAGS, fmu_binary, native_source_files, python_runtime_config
from .codegen.component_kernels import component_library
from .build_stamps import Stamp, file_request, recorded, remember, stamps_of
from .bytecode import unchecked_hash_pyc
from .equations import SOURCES as EQUATION_COMPILER, generated_files
from .reach import BOOT_SOURCE, module_archive_name, module_source, reached_modules
from .shared_modules import carried_digests, module_keys
from . import compiler as _compiler, reach as _reach, shared_modules as _shared_modules
from .source_error import import_failure
from .sources import ComponentSourceError, find_component, split_file_reference

__all__ = ["BUILD_LOG", "ComponentSourceError", "VALUE_ACCESS_SOURCE", "build_cached", "build_fmu", "cached_build",
           "load_component_class", "runtime_modules"]

PACKAGE_DIR = Path(deltafmi.__file__).parent
#: compiled value access of the variable declarations (see deltafmi/runtime/native_values.py)
VALUE_ACCESS_SOURCE = PACKAGE_DIR / "runtime" / "_values.c"
#: the modules that write modelDescription.xml at build time (FMUs do not carry them)
_MODEL_DESCRIPTIONS = ["deltafmi.runtime.model_description", "deltafmi.runtime.model_description3"]
#: FMI versions deltafmi builds, with where each puts its binary (FMI 3.0 names the platform
#: <arch>-<os>, FMI 2.0 linux64)
FMI_VERSIONS = (2, 3)
_BINARY_DIR = {2: "binaries/linux64", 3: "binaries/x86_64-linux"}
_GUID_NAMESPACE = uuid.UUID("6f1c8a52-4d0e-4f5e-9a53-0d3c5e2b7a11")
#: the names build_fmu itself writes directly under resources/: a resource file may take none of them
_RESERVED_RESOURCES = ("model", "python", "deltafmi_boot.py", "__pycache__", "deltafmi.json", "python.cfg", "README.txt",
                       NATIVE_KERNELS)


class ResourceError(ComponentSourceError):
    """A file to carry in an FMU's ``resources/`` is missing, or its name is taken."""


def resource_files(resources: Sequence[Path | str] = ()) -> list[tuple[Path, str]]:
    """(file, archive name) of the files an FMU carries for its component in ``resources/``,
    each under its own name: the FMI importer passes the unpacked folder's location at
    instantiation, which the component sees as ``self.resources_dir`` (FMI 2.0 section 2.1.7,
    ``fmuResourceLocation``; FMI 3.0 ``resourcePath``). :class:`ResourceError` for a missing file,
    two files of one name, or a name the FMU's own files use."""
    found: dict[str, Path] = {}
    for item in resources:
        path = Path(item)
        if not path.is_file():
            raise ResourceError(f"resource {item}: no such file")
        if path.name in _RESERVED_RESOURCES:
            raise ResourceError(f"resource {item}: the FMU's own resources/{path.name} has that name; rename it")
        if path.name in found and found[path.name].resolve() != path.resolve():
            raise ResourceError(f"resources {found[path.name]} and {item}: two files named {path.name}")
        found[path.name] = path
    return [(path, f"resources/{name}") for name, path in sorted(found.items())]


def load_component_class(source: Path, class_name: Optional[str] = None) -> type[Component]:
    """Import ``source`` and return the Component subclass ``class_name`` defined in it, or
    the one it defines when ``class_name`` is None."""
    source = Path(source)
    if not source.is_file():
        raise ComponentSourceError(f"{source}: no such file")
    if source.suffix != ".py":
        raise ComponentSourceError(f"{source}: a component's source is a Python file (.py)")
    name = f"_deltafmi_source_{re.sub(r'[^0-9a-zA-Z_]', '_', source.stem)}_{_digest(source.read_bytes())[:8]}"
    spec = importlib.util.spec_from_file_location(name, source)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        raise ComponentSourceError(f"{source}: importing it failed: {import_failure(exc)}") from exc
    classes = [obj for obj in vars(module).values()
               if isinstance(obj, type) and issubclass(obj, Component) and obj.__module__ == name]
    if class_name is not None:
        chosen = [c for c in classes if c.__name__ == class_name]
        if not chosen:
            found = ", ".join(c.__name__ for c in classes) or "none"
            raise ComponentSourceError(f"{source}: defines no component class '{class_name}' (it defines: {found})")
        classes = chosen
    if len(classes) != 1:
        found = ", ".join(c.__name__ for c in classes) or "none"
        hint = f" (build one of them as {source.name}:{classes[0].__name__})" if classes else ""
        raise ComponentSourceError(f"{source}: expected exactly one Component subclass, found {found}{hint}")
    cls = classes[0]
    identifier = cls.fmi_model_name()
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", identifier) or keyword.iskeyword(identifier):
        raise ComponentSourceError(f"{source}: model name {identifier!r} is not a valid C identifier")
    problem = definition_problem(cls)
    if problem:
        raise ComponentSourceError(problem)
    return cls


def runtime_modules(source: Path) -> list[str]:
    """The deltafmi modules an FMU of ``source`` carries: those its component source and the FMU
    runtime reach through their import statements (see :mod:`deltafmi.builder.reach`)."""
    return reached_modules([Path(source)])


def runtime_files(source: Path) -> list[tuple[Path, str]]:
    """(file, archive name) of the deltafmi sources bundled under ``resources/python`` for ``source``."""
    files = []
    for name in runtime_modules(source):
        files.append((module_source(name), f"resources/python/{module_archive_name(name)}"))
    return files


#: the plain C the master compiles when it runs (package-relative source -> the module that loads it)
PLAIN_C_SOURCES = {"master/stepping/native/fixed_step.c": "deltafmi.master.stepping.c_loop",
                   "master/stepping/native/erk.c": "deltafmi.master.stepping.explicit_rk",
                   "master/results/native/csv_rows.c": "deltafmi.master.results.csv_file",
                   "master/system_fmu/native/system_step.c": "deltafmi.master.system_fmu.direct",
                   "master/live/native/udp_reader.c": "deltafmi.master.live.native_udp"}
#: the data files the master reads when it runs (package-relative file -> the module that reads it)
MASTER_DATA = {"master/scenario/scenario.schema.json": "deltafmi.master.scenario.spec"}


def binary_files(source: Path) -> list[tuple[Path, str]]:
    """(file, archive name) of the compiled pieces bundled for ``source``: the value access, when
    the modules it carries use it, and the master's C, when it carries the master (a scenario
    exported as one FMU). A model's compiled kernels are C generated from its Python, loaded by
    the FMU's C layer: see :func:`.codegen.component_kernels.component_library`."""
    modules = runtime_modules(source)
    return compiled_value_access(modules) + compiled_master_loops(modules)


def compiled_master_loops(modules: list[str]) -> list[tuple[Path, str]]:
    """(file, archive name) of the data files and C sources of the master that ``modules`` read,
    each C source with its library compiled here into the bundle's prebuilt layer, so that the FMU
    needs no compiler where it runs;
    a piece that cannot be compiled is left out, with a warning (the master then steps in Python)."""
    package = Path(deltafmi.__file__).resolve().parent
    files = [(package / relative, f"resources/python/deltafmi/{relative}")
             for relative, user in MASTER_DATA.items() if user in modules]
    for relative, user in PLAIN_C_SOURCES.items():
        if user not in modules:
            continue
        try:
            library = plain_c_library(package / relative)
        except BuildError as exc:
            warnings.warn(f"the FMU's master steps in Python (same results, slower): {exc}", stacklevel=2)
            continue
        files.append((package / relative, f"resources/python/deltafmi/{relative}"))
        files.append((library, f"resources/python/deltafmi/_prebuilt/native/{library.parent.name}/{library.name}"))
    return files


def compiled_value_access(modules: Optional[list[str]] = None) -> list[tuple[Path, str]]:
    """(extension module, archive name) of the compiled value access, shipped beside its C source,
    when ``modules`` (default: all) include its user; empty, with a warning, when it cannot be
    compiled (the FMU then reads values in Python)."""
    if modules is not None and "deltafmi.runtime.native_values" not in modules:
        return []
    if sys.version_info < (3, 11):  # _values.c uses 3.11's stable ABI (the buffer protocol)
        return []
    try:
        module = python_extension(VALUE_ACCESS_SOURCE)
    except BuildError as exc:
        warnings.warn(f"FMUs ship without the compiled value access (same results, slower): {exc}", stacklevel=2)
        return []
    folder = "resources/python/deltafmi/runtime"
    return [(module, f"{folder}/{module.name}"), (VALUE_ACCESS_SOURCE, f"{folder}/{VALUE_ACCESS_SOURCE.name}")]


def content_key(source: Path, class_name: Optional[str] = None, fmi_version: int = 2,
                resources: Sequence[Path | str] = ()) -> str:
    """Hash of everything that determines an FMU built from ``source``: the files it carries
    (so that editing a module the model does not reach leaves its cached FMU valid), the
    ``resources`` by name and content, the FMI version, the native sources of its binary and how
    they are compiled, the code that writes its modelDescription.xml, this packager and the Python
    it was built for."""
    return _keyed(Path(source), class_name, fmi_version, resources)[0]


def _keyed(source: Path, class_name: Optional[str], fmi_version: int,
           resources: Sequence[Path | str]) -> tuple[str, list[Stamp]]:
    """:func:`content_key`, and the stamps of the files and folders it was taken from (taken
    before they were read), with which :mod:`.build_stamps` finds it again without reading them."""
    _check_version(fmi_version)
    _fmu_binary_for(source, fmi_version)  # first: without it nothing else matters (no warnings about the rest)
    carried = runtime_files(source) + binary_files(source) + resource_files(resources)
    writers = [module_source(name) for name in reached_modules(modules=_MODEL_DESCRIPTIONS, runtime=False)]
    codegen = PACKAGE_DIR / "builder" / "codegen"
    generator = sorted([*codegen.glob("*.py"), *codegen.glob("*.c")])  # writes the compiled kernels' C
    generator += EQUATION_COMPILER  # writes an equation model's kernels
    hashed = native_source_files(fmi_version) + writers + generator + [Path(__file__), BOOT_SOURCE, SHARED_MODULES]
    # folders where reached modules were found: a module added to one may be reached (from P import name);
    # the generators' folders: a file added to one is part of the generator
    folders = sorted({path.parent for path, _ in carried} | {path.parent for path in writers} |
                     {codegen, *(path.parent for path in EQUATION_COMPILER)})
    # stamped, not hashed: the code that decides what this key hashes (which modules are carried, the
    # binary's sources and flags); what it decides is hashed, so an edit there costs a hash, not a build
    stamps = stamps_of([source, *(path for path, _ in carried), *hashed, *KEY_CODE, *folders])
    digest = hashlib.sha256(Path(source).read_bytes() + f"\0{class_name or ''}\0fmi{fmi_version}\0".encode())
    for path, arcname in carried:
        digest.update(f"{arcname}\0{path.stat().st_size}\0".encode("utf-8", "surrogateescape") + path.read_bytes())
    for path in hashed:
        digest.update(path.read_bytes())
    digest.update(" ".join(CFLAGS).encode())  # how the binary is compiled
    # an FMU built where its compiled kernels could not be (no compiler) is not the one built where they can
    digest.update(f"\0compiler={compiler_available()}".encode())
    # the environment, not the interpreter's name in it: bin/python and bin/python3.12 (the console
    # scripts' shebang) of one venv build the same FMU
    digest.update(re.sub(r"(?m)^executable=.*$", f"prefix={sys.prefix}", python_runtime_config()).encode("utf-8", "surrogateescape"))
    return digest.hexdigest(), stamps


#: writes the keys of the modules an FMU may share (recorded in its deltafmi.json)
SHARED_MODULES = Path(_shared_modules.__file__)
#: the modules that decide which files a content key reads (the FMU's modules, its binary's
#: sources and flags, the Python it runs in)
KEY_CODE = [Path(_compiler.__file__), Path(_reach.__file__)]

#: where :func:`build_cached` says, at INFO, that it builds an FMU (silent when the FMU is cached);
#: the commands show it on stderr (``-q``: not), the API leaves it to the user's logging set-up
BUILD_LOG = logging.getLogger("deltafmi.build")


def build_fmu(source: Path | str, output: Optional[Path] = None, portable: bool = False,
              class_name: Optional[str] = None, fmi_version: int = 2, resources: Sequence[Path | str] = (),
              leave_out: Sequence[str] = ()) -> Path:
    """Build the FMU for the component in ``source`` (the class ``class_name``, needed only when
    the file defines several; ``source`` may also name a component as ``deltafmi build`` takes
    it: ``"DeltaRobot"``, ``"package.module:Class"``, ``"file.py:Class"``); returns the ``.fmu`` path.

    ``fmi_version`` 2 writes an FMI 2.0 FMU, 3 an FMI 3.0 one (both with Model Exchange and
    Co-Simulation, from the same class). The files ``resources`` are copied into the FMU's
    ``resources/`` folder, each under its name (:func:`resource_files`): the component reads
    them from its ``resources_dir``. A ``portable`` FMU also carries the interpreter, standard
    library and packages its model imports (see :mod:`deltafmi.builder.portable`), so that it runs
    where no Python is installed; ``leave_out`` names packages it does without where only the
    functions of deltafmi's own modules import them (a scenario exported as one FMU that has no
    algebraic loop never calls the loop solver's scipy)."""
    _check_version(fmi_version)
    source, class_name = _component(source, class_name)
    resources = resources or _shipped_resources(source)
    if portable:
        from .portable import make_portable
        cls = load_component_class(source, class_name)
        output = Path(output) if output else Path("build") / "fmus" / f"{cls.fmi_model_name()}.fmu"
        make_portable(build_cached(source, class_name=class_name, fmi_version=fmi_version, resources=resources),
                      output, leave_out)
        return output
    cls = load_component_class(source, class_name)
    identifier = cls.fmi_model_name()
    output = Path(output) if output else Path("build") / "fmus" / f"{identifier}.fmu"
    key = content_key(source, class_name, fmi_version, resources)
    guid = "{" + str(uuid.uuid5(_GUID_NAMESPACE, key)) + "}"
    binary = _fmu_binary_for(source, fmi_version)
    carried = runtime_files(source) + generated_files(cls)
    python_files = carried + binary_files(source)
    info = {"model_identifier": identifier, "class_name": cls.__name__, "source": source.name,
            "guid": guid, "fmi_version": fmi_version, "deltafmi_version": deltafmi.__version__,
            # what boot.py may share with another FMU in the process (see .shared_modules)
            "shared_modules": module_keys(python_files), "shared_files": carried_digests(python_files)}
    writer = model_description_xml if fmi_version == 2 else model_description3_xml
    kernels = component_library(cls)
    with replaced_atomically(output) as tmp:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as fmu:
            fmu.writestr("modelDescription.xml", writer(cls, guid))
            fmu.write(binary, f"{_BINARY_DIR[fmi_version]}/{identifier}.so")
            fmu.write(source, f"resources/model/{source.name}")
            fmu.write(BOOT_SOURCE, "resources/deltafmi_boot.py")
            fmu.writestr(importlib.util.cache_from_source("resources/deltafmi_boot.py"),
                         unchecked_hash_pyc(BOOT_SOURCE, "resources/deltafmi_boot.py"))
            fmu.writestr("resources/deltafmi.json", json.dumps(info, indent=2))
            fmu.writestr("resources/python.cfg", python_runtime_config())
            fmu.writestr("resources/README.txt", _readme(identifier, fmi_version, _interfaces(cls, fmi_version)))
            for path, arcname in carried:
                fmu.write(path, arcname)
                fmu.writestr(importlib.util.cache_from_source(arcname), unchecked_hash_pyc(path, arcname))
            for path, arcname in binary_files(source) + resource_files(resources):
                fmu.write(path, arcname)
            for path in native_source_files(fmi_version):
                fmu.write(path, f"sources/{path.name}")
            if kernels is not None:
                library = f"{_BINARY_DIR[fmi_version]}/{identifier}_kernels.so"
                fmu.write(kernels.library, library)
                fmu.write(kernels.source, f"sources/{kernels.source.name}")
                fmu.writestr(f"resources/{NATIVE_KERNELS}",
                             json.dumps({**kernels.description, "library": library}, indent=1))
            fmu.writestr("documentation/index.html", _documentation(cls, fmi_version))
    return output


def build_cached(source: Path | str, portable: bool = False, class_name: Optional[str] = None,
                 fmi_version: int = 2, resources: Sequence[Path | str] = ()) -> Path:
    """The FMU for ``source`` and ``resources`` (as :func:`build_fmu` takes them) from the per-user
    build cache, built when the source, a resource's content or the runtime changed."""
    return cached_build(source, portable, class_name, fmi_version, resources)


def cached_build(source: Path | str, portable: bool = False, class_name: Optional[str] = None,
                 fmi_version: int = 2, resources: Sequence[Path | str] = (),
                 also: Optional[tuple[str, Sequence[Stamp]]] = None) -> Path:
    """:func:`build_cached`; ``also``, (a :mod:`.build_stamps` request, stamps), is another request
    answered by this FMU while those stamps hold besides the FMU's own (a module reference,
    resolved through its module's file)."""
    source, class_name = _component(source, class_name)
    resources = resources or _shipped_resources(source)
    request = None if portable else file_request(source, class_name, fmi_version, [Path(r) for r in resources])
    known = recorded(request) if request else None
    if known is not None:
        found, stamps = known
    else:
        found, stamps = _cached_or_built(source, portable, class_name, fmi_version, resources)
        if request:
            remember(request, stamps, found)
    if also is not None and request:
        remember(also[0], [*stamps, *also[1]], found)
    return found


def _cached_or_built(source: Path, portable: bool, class_name: Optional[str], fmi_version: int,
                     resources: Sequence[Path | str]) -> tuple[Path, list[Stamp]]:
    key, stamps = _keyed(source, class_name, fmi_version, resources)
    key = key[:20]
    if portable:
        from .portable import bundle_key
        key += "-portable-" + bundle_key()[:12]
    target = cache_dir() / "fmus" / key
    existing = list(target.glob("*.fmu")) if target.is_dir() else []
    if existing:
        return existing[0], stamps
    with building(target):
        existing = list(target.glob("*.fmu")) if target.is_dir() else []
        if existing:  # another process built it while this one waited
            return existing[0], stamps
        cls = load_component_class(source, class_name)
        BUILD_LOG.info("building %s FMU (cached afterwards in %s) ...", cls.__name__,
                       _home_relative(cache_dir() / "fmus"))
        return build_fmu(source, target / f"{cls.fmi_model_name()}.fmu", portable=portable, class_name=class_name,
                         fmi_version=fmi_version, resources=resources), stamps


def _shipped_resources(source: Path) -> list[Path]:
    """The data files a packaged model's FMU carries when built with no resources given
    (:data:`deltafmi.models.RESOURCES`, files of scenarios/); none for any other source."""
    from deltafmi import models
    from deltafmi.shipped import SCENARIOS_DIR

    if Path(source).resolve().parent != Path(models.__file__).resolve().parent:
        return []
    return [SCENARIOS_DIR / name for name in models.RESOURCES.get(Path(source).stem, ())]


def _component(source: Path | str, class_name: Optional[str]) -> tuple[Path, Optional[str]]:
    """A source file and class name as given, or those of a component named as the CLI names it
    (a Modelica file: the equation model written for it, see :mod:`.equations.modelica`)."""
    file, named = (str(source), class_name) if class_name else split_file_reference(str(source))
    if file.endswith(".mo") and Path(file).is_file():
        from .equations.modelica import python_source_for
        return python_source_for(Path(file), named, cache_dir() / "modelica")
    if Path(source).is_file():
        return Path(source), class_name
    if class_name is not None:
        raise ComponentSourceError(f"{source}: no such file")
    found = find_component(str(source))
    return found.path, found.class_name


def _home_relative(path: Path) -> str:
    try:
        return "~/" + path.relative_to(Path.home()).as_posix()
    except ValueError:
        return str(path)


def _fmu_binary_for(source: Path, fmi_version: int) -> Path:
    """The FMU binary; without a compiler to build it, the error names the component ``source``."""
    try:
        return fmu_binary(fmi_version)
    except NoCompilerError:  # name the component, not the C file that would be compiled
        raise NoCompilerError(f"{source}: {no_compiler_message()}") from None


def _check_version(fmi_version: int) -> None:
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"fmi_version must be 2 or 3, not {fmi_version!r}")


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


_REQUIREMENTS = ("This FMU runs its model in CPython (3.10 or newer) with numpy, scipy and fmpy "
                 "installed. In a Python host (fmpy, libcosimpy, ...) it uses the host's interpreter. "
                 "In any other host (a C program, Simulink, OpenModelica, Dymola, libcosim) the binary "
                 "loads the Python library named in resources/python.cfg, recorded when the FMU was built; "
                 "override it with the environment variables DELTAFMI_LIBPYTHON (path of libpython3.x.so) "
                 "and DELTAFMI_PYTHON (the interpreter whose site-packages to use).")


def _interfaces(cls: type[Component], fmi_version: int) -> str:
    """The interfaces the FMU provides, in words."""
    if cls.co_simulation_only:
        return "Co-Simulation"
    if fmi_version == 3 and clock_driven(cls):
        return "Model Exchange, Co-Simulation and Scheduled Execution"
    return "Model Exchange and Co-Simulation"


def _readme(identifier: str, fmi_version: int, interfaces: str) -> str:
    return (f"{identifier}: an FMI {fmi_version}.0 FMU ({interfaces}) built by deltafmi "
            f"{deltafmi.__version__}.\n\n{_REQUIREMENTS}\n\nmodel/ holds the component source, python/ the "
            "deltafmi runtime it uses, deltafmi_boot.py the code the native bridge runs to load it.\n")


def _documentation(cls: type[Component], fmi_version: int) -> str:
    import html
    doc = html.escape((cls.__doc__ or "").strip())
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{cls.fmi_model_name()}</title></head>"
            f"<body><h1>{cls.fmi_model_name()}</h1><p>An FMI {fmi_version}.0 FMU ({_interfaces(cls, fmi_version)}) "
            f"built by deltafmi {deltafmi.__version__}.</p><pre>{doc}</pre><h2>Requirements</h2>"
            f"<p>{html.escape(_REQUIREMENTS)}</p></body></html>\n")
