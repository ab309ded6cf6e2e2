"""Portable FMUs (``deltafmi build --portable``) in a C host on a machine with no Python, and the one
message of an FMU that cannot start.

"No Python" is made real: tests/c_host/hide_python.sh, in a private mount namespace, covers every
Python installation, the checkout, the build cache and the running virtual environment; the C host
and the unpacked FMUs stay visible in a temporary folder. There a portable FMU must give the same
numbers as on this machine. Then what its binaries link (ldd), that it needs no execute bit, its
glibc floor, its size and licences; last, the failures of FMUs that cannot start.
"""
from __future__ import annotations

import os
import re
import shutil
import site
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest

from conftest import FMU_SRC, ROOT, clean_env, unzip
from host_loops import host_rows, me_env, run_c_host
from deltafmi.toolchain import cache_dir
from deltafmi.builder.packager import build_cached

HIDE = ROOT / "tests" / "c_host" / "hide_python.sh"
#: the libraries of glibc itself: the only ones a portable FMU may take from the machine
GLIBC = {"libc.so.6", "libm.so.6", "libdl.so.2", "libpthread.so.0", "librt.so.1", "libutil.so.1",
         "ld-linux-x86-64.so.2", "linux-vdso.so.1"}
#: model -> (source, variables printed, (stop, step) in CS, (stop, step) in ME); the Oscillator hits
#: its wall within 2 s (state events), the robot falls under gravity with its loops closed
MODELS = {"Oscillator": ("oscillator.py", ["x", "v"], (2.0, 1e-2), (2.0, 1e-3)),
          "DeltaRobot": ("delta_robot.py", ["q[1]", "q[2]", "q[3]", "z[1]", "z[2]", "z[3]"], (0.2, 1e-2), (0.1, 1e-3))}
PORTABLE = {"Oscillator": "portable_oscillator_fmu", "DeltaRobot": "portable_delta_robot_fmu"}
_PROBE = r"""
#include <dlfcn.h>
#include <stdio.h>
int main(int argc, char **argv) {
    for (int i = 1; i < argc; i++) printf("%s %s\n", dlopen(argv[i], RTLD_NOW) ? "loaded" : "missing", argv[i]);
    return 0;
}
"""


def hidden_paths() -> list[Path]:
    """What a machine with no Python lacks beyond the fixed list of hide_python.sh: this checkout,
    deltafmi's build cache, the running virtual environment, its interpreter and site-packages
    (never a system folder such as /usr that holds them: the script hides their parts there)."""
    system = {Path(p) for p in ("/", "/usr", "/usr/local", "/opt", "/root", "/home", "/tmp")} | {Path.home()}
    libpython = Path(sysconfig.get_config_var("LIBDIR") or "/", sysconfig.get_config_var("INSTSONAME") or "")
    candidates = {ROOT, cache_dir(), Path(sys.prefix), Path(sys.base_prefix), Path(sys.exec_prefix),
                  Path(sys.base_exec_prefix), Path(sys.executable), libpython, *map(Path, site.getsitepackages()),
                  Path(site.getusersitepackages())}
    return sorted({p.resolve() for p in candidates if p.exists() and p.resolve() not in system})


def elf_files(root: Path) -> list[Path]:
    out = []
    for folder, _, names in os.walk(root):
        for name in names:
            path = Path(folder) / name
            with open(path, "rb") as f:
                if f.read(4) == b"\x7fELF":
                    out.append(path)
    return sorted(out)


def elf_kind(data: bytes) -> str:
    """'shared object', or 'executable' for ET_EXEC or an ELF that names a program interpreter
    (PT_INTERP: a PIE program is ET_DYN too)."""
    e_type = int.from_bytes(data[16:18], "little")
    phoff, phentsize, phnum = (int.from_bytes(data[32:40], "little"), int.from_bytes(data[54:56], "little"),
                               int.from_bytes(data[56:58], "little"))
    interpreter = any(int.from_bytes(data[phoff + i * phentsize:phoff + i * phentsize + 4], "little") == 3
                      for i in range(phnum))
    return "shared object" if e_type == 3 and not interpreter else "executable"


def glibc_needs(binary: Path) -> set[tuple[int, ...]]:
    """GLIBC_x.y versions in ``binary``'s symbol version sections (readelf -V)."""
    text = subprocess.run(["readelf", "-V", "-W", str(binary)], capture_output=True, text=True, check=True).stdout
    return {tuple(map(int, v.split("."))) for v in re.findall(r"Name: GLIBC_([0-9][0-9.]*)", text)}


def read_cfg(directory: Path) -> dict:
    lines = (directory / "resources" / "python.cfg").read_text().splitlines()
    return dict(line.split("=", 1) for line in lines if "=" in line)


def write_cfg(directory: Path, **changes: str) -> None:
    cfg = {**read_cfg(directory), **changes}
    (directory / "resources" / "python.cfg").write_text("".join(f"{k}={v}\n" for k, v in cfg.items()))


def host_args(directory: Path, model: str, mode: str) -> tuple[list[str], dict]:
    """The C host's arguments after its path (``<dir> <id> <guid> <mode> <stop> <step> <vr>...``)
    and its extra environment, for ``model`` in ``mode``."""
    md = fmpy.read_model_description(str(directory))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    _, names, cs, me = MODELS[model]
    stop, step = cs if mode == "cs" else me
    args = [str(directory), model, md.guid, mode, str(stop), str(step), *(str(vr[n]) for n in names)]
    return args, me_env(directory) if mode == "me" else {}


def start_failure(host: Path, directory: Path, **env: str) -> str:
    """The one logger message of an fmi2Instantiate that returns NULL. The host then exits with 4
    (not a signal: no crash) and nothing else may appear: no stdout, no stderr but the logger's
    line and the host's own 'fmi2Instantiate failed'."""
    md = fmpy.read_model_description(str(directory))
    identifier = md.coSimulation.modelIdentifier
    out = subprocess.run([str(host), str(directory), identifier, md.guid, "cs", "0.1", "0.01", "0"],
                         capture_output=True, text=True, env=clean_env(**env), timeout=600)
    assert out.returncode == 4, f"host exited with {out.returncode}:\n{out.stdout[-2000:]}\n{out.stderr[-3000:]}"
    assert out.stdout == ""
    lines = out.stderr.splitlines()
    assert len(lines) == 2 and lines[1] == "fmi2Instantiate failed", out.stderr
    logged = re.fullmatch(r"\[host\|3\|\w+\] (.+)", lines[0])
    assert logged, lines[0]
    return logged.group(1)


def assert_advice(message: str, source: str = "oscillator.py") -> None:
    """A start-up message names the override and how to make an FMU that needs no Python."""
    assert "DELTAFMI_PYTHON" in message, message
    assert f"deltafmi build {source} --portable" in message, message


@pytest.fixture(scope="module")
def workspace(tmp_path_factory, c_host) -> Path:
    """A folder for the unpacked FMUs that the namespace leaves visible (as the host binary)."""
    path = tmp_path_factory.mktemp("portable")
    for visible in (path, c_host):
        covered = [p for p in hidden_paths() if p == visible.resolve() or p in visible.resolve().parents]
        assert not covered, f"{visible} lies in {covered[0]}, which the hidden-Python host hides: use --basetemp"
    return path


@pytest.fixture(scope="module")
def unpacked(request, workspace):
    """``unpacked(model, portable=True) -> Path``: the FMU extracted once per module."""
    done: dict = {}

    def get(model: str, portable: bool = True) -> Path:
        if (model, portable) not in done:
            fmu = request.getfixturevalue(PORTABLE[model]) if portable else build_cached(FMU_SRC / MODELS[model][0])
            done[model, portable] = unzip(fmu, workspace / f"{model}-{'portable' if portable else 'plain'}")
        return done[model, portable]

    return get


@pytest.fixture(scope="module")
def no_python() -> list[str]:
    """The command prefix that runs a command where no Python can be found."""
    if not shutil.which("unshare"):
        pytest.skip("no `unshare` (util-linux): the hidden-Python host needs a mount namespace")
    reasons = []
    for unshare in (["unshare", "-m"], ["unshare", "-r", "-m"]):  # root, else a user namespace
        probe = subprocess.run([*unshare, "true"], capture_output=True, text=True)
        if probe.returncode == 0:
            return [*unshare, "bash", str(HIDE), *map(str, hidden_paths()), "--"]
        reasons.append(f"`{' '.join(unshare)}`: {probe.stderr.strip()}")
    pytest.skip("cannot make a mount namespace to hide Python (needs root or unprivileged user namespaces): "
                + "; ".join(reasons))


@pytest.fixture(scope="module")
def dlopen_probe(workspace) -> Path:
    exe = workspace / "dlopen_probe"
    subprocess.run(["cc", "-x", "c", "-", "-o", str(exe), "-ldl"], input=_PROBE, text=True, check=True)
    return exe


def test_the_namespace_hides_every_python(no_python, dlopen_probe, unpacked, c_host):
    """Inside, no interpreter runs, no libpython loads, the checkout is empty; outside they do."""
    env = clean_env(PATH="/usr/local/bin:/usr/bin:/bin")
    libpython = Path(sysconfig.get_config_var("LIBDIR"), sysconfig.get_config_var("INSTSONAME"))
    names = [str(libpython), "libpython3.so", *(f"libpython3.{minor}.so.1.0" for minor in range(8, 16))]
    outside = subprocess.run([str(dlopen_probe), *names], capture_output=True, text=True, env=env, check=True)
    assert f"loaded {libpython}" in outside.stdout  # the probe can see what it looks for
    inside = subprocess.run([*no_python, str(dlopen_probe), *names], capture_output=True, text=True, env=env)
    assert inside.returncode == 0, inside.stderr
    assert "loaded" not in inside.stdout and inside.stdout.count("missing") == len(names), inside.stdout
    for python in (sys.executable, os.path.realpath(sys.executable)):
        assert subprocess.run([python, "-c", "print(42)"], capture_output=True, text=True, env=env).stdout == "42\n"
    for python in ("python3", "python", sys.executable, os.path.realpath(sys.executable)):
        ran = subprocess.run([*no_python, python, "-c", "print(42)"], capture_output=True, text=True, env=env)
        assert ran.returncode != 0 and "42" not in ran.stdout, f"{python} ran in the namespace"
    # the checkout, the build cache, the virtual environment and its site-packages are empty there
    folders = [str(p) for p in hidden_paths() if p.is_dir()]
    assert str(ROOT) in folders and str(cache_dir().resolve()) in folders
    listing = subprocess.run([*no_python, "sh", "-c", 'for d; do [ ! -d "$d" ] || ls -A "$d"; done', "sh", *folders],
                             capture_output=True, text=True, env=env)
    assert listing.returncode == 0 and listing.stdout == "", listing.stdout[:2000]
    # the FMU that needs this machine's Python finds none there
    plain = unpacked("Oscillator", portable=False)
    args, _ = host_args(plain, "Oscillator", "cs")
    failed = subprocess.run([*no_python, str(c_host), *args], capture_output=True, text=True, env=clean_env())
    assert failed.returncode == 4 and "does not exist" in failed.stderr, failed.stderr


@pytest.mark.parametrize("mode", ["cs", "me"])
@pytest.mark.parametrize("model", list(MODELS))
def test_portable_fmu_without_python_equals_this_machine(model, mode, no_python, unpacked, c_host):
    """The portable FMU where no Python exists == the same FMU in the C host here == the
    non-portable FMU (which runs on this machine's Python), to 1e-9."""
    portable = unpacked(model)
    args, extra = host_args(portable, model, mode)
    hidden = subprocess.run([*no_python, str(c_host), *args], capture_output=True, text=True,
                            env=clean_env(**extra), timeout=300)
    assert hidden.returncode == 0, f"exit {hidden.returncode}:\n{hidden.stderr[-3000:]}"
    printed = [line for line in hidden.stderr.splitlines() if not line.startswith("[host|")]
    assert not printed, f"the FMU printed outside the FMI logger: {printed[:5]}"
    rows = host_rows(hidden.stdout)
    stop, step = MODELS[model][2 if mode == "cs" else 3]
    assert rows.shape == (round(stop / step) + 1, 1 + len(MODELS[model][1]))
    assert np.ptp(rows[:, 1]) > 1e-3  # it moved: not a run of start values
    here = host_rows(run_c_host(c_host, portable, mode, *args[4:], env=extra).stdout)
    plain = host_rows(run_c_host(c_host, unpacked(model, portable=False), mode, *args[4:], env=extra).stdout)
    np.testing.assert_allclose(rows, here, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rows, plain, rtol=0, atol=1e-9)


@pytest.mark.parametrize("model", list(MODELS))
def test_bundled_binaries_need_only_the_bundle_and_glibc(model, unpacked):
    """ldd of every ELF in the FMU, with the bundle's library folders on the search path (the
    loader opens python/lib's libraries by path before anything else, and wheels find their .libs
    by RPATH): every dependency is inside the FMU or one of glibc's libraries. A name ldd does not
    find passes only if a bundled library carries it as its SONAME (fmpy's SUNDIALS libraries need
    libsundials_core.so.7, which its loader opens as sundials_core.so first; the dynamic linker
    matches a needed name against the SONAME of what is already loaded)."""
    root = unpacked(model)
    binaries = elf_files(root)
    folders = sorted({str(p.parent) for p in binaries})
    sonames = set()
    for binary in binaries:
        dynamic = subprocess.run(["readelf", "-d", "-W", str(binary)], capture_output=True, text=True).stdout
        sonames.update(re.findall(r"\(SONAME\)\s+Library soname: \[([^\]]+)\]", dynamic))
    outsiders = []
    for binary in binaries:
        out = subprocess.run(["ldd", str(binary)], capture_output=True, text=True,
                             env=clean_env(LD_LIBRARY_PATH=":".join(folders))).stdout
        for line in out.splitlines():
            line = line.strip()
            arrow = re.fullmatch(r"(\S+) => (.+?)(?: \(0x[0-9a-f]+\))?", line)
            if arrow:
                name, target = arrow.groups()
                inside = target != "not found" and root in Path(target).resolve().parents
                if inside or name in GLIBC or (target == "not found" and name in sonames):
                    continue
                outsiders.append(f"{binary.relative_to(root)}: {name} => {target}")
            elif line.startswith("/") and Path(line.split()[0]).name not in GLIBC:
                outsiders.append(f"{binary.relative_to(root)}: {line}")
    assert len(binaries) > 20  # libpython, the starter, lib-dynload, numpy, ...
    assert not outsiders, "outside the FMU and glibc:\n" + "\n".join(outsiders)


@pytest.mark.parametrize("model", list(MODELS))
def test_runs_without_execute_bits_and_ships_no_program(model, request, c_host, tmp_path):
    """Zip importers drop file modes. Nothing in a portable FMU needs an execute bit: dlopen maps
    a shared object whatever its mode (only a noexec mount stops it), and the FMU ships no program
    to exec: every ELF in the archive is a shared object (ET_DYN without a program interpreter)."""
    fmu = request.getfixturevalue(PORTABLE[model])
    with zipfile.ZipFile(fmu) as archive:
        programs = [info.filename for info in archive.infolist()
                    if archive.open(info).read(4) == b"\x7fELF" and elf_kind(archive.read(info)) == "executable"]
    directory = unzip(fmu, tmp_path / "fmu")
    for folder, _, names in os.walk(directory):
        for name in names:
            path = Path(folder) / name
            path.chmod(path.stat().st_mode & ~0o111)
    assert not any(os.stat(p).st_mode & 0o111 for p in elf_files(directory))
    args, extra = host_args(directory, model, "cs")
    rows = host_rows(run_c_host(c_host, directory, "cs", *args[4:], env=extra).stdout)
    assert np.ptp(rows[:, 1]) > 1e-3
    assert not programs, f"executables in the FMU: {programs}"


@pytest.mark.parametrize("model", list(MODELS))
def test_glibc_floor_is_the_newest_glibc_symbol_bundled(model, unpacked):
    """python.cfg's glibc= is the newest GLIBC_x.y symbol version any ELF in the FMU needs, this
    machine has it, and the FMU's documentation states it."""
    root = unpacked(model)
    newest = max(v for binary in elf_files(root) for v in glibc_needs(binary))
    floor = read_cfg(root)["glibc"]
    assert floor == ".".join(map(str, newest))
    machine = os.confstr("CS_GNU_LIBC_VERSION").split()[1]
    assert tuple(map(int, machine.split("."))) >= newest
    assert f"glibc {floor}" in (root / "documentation" / "index.html").read_text()


def test_a_glibc_older_than_the_floor_is_one_message(portable_oscillator_fmu, c_host, tmp_path):
    directory = unzip(portable_oscillator_fmu, tmp_path / "fmu")
    write_cfg(directory, glibc="9.99")
    message = start_failure(c_host, directory)
    machine = os.confstr("CS_GNU_LIBC_VERSION").split()[1]
    assert "glibc 9.99" in message and f"glibc {machine}" in message, message
    assert "deltafmi build oscillator.py --portable" in message, message


def test_portable_delta_robot_is_at_most_40_mb(portable_delta_robot_fmu):
    size = portable_delta_robot_fmu.stat().st_size
    with zipfile.ZipFile(portable_delta_robot_fmu) as archive:
        parts: dict = {}
        for info in archive.infolist():
            part = "/".join(info.filename.split("/")[:4])
            parts[part] = parts.get(part, 0) + info.compress_size
    largest = ", ".join(f"{name} {n / 1e6:.1f}" for name, n in sorted(parts.items(), key=lambda x: -x[1])[:8])
    assert size <= 40e6, f"portable DeltaRobot is {size / 1e6:.2f} MB zipped; largest parts (MB): {largest}"


@pytest.mark.parametrize("model", list(MODELS))
def test_licences_of_everything_bundled(model, request):
    """documentation/licenses/ has CPython's licence, numpy's, SUNDIALS' when its libraries are
    bundled, one per shared library taken from the system (python/lib), and, for each library a
    wheel bundles (numpy.libs, ...), a licence of that wheel that names it."""
    with zipfile.ZipFile(request.getfixturevalue(PORTABLE[model])) as archive:
        names = archive.namelist()
        licences = {n: archive.read(n).decode("utf-8", "replace") for n in names
                    if n.startswith("documentation/licenses/") and not n.endswith("/")}

    def texts(prefix: str = "") -> list[str]:
        return [text for name, text in licences.items() if name.startswith("documentation/licenses/" + prefix)]

    missing = []
    if not any("PYTHON SOFTWARE FOUNDATION LICENSE" in t for t in texts("CPython/")):
        missing.append("CPython")
    if not any("NumPy Developers" in t for t in texts("numpy/")):
        missing.append("numpy")
    if any("sundials" in n.lower() and n.endswith(".so") for n in names) and \
            not any("SUNDIALS" in t and "Lawrence Livermore" in t for t in texts()):
        missing.append("SUNDIALS")
    system = [n.rsplit("/", 1)[1] for n in names if re.fullmatch(r"resources/python/lib/lib[^/]+\.so[.0-9]*", n)]
    for library in system:
        if not library.startswith("libpython") and not texts(library + "/"):
            missing.append(library)
    for name in names:
        wheel_library = re.fullmatch(r"resources/python/site-packages/(\w+)\.libs/(lib[^/]+)", name)
        if wheel_library:
            package, library = wheel_library.groups()
            words = {w for w in re.findall(r"[a-z]+", library[3:].lower()) if len(w) >= 4} - {package, "scipy"}
            if not any(w in t.lower() for w in words for t in texts(package + "/")):
                missing.append(f"{package}.libs/{library}")
    assert system and not missing, f"no licence in documentation/licenses/ for: {missing}"


# --- FMUs that cannot start: NULL from fmi2Instantiate, one logger message, nothing else -----------

def other_python() -> tuple[str, Path, str]:
    """(interpreter, its shared libpython, 'X.Y') of the newest installed CPython >= 3.10 whose
    version differs from the builder's; skips when this machine has none."""
    script = ("import sys, sysconfig; print(f'{sys.version_info[0]}.{sys.version_info[1]}'); "
              "print(sysconfig.get_config_var('LIBDIR') or ''); print(sysconfig.get_config_var('INSTSONAME') or '')")
    mine = f"{sys.version_info.major}.{sys.version_info.minor}"
    roots = [Path(os.environ.get("PYENV_ROOT", Path.home() / ".pyenv")) / "versions"]
    candidates = [p for r in roots for p in r.glob("*/bin/python3")]
    candidates += sorted(p for d in ("/usr/bin", "/usr/local/bin") for p in Path(d).glob("python3.*")
                         if re.fullmatch(r"python3\.\d+", p.name))
    found = []
    for python in candidates:
        out = subprocess.run([str(python), "-I", "-c", script], capture_output=True, text=True)
        if out.returncode != 0:
            continue
        version, libdir, soname = out.stdout.split("\n")[:3]
        library, key = Path(libdir, soname), tuple(map(int, version.split(".")))
        if version != mine and key >= (3, 10) and soname and library.is_file():
            found.append((key, str(python), library, version))
    if found:
        return max(found)[1:]
    pytest.skip(f"no CPython other than {mine} with a shared libpython on this machine")


@pytest.fixture
def plain_oscillator(unpacked, tmp_path) -> Path:
    """A copy of the non-portable Oscillator, free to edit."""
    return Path(shutil.copytree(unpacked("Oscillator", portable=False), tmp_path / "fmu"))


def test_python_library_gone(plain_oscillator, c_host):
    missing = "/nonexistent/python/lib/libpython3.11.so.1.0"
    write_cfg(plain_oscillator, library=missing)
    message = start_failure(c_host, plain_oscillator)
    assert missing in message
    assert_advice(message)


def test_python_interpreter_gone(plain_oscillator, c_host):
    """A deleted virtual environment: its libpython may still exist, its interpreter does not."""
    missing = "/nonexistent/venv/bin/python"
    write_cfg(plain_oscillator, executable=missing)
    message = start_failure(c_host, plain_oscillator)
    assert missing in message
    assert_advice(message)


def test_recorded_python_replaced_by_another_version(plain_oscillator, c_host):
    """The library the FMU recorded is now another version (an upgrade in place)."""
    _, library, version = other_python()
    write_cfg(plain_oscillator, library=str(library))
    message = start_failure(c_host, plain_oscillator)
    built = read_cfg(plain_oscillator)["version"]
    assert f"Python {version}" in message and f"Python {built}" in message, message
    assert_advice(message)


def test_libpython_override_of_another_version(unpacked, c_host):
    """DELTAFMI_LIBPYTHON at another version's libpython, the FMU built here: the message says
    which version it found and which the FMU (and its recorded interpreter) was built for."""
    _, library, version = other_python()
    directory = unpacked("Oscillator", portable=False)
    message = start_failure(c_host, directory, DELTAFMI_LIBPYTHON=str(library))
    built = read_cfg(directory)["version"]
    assert str(library) in message and f"Python {version}" in message and f"Python {built}" in message, message
    assert_advice(message)


def test_python_without_numpy(unpacked, c_host, tmp_path):
    """DELTAFMI_PYTHON and DELTAFMI_LIBPYTHON at a Python (a fresh virtual environment: surely
    no numpy) that lacks a package the model imports."""
    python, library, version = other_python()
    venv = tmp_path / "venv"
    subprocess.run([python, "-m", "venv", "--without-pip", str(venv)], check=True, capture_output=True)
    message = start_failure(c_host, unpacked("Oscillator", portable=False),
                            DELTAFMI_PYTHON=str(venv / "bin" / "python"), DELTAFMI_LIBPYTHON=str(library))
    assert "'numpy'" in message and str(venv / "bin" / "python") in message and f"Python {version}" in message, message
    assert_advice(message)
