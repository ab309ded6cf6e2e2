"""Build the third-party-style C FMUs of tests/third_party into real .fmu archives.

Each model is a folder with ``model.c`` and ``modelDescription.xml`` (and ``resources/`` when it
reads files). The binary is compiled with ``cc`` from the model, ``common.c`` and the front end of
the model's FMI version (its modelDescription's ``fmiVersion``): ``plumbing.c`` supplies every fmi2
function, ``plumbing3.c`` every fmi3 function. It is compiled against the FMI headers shipped in
deltafmi/runtime/native, exports only the ``fmi2*`` (``fmi3*``) functions and links nothing but libc
and libm: no Python anywhere (compiled once per build cache, ``$DELTAFMI_CACHE``, for all the modules
that build the model). FMI 2.0 binaries go to ``binaries/linux64``, FMI 3.0 binaries to
``binaries/x86_64-linux``.

    build_fmu("BouncingBall3", out_dir)   # -> out_dir/BouncingBall3.fmu (FMI 3.0, ME + CS)
"""
from __future__ import annotations

import hashlib
import re
import shutil
import subprocess
import zipfile
from pathlib import Path
from typing import Dict, Optional, Tuple

HERE = Path(__file__).resolve().parent
HEADERS = HERE.parents[1] / "deltafmi" / "runtime" / "native"
MODELS = ("AllTypes", "Ticker", "LookupTable", "BouncingBall", "Oscillator")
MODELS3 = ("AllTypes3", "StateSpace3", "BouncingBall3", "Stopper3", "Table3", "Sampler3")
FRONT_END = {2: "plumbing.c", 3: "plumbing3.c"}
PLATFORM = {2: "linux64", 3: "x86_64-linux"}


def version_of(model: str) -> int:
    """The major FMI version (2 or 3) of ``model``'s modelDescription.xml."""
    text = (HERE / model / "modelDescription.xml").read_text()
    found = re.search(r'fmiVersion="(\d)', text)
    if found is None or int(found.group(1)) not in FRONT_END:
        raise ValueError(f"{model}/modelDescription.xml: no fmiVersion 2.0 or 3.0")
    return int(found.group(1))


def build_fmu(model: str, out_dir: Path, fmi_version: Optional[int] = None) -> Path:
    """Compile ``model`` and pack ``out_dir/<model>.fmu`` (both ME and CS, one binary).

    The FMI version is the model's own; ``fmi_version`` (2 or 3), when given, is checked."""
    version = version_of(model)
    if fmi_version is not None and fmi_version != version:
        raise ValueError(f"{model} is an FMI {version}.0 model, not FMI {fmi_version}.0")
    source = HERE / model
    out_dir.mkdir(parents=True, exist_ok=True)
    binary = out_dir / f"{model}.so"
    sources = [HERE / "common.c", HERE / FRONT_END[version], source / "model.c"]
    shutil.copyfile(_compiled(model, sources), binary)
    fmu = out_dir / f"{model}.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.write(source / "modelDescription.xml", "modelDescription.xml")
        archive.write(binary, f"binaries/{PLATFORM[version]}/{model}.so")
        for path in sorted((source / "resources").rglob("*")) if (source / "resources").is_dir() else []:
            if path.is_file():
                archive.write(path, f"resources/{path.relative_to(source / 'resources').as_posix()}")
        for path in (HERE / "plumbing.h", *sources):
            archive.write(path, f"sources/{path.name}")
        model_c = (source / "model.c").read_text()
        for path in sorted((HERE / "shared").glob("*.h")):
            if f'"shared/{path.name}"' in model_c:
                archive.write(path, f"sources/shared/{path.name}")
    return fmu


def _compiled(model: str, sources: list) -> Path:
    """``model``'s binary, compiled once per build cache (``$DELTAFMI_CACHE``) and C source: the
    suite's modules build the same models, each into folders of their own."""
    from deltafmi.toolchain import build_into, cache_dir

    command = ["cc", "-shared", "-fPIC", "-O2", "-std=gnu11", "-Wall", "-Wextra", "-Werror", "-fvisibility=hidden",
               f"-I{HEADERS}", f"-I{HERE}"]
    key = hashlib.sha256(" ".join(command).encode())
    for path in [*sources, *sorted(HEADERS.glob("*.h")), *sorted(HERE.glob("*.h")), *sorted(HERE.glob("shared/*.h"))]:
        key.update(path.name.encode() + b"\0" + path.read_bytes())
    folder = cache_dir() / "test-c-fmus" / f"{model}-{key.hexdigest()[:16]}"

    def compile_into(tmp: str) -> None:
        compiled = subprocess.run([*command, *map(str, sources), "-o", f"{tmp}/{model}.so", "-lm"],
                                  capture_output=True, text=True)
        if compiled.returncode:
            raise RuntimeError(f"compiling {model} failed:\n{compiled.stderr}")

    if not folder.exists():
        build_into(folder, compile_into)
    return folder / f"{model}.so"


def build_all(out_dir: Path, models: Tuple[str, ...] = MODELS) -> Dict[str, Path]:
    """Every FMI 2.0 model of tests/third_party (or ``models``) as ``{model: .fmu path}``."""
    return {model: build_fmu(model, out_dir) for model in models}


def build_all3(out_dir: Path) -> Dict[str, Path]:
    """Every FMI 3.0 model of tests/third_party as ``{model: .fmu path}``."""
    return build_all(out_dir, MODELS3)
