"""What a portable FMU carries so that it runs where no Python is installed.

``deltafmi build --portable`` adds, under ``resources/python`` beside the FMU's deltafmi runtime:

- ``lib/libpython3.X.so.1.0``: the builder's interpreter (stripped of debug information), and
  ``lib/deltafmi-starter.so``, which starts it with an isolated configuration (``native/starter.c``);
- ``lib/python3X.zip``: the part of the standard library the model reaches, as bytecode; the
  extension modules it loads in ``lib/lib-dynload``;
- ``site-packages/``: the third-party packages the model imports (numpy and its ``numpy.libs``), as
  bytecode and extension modules, without the subpackages the model never imports, tests and headers;
- ``lib/``: every shared library those binaries need that is not part of glibc (libffi, libz,
  libcrypto, ...), which the loader opens before the interpreter starts (listed in order in
  ``python.cfg``), so that a binary's dependency is found by its soname;
- ``documentation/licenses/``: the licence of everything bundled.

What "the model reaches" is the trace of ``imports.py``: the modules in ``sys.modules`` after the
model ran through the FMU's runtime in the builder's Python, plus what the boot code and bridge need.
glibc is the one thing not bundled: the FMU records the newest glibc symbol version any bundled
binary needs (its floor) and the loader refuses, with a message, a machine whose glibc is older.
"""
from __future__ import annotations

import functools
import io
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Optional, Sequence

from deltafmi.toolchain import BuildError, abi_tag, build_into, cache_dir, python_include, single_file_library, strip_unneeded
from .compiler import NATIVE_DIR
from .bytecode import unchecked_hash_pyc

__all__ = ["bundle_key", "make_portable", "starter_library"]

PYTHON_DIR = "resources/python"
#: shared libraries of glibc itself: the host provides them (the FMU states the version it needs)
GLIBC_LIBRARIES = {"libc.so.6", "libm.so.6", "libdl.so.2", "libpthread.so.0", "librt.so.1", "libutil.so.1",
                   "libresolv.so.2", "libanl.so.1", "ld-linux-x86-64.so.2", "libmvec.so.1"}
#: modules the boot code and the bridge use whatever the model imports
BOOT_MODULES = ("encodings", "runpy", "traceback", "pickle", "copyreg", "json", "hashlib", "contextlib",
                "importlib.util", "importlib.machinery", "threading", "logging", "warnings", "struct", "math",
                "copy", "types", "linecache", "tokenize", "weakref")
#: extension modules left out: hashlib falls back to CPython's own hashes without OpenSSL's _hashlib,
#: which would bring libcrypto (4.6 MB); nothing in an FMU speaks TLS
_UNBUNDLED = ("_hashlib", "_ssl")
#: never bundled from a package: tests, headers, type stubs, sources of compiled code
_SKIPPED_FILES = re.compile(r"(\.pyi|\.pxd|\.h|\.c|\.pyx|\.typed|\.a)$")
_SKIPPED_DIRS = {"tests", "test", "__pycache__", "include", "_pyinstaller"}
#: development tools that libraries import if they happen to be installed and run without
#: (scipy's test utilities try Cython): a trace on the builder's machine sees them, no model needs them
_OPPORTUNISTIC = {"Cython", "cython", "pyximport"}
#: packages deltafmi's own modules import (inside functions) only for what a run from the command
#: line does, which no FMU does: plots and the live display (matplotlib), data frames (pandas),
#: Parquet and MAT result files (pyarrow, scipy.io). A scenario exported as one FMU carries the
#: master's modules with those functions; the FMU bundles these packages only where its trace
#: imports them when it runs, or its model's own files name them.
HOST_ONLY = ("matplotlib", "pandas", "pyarrow", "scipy.io")
#: bundle files from this size on (bytes) are compressed once into the build cache (:func:`_compressed_members`)
_LARGE_MEMBER = 1 << 20
_STDLIB_SKIPPED = {"test", "idlelib", "tkinter", "turtledemo", "ensurepip", "lib2to3", "pydoc_data",
                   "site-packages", "lib-dynload", "config-" + sysconfig.get_config_var("LDVERSION") + "-x86_64-linux-gnu"}


@dataclass
class PortableBundle:
    """Files of the bundle: (file on disk, archive name), generated (bytes, archive name), python.cfg."""
    files: list = field(default_factory=list)
    data: list = field(default_factory=list)
    config: str = ""
    glibc_floor: tuple = (2, 0)
    licenses: list = field(default_factory=list)
    python_version: str = ""


def python_tag() -> str:
    """'3.11' for the builder's interpreter."""
    return f"{sys.version_info.major}.{sys.version_info.minor}"


def _stdlib_dir() -> Path:
    return Path(sysconfig.get_path("stdlib")).resolve()


def _site_dirs() -> list[Path]:
    import site
    dirs = set(site.getsitepackages() + [site.getusersitepackages(), sysconfig.get_path("purelib"),
                                         sysconfig.get_path("platlib")])
    return sorted({Path(d).resolve() for d in dirs if d and Path(d).is_dir()}, key=lambda p: -len(str(p)))


def boot_modules() -> dict[str, Optional[str]]:
    """Module name -> file of everything ``BOOT_MODULES`` imports, in a clean interpreter."""
    script = "\n".join([
        "import sys, json",
        f"for name in {_UNBUNDLED!r}: sys.modules[name] = None",
        f"for name in {BOOT_MODULES!r}: __import__(name)",
        "import hashlib; hashlib.sha1(b'')",  # imports the fallback the boot code's digest uses then
        f"for name in {_UNBUNDLED!r}: del sys.modules[name]",
        "print(json.dumps({n: getattr(m, '__file__', None) for n, m in sys.modules.items()}))"])
    import json
    result = subprocess.run([sys.executable, "-I", "-S", "-c", script], capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(f"listing the modules the FMU's boot code needs failed:\n{result.stderr}")
    return json.loads(result.stdout)


def classify(modules: Mapping[str, Optional[str]]) -> tuple[set, set, dict]:
    """(stdlib top-level names, lib-dynload files, third-party: site dir -> top-level names)."""
    stdlib, dynload, third_party = set(), set(), {}
    root, sites = _stdlib_dir(), _site_dirs()
    for name, file in modules.items():
        if not file:
            continue
        path = Path(file).resolve()
        site = next((s for s in sites if s in path.parents), None)
        if site is not None:
            top = path.relative_to(site).parts[0]
            top = Path(top).stem if path.parent == site else top
            if top not in _OPPORTUNISTIC:
                third_party.setdefault(site, set()).add(top)
        elif path.parent.name == "lib-dynload" and root in path.parents:
            if name not in _UNBUNDLED:
                dynload.add(path)
        elif root in path.parents:
            top = path.relative_to(root).parts[0]
            if top not in _STDLIB_SKIPPED:
                stdlib.add(Path(top).stem if path.parent == root else top)
    return stdlib, dynload, third_party


def _stdlib_zip(tops: set) -> bytes:
    """The standard library's modules and packages named in ``tops`` as a zip of .pyc files.

    Stored, not deflated: zipimport would need zlib to read it before anything else is imported
    (zlib may not even be bundled), and the FMU's own zip compresses it anyway."""
    root = _stdlib_dir()
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        for top in sorted(tops):
            package = root / top
            files = sorted(p for p in package.rglob("*.py") if not _SKIPPED_DIRS & set(p.relative_to(root).parts)) \
                if package.is_dir() else [root / f"{top}.py"]
            for path in files:
                if path.is_file():
                    name = path.relative_to(root).as_posix()
                    archive.writestr(name + "c", unchecked_hash_pyc(path, name))
    return buffer.getvalue()


def _package_files(site: Path, top: str, imported: set) -> list[tuple[Path, str]]:
    """Files of the third-party package ``top`` (its subpackages the model imported only)."""
    base = site / top
    if not base.is_dir():
        return [(p, p.name) for p in site.glob(f"{top}.*") if p.is_file() and p.suffix in (".py", ".so")]
    out = []
    for directory, subdirs, files in os.walk(base):
        relative = Path(directory).relative_to(site)
        dotted = ".".join(relative.parts)
        subdirs[:] = [d for d in subdirs if d not in _SKIPPED_DIRS and
                      (not (Path(directory) / d / "__init__.py").exists() or f"{dotted}.{d}" in imported)]
        for name in files:
            if not _SKIPPED_FILES.search(name):
                out.append((Path(directory) / name, (relative / name).as_posix()))
    libs = site / f"{top}.libs"  # auditwheel's folder of the wheel's own shared libraries
    if libs.is_dir():
        out += [(p, f"{libs.name}/{p.name}") for p in sorted(libs.iterdir()) if p.is_file()]
    return out


@functools.lru_cache(maxsize=None)  # each binary's section is read for its NEEDED and its SONAME
def _dynamic(binary: Path) -> str:
    return subprocess.run(["readelf", "-d", "-W", str(binary)], capture_output=True, text=True).stdout


def _needed(binary: Path) -> list[str]:
    return re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", _dynamic(binary))


def _soname(binary: Path) -> str:
    found = re.search(r"\(SONAME\)\s+Library soname: \[([^\]]+)\]", _dynamic(binary))
    return found.group(1) if found else binary.name


@functools.lru_cache(maxsize=None)
def _resolved(binary: Path) -> dict[str, str]:
    """soname -> path, as the dynamic linker of this machine resolves ``binary``'s dependencies."""
    result = subprocess.run(["ldd", str(binary)], capture_output=True, text=True)
    return dict(re.findall(r"^\s*(\S+) => (/\S+)", result.stdout, re.M))


@functools.lru_cache(maxsize=None)
def glibc_versions(binary: Path) -> frozenset[tuple[int, ...]]:
    """The GLIBC_x.y symbol versions ``binary`` requires."""
    result = subprocess.run(["readelf", "-V", "-W", str(binary)], capture_output=True, text=True)
    return frozenset(tuple(int(x) for x in v.split(".")) for v in re.findall(r"Name: GLIBC_([0-9.]+)", result.stdout))


def _is_elf(path: Path) -> bool:
    with open(path, "rb") as f:
        return f.read(4) == b"\x7fELF"


def _stripped_copy(binary: Path) -> Path:
    """``binary`` without debug information (libpython from pyenv is 23 MB with, ~5 MB without)."""
    digest = f"{binary.name}-{binary.stat().st_size}-{int(binary.stat().st_mtime)}"
    target = cache_dir() / "portable" / "stripped" / digest
    copy = target / binary.name
    if not copy.exists():
        def build(tmp: str) -> None:
            out = Path(tmp) / binary.name
            shutil.copy2(binary, out)
            strip_unneeded(out)
        build_into(target, build)
    return copy


def _libpython() -> Path:
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    soname = sysconfig.get_config_var("INSTSONAME") or ""
    path = Path(libdir) / soname
    if not sysconfig.get_config_var("Py_ENABLE_SHARED") or not path.is_file():
        raise BuildError(f"--portable needs a Python built with a shared libpython; {sys.executable} has none "
                         "(pyenv: PYTHON_CONFIGURE_OPTS=--enable-shared)")
    return path


def starter_library() -> Path:
    """``native/starter.c`` compiled against this Python's headers, from the cache."""
    return single_file_library(NATIVE_DIR / "starter.c", "deltafmi-starter.so", [python_include], abi_tag())


def portable_bundle(modules: Mapping[str, Optional[str]], needs_sundials: bool,
                    sundials_dir: Optional[Path] = None) -> PortableBundle:
    """The interpreter, standard library, packages and shared libraries for ``modules`` (name -> file)."""
    everything = dict(boot_modules())
    everything.update(modules)
    stdlib, dynload, third_party = classify(everything)
    version = python_tag()
    bundle = PortableBundle(python_version=version)
    zip_name = f"lib/python{version.replace('.', '')}.zip"
    dynload_dir = f"lib/python{version}/lib-dynload"
    bundle.data.append((_stdlib_zip(stdlib), f"{PYTHON_DIR}/{zip_name}"))
    libpython = _libpython()
    binaries: list[tuple[Path, str]] = [(_stripped_copy(libpython), f"lib/{libpython.name}"),
                                        (starter_library(), "lib/deltafmi-starter.so")]
    binaries += [(path, f"{dynload_dir}/{path.name}") for path in sorted(dynload)]
    imported = set(everything)
    packaged: list[tuple[Path, str]] = []
    for site, tops in third_party.items():
        for top in sorted(tops):
            packaged += [(p, f"site-packages/{name}") for p, name in _package_files(site, top, imported)]
            bundle.licenses += _package_licenses(site, top)
    if needs_sundials:
        if sundials_dir is None or not any(sundials_dir.glob("*.so")):
            raise BuildError("--portable: the model integrates with CVODE, and the SUNDIALS libraries fmpy ships "
                             f"are not on this machine ({sundials_dir or 'fmpy is not installed'})")
        binaries += [(p, f"sundials/{p.name}") for p in sorted(sundials_dir.glob("*.so"))]
        # fmpy's licence file carries SUNDIALS' BSD licence for the libraries it compiled
        fmpy_site = sundials_dir.parents[2]
        bundle.licenses += [(path, f"SUNDIALS (built by fmpy)/{Path(name).name}")
                            for path, name in _package_licenses(fmpy_site, "fmpy")]
    for path, name in packaged:
        if path.suffix == ".py":
            bundle.data.append((unchecked_hash_pyc(path, name), f"{PYTHON_DIR}/{name}c"))
        elif _is_elf(path):
            binaries.append((path, name))
        else:
            bundle.files.append((path, f"{PYTHON_DIR}/{name}"))
    preload = _dependencies(binaries)
    bundle.files += [(path, f"{PYTHON_DIR}/{name}") for path, name in binaries + preload]
    floor = max((v for path, _ in binaries + preload for v in glibc_versions(path)), default=(2, 2, 5))
    bundle.glibc_floor = floor
    bundle.licenses += _python_licenses() + _system_licenses([p for p, _ in preload])
    bundle.config = "".join(f"{key}={value}\n" for key, value in (
        ("portable", "1"), ("version", version), ("home", "python"),
        ("library", f"python/lib/{libpython.name}"), ("starter", "python/lib/deltafmi-starter.so"),
        ("paths", f"{zip_name};{dynload_dir};site-packages"),
        ("preload", ";".join(f"python/{name}" for _, name in preload)),
        ("glibc", ".".join(map(str, floor)))))
    return bundle


def _dependencies(binaries: list[tuple[Path, str]]) -> list[tuple[Path, str]]:
    """Shared libraries outside glibc that ``binaries`` need and do not carry, dependencies first."""
    carried = {Path(name).name for _, name in binaries} | {_soname(path) for path, _ in binaries}
    found: dict[str, Path] = {}
    order: list[str] = []

    def visit(binary: Path) -> None:
        resolved = None
        for soname in _needed(binary):
            if soname in GLIBC_LIBRARIES or soname in carried or soname in found:
                continue
            resolved = resolved if resolved is not None else _resolved(binary)
            if soname not in resolved:
                raise BuildError(f"--portable: {binary} needs {soname}, which this machine does not resolve")
            found[soname] = Path(resolved[soname])
            visit(found[soname])
            order.append(soname)

    for path, _ in binaries:
        visit(path)
    return [(found[soname], f"lib/{soname}") for soname in order]


def _package_licenses(site: Path, top: str) -> list[tuple[Path, str]]:
    out = []
    for info in site.glob("*.dist-info"):
        record = info / "top_level.txt"
        names = record.read_text().split() if record.exists() else [info.name.split("-")[0]]
        if top not in names and info.name.split("-")[0].lower() != top.lower():
            continue
        found = [(path, f"{top}/{path.relative_to(info).as_posix()}") for path in sorted(info.rglob("*"))
                 if path.is_file() and re.match(r"(LICEN[CS]E|COPYING|NOTICE)", path.name, re.I)]
        if not found and (info / "METADATA").is_file():  # no licence file: its declared licence, in its metadata
            found = [(info / "METADATA", f"{top}/METADATA")]
        out += found
    return out


def _python_licenses() -> list[tuple[Path, str]]:
    license_file = _stdlib_dir() / "LICENSE.txt"
    return [(license_file, "CPython/LICENSE.txt")] if license_file.exists() else []


def _system_licenses(libraries: list[Path]) -> list[tuple[Path, str]]:
    """Debian's copyright file of the package that installed each library (dpkg -S)."""
    # merged /usr: dpkg may know the file as /lib/... or /usr/lib/..., by its soname link or real name
    candidates = {library: sorted({str(library), str(library.resolve()), str(library.resolve()).removeprefix("/usr"),
                                   "/usr" + str(library)}) for library in libraries}
    owners = _dpkg_owners(tuple(sorted({c for names in candidates.values() for c in names})))
    out = []
    for library, names in candidates.items():
        package = next((owners[name] for name in names if name in owners), "")
        copyright_file = Path("/usr/share/doc") / package / "copyright"
        if package and copyright_file.exists():
            out.append((copyright_file, f"{library.name}/copyright"))
    return out


@functools.lru_cache(maxsize=None)
def _dpkg_owners(paths: tuple[str, ...]) -> dict[str, str]:
    """Absolute path -> the Debian package that installed it, for those of ``paths`` dpkg knows: one
    ``dpkg -S`` for all (it prints ``package[:arch]: path`` for each it knows, and exits 1 when
    it does not know one)."""
    if not paths or not shutil.which("dpkg"):
        return {}
    result = subprocess.run(["dpkg", "-S", *paths], capture_output=True, text=True)
    owners = {}
    for line in result.stdout.splitlines():
        package, sep, path = line.partition(": ")
        if sep and path in paths and not package.startswith("diversion by"):
            owners[path] = package.split(":")[0].strip()
    return owners


_TRACE = r'''
import importlib, json, math, os, runpy, sys
resources, out = sys.argv[1], sys.argv[2]
sys.path += sys.argv[3:]  # the site directories, without the site module's .pth hooks (not bundled)
load = runpy.run_path(resources + "/deltafmi_boot.py")["load"]
for fmu_type in (1, 0):  # Co-Simulation, then Model Exchange
    try:
        instance = load(resources, "trace", "", fmu_type)
    except ValueError:  # a model that offers Co-Simulation only
        continue
    instance.enter_initialization(0.0, math.nan, math.nan)
    instance.exit_initialization()
    for k in range(3):
        if fmu_type == 1:
            instance.do_step(k * 1e-3, 1e-3)
        else:
            instance.evaluate(k * 1e-3)
    state = instance.get_state()
    if instance.component_class.can_serialize_state:
        state = instance.deserialize_state(instance.serialize_state(state))
    instance.set_state(state)
    instance.terminate()
    instance.reset()
for name in json.loads(os.environ["DELTAFMI_STATIC_IMPORTS"]):  # what branches that did not run import
    try:
        importlib.import_module(name)
    except Exception:  # a name that is an attribute, not a module ("from numpy.linalg import LinAlgError")
        pass
json.dump({n: getattr(m, "__file__", None) for n, m in sys.modules.items()}, open(out, "w"))
'''


def static_imports(python_files: list[Path]) -> list[str]:
    """Modules outside deltafmi that the import statements of ``python_files`` name anywhere
    (inside functions too): what a branch the trace did not run may import."""
    from .reach import absolute_imports
    names = {name for path in python_files for name in absolute_imports(path)}
    return sorted(n for n in names if n.split(".")[0] != "deltafmi" and not n.startswith("_deltafmi"))


def _left_out(name: str, packages: Sequence[str]) -> bool:
    """Whether module ``name`` is one of ``packages`` or inside one."""
    return any(name == package or name.startswith(package + ".") for package in packages)


def traced_modules(fmu: Path, leave_out: Sequence[str] = ()) -> dict[str, Optional[str]]:
    """Modules (name -> file) the FMU's Python side imports: its boot code loads the model in a
    fresh interpreter of this Python, which steps it in CS and evaluates it in ME, then imports what
    the import statements of the FMU's Python files name (a runtime trace alone misses the
    branches that did not run: a lazily imported module, an ``except ImportError`` fallback), but
    for the :data:`HOST_ONLY` packages, and those in ``leave_out``, that the FMU's copy of deltafmi
    names (the model's own files keep every name)."""
    import json
    with tempfile.TemporaryDirectory() as tmp:
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(tmp)
        out = Path(tmp) / "modules.json"
        python = Path(tmp) / "resources" / "python"
        own = sorted((python / "deltafmi").rglob("*.py"))
        sources = sorted(set(python.rglob("*.py")) - set(own))
        sources += sorted((Path(tmp) / "resources" / "model").glob("*.py"))
        unused = (*HOST_ONLY, *leave_out)
        static = static_imports(sources) + [n for n in static_imports(own) if not _left_out(n, unused)]
        env = {**os.environ, "DELTAFMI_STATIC_IMPORTS": json.dumps(sorted(set(static)))}
        result = subprocess.run([sys.executable, "-I", "-S", "-c", _TRACE, f"{tmp}/resources", str(out),
                                 *map(str, _site_dirs())], capture_output=True, text=True, env=env)
        if result.returncode != 0:
            raise BuildError(f"--portable: running {fmu.name} to see what it imports failed:\n{result.stderr[-3000:]}")
        return json.loads(out.read_text())


def bundle_key() -> str:
    """Hash of what a portable bundle is made from beyond the FMU itself: this module, the starter,
    the interpreter and the installed distributions (their names carry their versions)."""
    import hashlib
    digest = hashlib.sha256(Path(__file__).read_bytes() + (NATIVE_DIR / "starter.c").read_bytes())
    digest.update(sys.version.encode() + str(_libpython().stat().st_mtime_ns).encode())
    for site in _site_dirs():
        digest.update(" ".join(sorted(p.name for p in site.glob("*.dist-info"))).encode())
    return digest.hexdigest()


def make_portable(fmu: Path, output: Path, leave_out: Sequence[str] = ()) -> PortableBundle:
    """Write ``output``: the non-portable ``fmu`` plus the interpreter and packages it runs on
    (``leave_out``: see :func:`traced_modules`)."""
    from importlib.util import find_spec
    from ..files import replaced_atomically
    modules = traced_modules(fmu, leave_out)
    spec = find_spec("fmpy")
    sundials = Path(spec.submodule_search_locations[0]) / "sundials" / "x86_64-linux" if spec else None
    with zipfile.ZipFile(fmu) as archive:  # the runtime imports its solver only when a component integrates
        needs_sundials = _integrates(archive)
    bundle = portable_bundle(modules, needs_sundials=needs_sundials, sundials_dir=sundials)
    replaced = {"resources/python.cfg", "documentation/index.html", "resources/README.txt"}
    large = [(path, name) for path, name in bundle.files if path.stat().st_size >= _LARGE_MEMBER]
    in_large = set(large)
    with zipfile.ZipFile(fmu) as source, replaced_atomically(output) as tmp:
        version = _fmi_version(source.read("modelDescription.xml"))
        shutil.copyfile(_compressed_members(large), tmp)
        with zipfile.ZipFile(tmp, "a", zipfile.ZIP_DEFLATED) as archive:
            for item in source.infolist():
                if item.filename not in replaced:
                    archive.writestr(item, source.read(item.filename))
            archive.writestr("resources/python.cfg", bundle.config)
            for path, name in bundle.files:
                if (path, name) not in in_large:
                    archive.write(path, name)
            for data, name in bundle.data:
                archive.writestr(name, data)
            for path, name in bundle.licenses:
                archive.write(path, f"documentation/licenses/{name}")
            archive.writestr("resources/README.txt", portable_readme(bundle, version))
            archive.writestr("documentation/index.html", _with_portable_section(
                source.read("documentation/index.html").decode(), bundle, version))
    return bundle


def _compressed_members(files: list[tuple[Path, str]]) -> Path:
    """A zip archive of ``files`` (file on disk, archive name), deflated as the FMU's other members
    are, from the build cache: the large shared libraries (numpy's, the interpreter) are most of a
    bundle and of the time its compression takes, and every portable FMU of the same packages
    carries the same ones. A portable FMU starts as a copy of it."""
    import hashlib
    digest = hashlib.sha256()
    for path, name in files:
        stat = path.stat()
        digest.update(f"{name}\0{path.resolve()}\0{stat.st_size}\0{stat.st_mtime_ns}\0".encode("utf-8", "surrogateescape"))
    target = cache_dir() / "portable" / "members" / digest.hexdigest()[:24]

    def build(tmp: str) -> None:
        with zipfile.ZipFile(Path(tmp) / "members.zip", "w", zipfile.ZIP_DEFLATED) as archive:
            for path, name in files:
                archive.write(path, name)
    build_into(target, build)
    return target / "members.zip"


def _integrates(archive: zipfile.ZipFile) -> bool:
    """Whether the FMU's Python side, or that of an FMU of ours it carries in resources/ (a scenario
    exported as one FMU runs them in its interpreter), integrates with CVODE."""
    if f"{PYTHON_DIR}/deltafmi/runtime/cvode.py" in archive.namelist():
        return True
    for name in archive.namelist():
        if name.startswith("resources/") and name.endswith(".fmu"):
            with archive.open(name) as nested_file, zipfile.ZipFile(io.BytesIO(nested_file.read())) as nested:
                if _integrates(nested):
                    return True
    return False


def _fmi_version(model_description: bytes) -> str:
    """The fmiVersion attribute of a modelDescription.xml ("2.0", "3.0")."""
    import xml.etree.ElementTree as ET
    return ET.fromstring(model_description).get("fmiVersion", "2.0")


def portable_readme(bundle: PortableBundle, fmi_version: str = "2.0") -> str:
    glibc = ".".join(map(str, bundle.glibc_floor))
    return (f"A portable deltafmi FMU (FMI {fmi_version}, Model Exchange and Co-Simulation).\n\n"
            f"It carries CPython {bundle.python_version} (python/lib), the part of the standard library and "
            f"the packages its model imports, and the shared libraries they need beyond glibc. It runs on "
            f"Linux x86_64 with glibc {glibc} or newer, with no Python installed. In a host that already runs "
            f"Python (fmpy), it uses the host's interpreter, which needs numpy.\n"
            f"Licences of everything bundled: documentation/licenses/.\n")


def _with_portable_section(page: str, bundle: PortableBundle, fmi_version: str) -> str:
    import html
    section = f"<h2>Requirements (portable FMU)</h2><p>{html.escape(portable_readme(bundle, fmi_version))}</p>"
    return re.sub(r"<h2>Requirements</h2>.*</body>", lambda _: section + "</body>", page, flags=re.S)
