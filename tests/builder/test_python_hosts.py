"""deltafmi FMUs in fmpy on CPython 3.10, 3.11, 3.12 and 3.13, each a fresh virtual environment with
nothing but fmpy: non-portable and portable FMUs, FMI 2.0 and 3.0 builds, Co-Simulation and Model
Exchange, give the results of the builder's environment (this test's interpreter, FMI 2.0) to 1e-6,
whatever the host's version.

A host of another version than the FMU's runs the model in its own interpreter with the FMU's
pure-Python fallbacks (the runtime's sources instead of its compiled value access) and its own
numpy (the compiled kernels are plain C, whatever the host's version); the packages a portable FMU carries serve only a host of the bundled version.
"""
from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Optional

import numpy as np
import pytest
from uv import find_uv_bin

from conftest import ROOT, clean_env, unzip

VERSIONS = ("3.10", "3.11", "3.12", "3.13")
MODELS = ("oscillator", "delta_robot")
#: a host's packages: fmpy and what its simulate_fmu imports (fmpy's other requirements, cmake,
#: jinja2, lark, msgpack and nbformat, serve its other tools: half the install time for nothing here)
HOST_PACKAGES = ("fmpy", "numpy", "lxml", "attrs")
#: a model that imports scipy, which fmpy does not install: only its portable FMU's bundle has it
SCIPY_MODEL = ROOT / "tests" / "components" / "erf" / "model.py"
STOP, INTERVAL = 0.3, 0.01
#: |host - builder| <= TOLERANCE * max(1, |builder|), every output at every output time
TOLERANCE = 1e-6
BUILDER = f"{sys.version_info.major}.{sys.version_info.minor}"

# Run by each host: simulate every FMU in CS and ME, write results (or the error) as JSON. fmpy's
# logger prints the FMU's messages to stdout, which the test shows when something fails.
# Each FMU is extracted once for both interfaces (fmpy simulates an extracted FMU's folder as it does
# the file it would extract again): a portable FMU unpacks to 60-110 MB.
HOST_SCRIPT = r'''
import json, shutil, sys
from fmpy import extract, simulate_fmu
out, stop, interval, fmus = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), sys.argv[4:]
results = {}
for fmu in fmus:
    folder = extract(fmu)
    for interface in ("CoSimulation", "ModelExchange"):
        try:
            r = simulate_fmu(folder, fmi_type=interface, stop_time=stop, output_interval=interval)
            results[f"{fmu}|{interface}"] = {n: r[n].astype(float).tolist() for n in r.dtype.names}
        except Exception as exc:
            results[f"{fmu}|{interface}"] = f"{type(exc).__name__}: {exc}"
    shutil.rmtree(folder, ignore_errors=True)
finder = next((f for f in sys.meta_path if type(f).__name__ == "_BundledSitePackages"), None)
scipy = sys.modules.get("scipy")
results["finder"] = {
    "sites": sorted(finder.sites.values()) if finder else None,
    "last": finder is sys.meta_path[-1] if finder else None,
    # the host's own code asking: the bundled packages are never served to it
    "serves_host": bool(finder and finder.find_spec("scipy") is not None),
    "scipy": getattr(scipy, "__file__", None)}
json.dump(results, open(out, "w"))
'''


def _interpreter(version: str) -> Optional[Path]:
    """pyenv's newest CPython ``version``, else a ``python3.X`` on PATH."""
    root = Path(os.environ.get("PYENV_ROOT", Path.home() / ".pyenv")) / "versions"
    releases = [p for p in root.glob(f"{version}.*/bin/python3") if re.fullmatch(r"\d+\.\d+\.\d+", p.parts[-3])]
    found = sorted(releases, key=lambda p: int(p.parts[-3].split(".")[2]))  # not 3.13.0t (free-threaded)
    if found:
        return found[-1]
    which = shutil.which(f"python{version}")
    return Path(which) if which else None


def _fresh_fmpy_venv(version: str, root: Path) -> tuple[Optional[Path], str]:
    """(python of a new virtual environment with fmpy and what it needs to simulate, "") or (None, why not)."""
    interpreter = _interpreter(version)
    if interpreter is None:
        return None, f"no CPython {version} on this machine (pyenv or python{version} on PATH)"
    venv = root / f"venv{version}"
    made = subprocess.run([str(interpreter), "-m", "venv", "--without-pip", str(venv)], capture_output=True, text=True)
    if made.returncode != 0:
        return None, f"{interpreter} cannot make a virtual environment: {made.stderr.strip()[-500:]}"
    python = venv / "bin" / "python"
    # uv (astral's installer, a test requirement) installs the host's packages from the registry or
    # its cache: pip took 4-5 CPU-s a venv, most of it reading the index's thousands of numpy files
    installed = subprocess.run([find_uv_bin(), "pip", "install", "-q", "--python", str(python), "--no-deps",
                                *HOST_PACKAGES], capture_output=True, text=True)
    if installed.returncode != 0:
        raise AssertionError(f"installing fmpy into a CPython {version} environment failed:\n"
                             f"{installed.stderr[-2000:]}")
    return python, ""


def session_fmpy_venv(version: str, tmp_path_factory: pytest.TempPathFactory) -> tuple[Optional[Path], str]:
    """:func:`_fresh_fmpy_venv` made once in this test session for all its xdist workers (in the
    folder they share, under a lock): the first test to ask makes it, the others take it."""
    import fcntl

    base = tmp_path_factory.getbasetemp()
    root = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "fmpy_hosts"
    root.mkdir(exist_ok=True)
    with open(root / f"{version}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        made = root / f"{version}.json"
        if made.exists():
            python, why = json.loads(made.read_text())
            return (Path(python) if python else None), why
        python, why = _fresh_fmpy_venv(version, root)
        made.write_text(json.dumps([str(python) if python else None, why]))
        return python, why


@pytest.fixture(scope="session")
def fmpy_hosts(tmp_path_factory) -> dict:
    """version -> (python of a fresh venv with nothing but fmpy, or None; why not), made in parallel."""
    with ThreadPoolExecutor(len(VERSIONS)) as pool:
        made = dict(zip(VERSIONS, pool.map(lambda v: session_fmpy_venv(v, tmp_path_factory), VERSIONS)))
    return made


@pytest.fixture(scope="session")
def host_fmus(build_fmu_from_src, portable_oscillator_fmu, portable_delta_robot_fmu) -> dict:
    """(model, "plain" | "portable") -> FMU; portable ones from the build cache."""
    from deltafmi.builder.packager import build_cached
    fmus = {(model, "plain"): build_fmu_from_src(f"{model}.py") for model in MODELS}
    fmus["oscillator", "portable"] = portable_oscillator_fmu
    fmus["delta_robot", "portable"] = portable_delta_robot_fmu
    fmus["erf", "portable"] = build_cached(SCIPY_MODEL, portable=True)
    for model in MODELS:  # FMI 3.0 builds: the FMI 2.0 build's results, arrays element by element
        fmus[model, "fmi3"] = build_cached(ROOT / "fmu_src" / f"{model}.py", fmi_version=3)
    return fmus


def _simulate(python: Path, fmus: list[Path], out: Path) -> tuple[dict, str]:
    # the hosts' packages are installed without bytecode: the first run writes what it imports (the C
    # host's runs below then find it), whatever PYTHONDONTWRITEBYTECODE this session has
    env = {name: value for name, value in os.environ.items() if name != "PYTHONDONTWRITEBYTECODE"}
    run = subprocess.run([str(python), "-c", HOST_SCRIPT, str(out), str(STOP), str(INTERVAL), *map(str, fmus)],
                         capture_output=True, text=True, timeout=600, cwd=out.parent, env=env)
    if run.returncode != 0 or not out.exists():
        raise AssertionError(f"{python} exited with {run.returncode}:\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}")
    return json.loads(out.read_text()), run.stdout + run.stderr


@pytest.fixture(scope="session")
def host_results(fmpy_hosts, host_fmus, tmp_path_factory) -> dict:
    """"builder" and each available version -> (results by "fmu|interface", the host's log)."""
    root = tmp_path_factory.mktemp("host_results")
    pythons = {"builder": Path(sys.executable)}
    pythons.update({v: python for v, (python, _) in fmpy_hosts.items() if python is not None})
    fmus = list(host_fmus.values())
    reference_fmus = [fmu for (model, _), fmu in host_fmus.items() if model in MODELS]
    with ThreadPoolExecutor(2) as pool:  # 2 cores: more processes only share them
        futures = {name: pool.submit(_simulate, python, reference_fmus if name == "builder" else fmus,
                                     root / f"{name}.json") for name, python in pythons.items()}
        return {name: future.result() for name, future in futures.items()}


def _scalarized(result: dict) -> dict:
    """An FMI 3.0 result's array columns (rows of lists) as FMI 2.0 names them: z -> z[1], z[2], ..."""
    found = {}
    for name, values in result.items():
        if values and isinstance(values[0], list):
            for i in range(len(values[0])):
                found[f"{name}[{i + 1}]"] = [row[i] for row in values]
        else:
            found[name] = values
    return found


def _deviation(reference: dict, result: dict) -> float:
    """Largest |result - reference| / max(1, |reference|) over every variable and output time."""
    assert set(result) == set(reference), f"variables differ: {sorted(set(result) ^ set(reference))}"
    worst = 0.0
    for name, values in reference.items():
        ref, got = np.asarray(values), np.asarray(result[name])
        assert got.shape == ref.shape, f"{name}: {got.shape[0]} output rows, the builder's had {ref.shape[0]}"
        worst = max(worst, float(np.max(np.abs(got - ref) / np.maximum(1.0, np.abs(ref)), initial=0.0)))
    return worst


@pytest.mark.parametrize("version", VERSIONS)
def test_fmpy_host_gives_the_builders_results(version, fmpy_hosts, host_fmus, host_results):
    python, why = fmpy_hosts[version]
    if python is None:
        pytest.skip(why)
    reference, builder_log = host_results["builder"]
    results, log = host_results[version]
    failures = []
    for (model, kind), fmu in host_fmus.items():
        if model not in MODELS:
            continue
        for interface in ("CoSimulation", "ModelExchange"):
            expected = reference[f"{host_fmus[model, 'plain']}|{interface}"]
            assert not isinstance(expected, str), f"the builder's own {model} {interface} failed: {expected}\n" \
                                                  f"{builder_log[-2000:]}"
            got = results[f"{fmu}|{interface}"]
            if isinstance(got, str):
                failures.append(f"{model} ({kind}) {interface}: {got}")
                continue
            got = _scalarized(got)
            deviation = _deviation(expected, got)
            if not deviation <= TOLERANCE:
                failures.append(f"{model} ({kind}) {interface}: deviates by {deviation:.3g} (relative)")
    assert not failures, f"CPython {version} with fmpy:\n" + "\n".join(failures) + f"\nhost log:\n{log[-3000:]}"


def test_bundled_packages_serve_only_the_fmus_of_the_bundled_version(fmpy_hosts, host_fmus, host_results):
    """A portable FMU whose model imports scipy, in a host with nothing but fmpy: of the bundled
    version, it takes scipy from its bundle (for its own imports only: the host's code is not served)
    and computes erf exactly; of another version, it fails to instantiate with a message that says why."""
    fmu = host_fmus["erf", "portable"]
    checked = 0
    for version, (python, _) in fmpy_hosts.items():
        if python is None:
            continue
        checked += 1
        results, log = host_results[version]
        finder = results["finder"]
        for interface in ("CoSimulation", "ModelExchange"):
            result = results[f"{fmu}|{interface}"]
            if version == BUILDER:
                assert not isinstance(result, str), f"{interface}: {result}\n{log[-3000:]}"
                exact = np.array([math.erf(t) for t in result["time"]])
                assert result["time"][-1] == pytest.approx(STOP)
                assert np.max(np.abs(np.array(result["y"]) - exact)) < 1e-9
            else:
                assert isinstance(result, str) and "instantiate" in result, result
        if version == BUILDER:
            assert finder["last"] is True, finder
            assert finder["sites"] and all(s.endswith("/resources/python/site-packages") for s in finder["sites"])
            assert finder["scipy"] and "/resources/python/site-packages/scipy/" in finder["scipy"], finder
            assert finder["serves_host"] is False
        else:
            assert not finder["sites"], f"CPython {version}: the {BUILDER} bundle was registered: {finder}"
            assert finder["scipy"] is None, finder
            assert (f"CPython {version}; the packages this portable FMU carries are for CPython {BUILDER} and "
                    "serve only that version") in log
    if checked == 0:
        pytest.skip("no CPython 3.10-3.13 on this machine")


def _libpython(python: Path) -> Optional[Path]:
    """The shared libpython of ``python``'s installation, or None (a static build)."""
    script = "import sysconfig as s; print(s.get_config_var('LIBDIR') or '', s.get_config_var('INSTSONAME') or '')"
    out = subprocess.run([str(python), "-c", script], capture_output=True, text=True, check=True).stdout.split()
    library = Path(*out) if len(out) == 2 else None
    return library if library is not None and library.is_file() else None


def _c_host_rows(c_host: Path, directory: Path, fmu: Path, env: dict) -> np.ndarray:
    """Co-Simulation from the plain-C host: outputs every 10 ms up to STOP, one row per step."""
    import fmpy
    md = fmpy.read_model_description(str(fmu))
    outputs = [str(v.valueReference) for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    run = subprocess.run([str(c_host), str(directory), md.coSimulation.modelIdentifier, md.guid, "cs", str(STOP),
                          str(INTERVAL), *outputs], capture_output=True, text=True, env=clean_env(**env), timeout=300)
    assert run.returncode == 0, f"C host, {fmu.name}, {env}: exit {run.returncode}\n{run.stdout[-2000:]}" \
                                f"{run.stderr[-2000:]}"
    return np.array([[float(x) for x in line.split(",")] for line in run.stdout.splitlines() if line[:1].isdigit()])


@pytest.mark.parametrize("version", VERSIONS)
def test_c_host_starts_each_cpython_the_override_names(version, fmpy_hosts, host_fmus, c_host, tmp_path):
    """The bridge starts, in a C host, the libpython of every CPython 3.10-3.13 (DELTAFMI_LIBPYTHON,
    with DELTAFMI_PYTHON for its packages) through the C API subset it binds at run time
    (native/pyapi.h), and a non-portable FMU gives the results of the builder's Python."""
    python, why = fmpy_hosts[version]
    if python is None:
        pytest.skip(why)
    library = _libpython(python)
    if library is None:
        pytest.skip(f"CPython {version} ({python}) has no shared libpython for a C host to load")
    for model in MODELS:
        fmu = host_fmus[model, "plain"]
        directory = unzip(fmu, tmp_path / model)
        reference = _c_host_rows(c_host, directory, fmu, {})  # the Python recorded at build time
        override = {"DELTAFMI_LIBPYTHON": str(library), "DELTAFMI_PYTHON": str(python)}
        got = _c_host_rows(c_host, directory, fmu, override)
        assert reference.shape == got.shape == (round(STOP / INTERVAL) + 1, reference.shape[1]), model
        if version != BUILDER:  # that version ran the runtime: it compiled the sources for itself
            tag = f"cpython-{version.replace('.', '')}"
            assert list(directory.glob(f"resources/python/deltafmi/runtime/__pycache__/instance.{tag}.pyc")), model
        assert np.max(np.abs(got - reference) / np.maximum(1.0, np.abs(reference))) <= TOLERANCE, model
