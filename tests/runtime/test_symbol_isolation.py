"""Our FMUs inside a host that has its own SUNDIALS, and what their binaries export.

The hostile host is tests/c_host/host.c linked against Debian's SUNDIALS 6 (libsundials-dev), which
it uses before loading the FMU: every SUNDIALS symbol is then in the process's global scope. Before
the FMU's solver was loaded with RTLD_DEEPBIND, each Co-Simulation FMU with states died there in
its first fmi2DoStep (fmpy's CVODE 7 calling the host's CVODE 6 internals). Every FMU of fmu_src/
runs there in both interfaces and gives what the same algorithm gives through fmpy.
"""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import fmpy
import numpy as np
import pytest

from conftest import MODEL_FILES, NATIVE, ROOT, unzip
from deltafmi.builder.compiler import exported_symbols
from host_loops import co_simulation, host_rows, me_env, model_exchange_euler, run_c_host, shared_libraries

FMU_SOURCES = MODEL_FILES
CS_STOP, CS_STEP = 0.6, 1e-3
ME_STOP, ME_STEP = 0.1, 1e-4


@pytest.fixture(scope="session")
def hostile_host(tmp_path_factory) -> Path:
    """The C host linked against, and warmed up with, Debian's SUNDIALS."""
    exe = tmp_path_factory.mktemp("hostile_host") / "host"
    build = subprocess.run(
        ["cc", "-O2", "-Wall", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "host.c"),
         str(ROOT / "tests" / "c_host" / "sundials_preload.c"), "-o", str(exe), "-ldl", "-lm",
         "-lsundials_cvode", "-lsundials_nvecserial", "-lsundials_sunmatrixdense", "-lsundials_sunlinsoldense"],
        capture_output=True, text=True)
    if build.returncode != 0:
        message = f"cannot build the hostile host (apt-get install libsundials-dev):\n{build.stderr[-2000:]}"
        if os.environ.get("CI"):
            pytest.fail(message)  # .ci/run installs it: in CI this test must run
        pytest.skip(message)
    return exe


@pytest.fixture(scope="module")
def extracted(build_fmu_from_src, tmp_path_factory):
    """``extracted(source) -> directory`` of the unzipped FMU."""
    cache: dict[str, Path] = {}

    def get(source: str) -> Path:
        if source not in cache:
            cache[source] = unzip(build_fmu_from_src(source), tmp_path_factory.mktemp(Path(source).stem))
        return cache[source]

    return get


def _recorded(directory: Path) -> list[int]:
    """Value references of the continuous states and the Real outputs."""
    md = fmpy.read_model_description(str(directory))
    states = [unknown.variable.derivative.valueReference for unknown in md.derivatives]
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    return list(dict.fromkeys(states + outputs))


@pytest.mark.parametrize("source", FMU_SOURCES)
def test_co_simulation_in_a_host_with_its_own_sundials(source, hostile_host, extracted):
    directory = extracted(source)
    vrs = _recorded(directory)
    out = run_c_host(hostile_host, directory, "cs", CS_STOP, CS_STEP, *vrs)
    assert "host SUNDIALS 6." in out.stderr  # the host did use its own SUNDIALS first
    rows = host_rows(out.stdout)
    expected = co_simulation(directory, CS_STOP, CS_STEP, vrs)
    assert rows.shape == expected.shape
    assert np.all(np.isfinite(rows))
    np.testing.assert_allclose(rows, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("source", FMU_SOURCES)
def test_model_exchange_in_a_host_with_its_own_sundials(source, hostile_host, extracted):
    directory = extracted(source)
    vrs = _recorded(directory)
    out = run_c_host(hostile_host, directory, "me", ME_STOP, ME_STEP, *vrs, env=me_env(directory))
    rows = host_rows(out.stdout)
    expected = model_exchange_euler(directory, ME_STOP, ME_STEP, vrs)
    assert rows.shape == expected.shape
    assert np.all(np.isfinite(rows))
    np.testing.assert_allclose(rows, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("source", FMU_SOURCES)
def test_binaries_export_only_what_their_loader_needs(source, extracted):
    """The FMU binary: fmi2* only; its compiled kernels' library: dfmi_kernel_* and dfmi_function_*
    (the compiled functions the component calls) only. Python
    extension modules in resources/: PyInit_* only."""
    directory = extracted(source)
    identifier = fmpy.read_model_description(str(directory)).coSimulation.modelIdentifier
    binaries = sorted(p.name for p in (directory / "binaries").rglob("*") if p.is_file())
    assert binaries in ([f"{identifier}.so"], [f"{identifier}.so", f"{identifier}_kernels.so"])
    for library in shared_libraries(directory):
        symbols = exported_symbols(library)
        assert symbols, library
        prefix = (("dfmi_kernel_", "dfmi_function_") if library.name.endswith("_kernels.so")
                  else "fmi2" if "binaries" in library.relative_to(directory).parts else "PyInit_")
        strays = [name for name in symbols if not name.startswith(prefix)]
        assert not strays, f"{library.relative_to(directory)} exports {strays[:10]}"
