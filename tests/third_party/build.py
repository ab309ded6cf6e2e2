"""Build the third-party-style C FMUs of tests/third_party into real .fmu archives.

Each model is a folder with ``model.c`` and ``modelDescription.xml`` (and ``resources/`` when it
reads files); ``plumbing.c`` supplies every fmi2 function. The binary is compiled with ``cc``
against the FMI 2.0 headers shipped in deltafmi/export/native, exports only the ``fmi2*``
functions and does not link anything but libc and libm: no Python anywhere.
"""
from __future__ import annotations

import subprocess
import zipfile
from pathlib import Path
from typing import Dict

HERE = Path(__file__).resolve().parent
HEADERS = HERE.parents[1] / "deltafmi" / "export" / "native"
MODELS = ("AllTypes", "Ticker", "LookupTable", "BouncingBall")


def build_fmu(model: str, out_dir: Path) -> Path:
    """Compile ``model`` and pack ``out_dir/<model>.fmu`` (both ME and CS, one binary)."""
    source = HERE / model
    out_dir.mkdir(parents=True, exist_ok=True)
    binary = out_dir / f"{model}.so"
    compiled = subprocess.run(["cc", "-shared", "-fPIC", "-O2", "-std=gnu11", "-Wall", "-Wextra", "-Werror",
                               "-fvisibility=hidden", f"-I{HEADERS}", f"-I{HERE}",
                               str(HERE / "plumbing.c"), str(source / "model.c"), "-o", str(binary), "-lm"],
                              capture_output=True, text=True)
    if compiled.returncode:
        raise RuntimeError(f"compiling {model} failed:\n{compiled.stderr}")
    fmu = out_dir / f"{model}.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.write(source / "modelDescription.xml", "modelDescription.xml")
        archive.write(binary, f"binaries/linux64/{model}.so")
        for path in sorted((source / "resources").rglob("*")) if (source / "resources").is_dir() else []:
            if path.is_file():
                archive.write(path, f"resources/{path.relative_to(source / 'resources').as_posix()}")
        for path in (HERE / "plumbing.h", HERE / "plumbing.c", source / "model.c"):
            archive.write(path, f"sources/{path.name}")
    return fmu


def build_all(out_dir: Path) -> Dict[str, Path]:
    """Every model of tests/third_party as ``{model: .fmu path}``."""
    return {model: build_fmu(model, out_dir) for model in MODELS}
