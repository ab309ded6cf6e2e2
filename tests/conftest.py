"""Shared fixtures: FMUs built from the packaged models (fmu_src/) once per session, the compiled C
host; and the markers every test module gets from the tables below (one place to see them).

The suite runs on both cores (pytest-xdist, ``--dist loadgroup``): the modules of :data:`SERIAL`,
which measure wall time, threads or memory, or start Dask clusters of their own, run on one worker,
one test after the other (the ``xdist_group`` "serial"); every other test runs wherever a
worker is free. The FMU build cache is shared by both workers and safe for that (each build is
renamed into place whole).
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the folders of tests, one per layer of the package; a test module may use another's helpers by
#: its name (``from test_third_party_fmus import ball_exact``), whichever folder is collected first
LAYERS = ("runtime", "physics", "models", "builder", "master", "apps")
for _layer in LAYERS:
    if str(ROOT / "tests" / _layer) not in sys.path:
        sys.path.insert(0, str(ROOT / "tests" / _layer))
FMU_SRC = ROOT / "fmu_src"
#: the file names of the packaged models (deltafmi.models), one component each
MODEL_FILES = sorted(f"{module}.py" for module in __import__("deltafmi.models").models.MODELS.values())
NATIVE = ROOT / "deltafmi" / "runtime" / "native"


@pytest.fixture(scope="session")
def build_fmu_from_src(tmp_path_factory):
    """``build("oscillator.py") -> Path`` of a freshly built FMU (built once per session)."""
    from deltafmi.builder import build_fmu

    out = tmp_path_factory.mktemp("fmus")
    built: dict[str, Path] = {}

    def build(name: str) -> Path:
        if name not in built:
            built[name] = build_fmu(FMU_SRC / name, out / f"{Path(name).stem}.fmu")
        return built[name]

    return build


@pytest.fixture(scope="session")
def portable_oscillator_fmu() -> Path:
    """The portable Oscillator FMU (``deltafmi build --portable``), from the build cache."""
    from deltafmi.builder.packager import build_cached
    return build_cached(FMU_SRC / "oscillator.py", portable=True)


@pytest.fixture(scope="session")
def portable_delta_robot_fmu() -> Path:
    """The portable DeltaRobot FMU (CVODE, numpy, compiled kernels), from the build cache."""
    from deltafmi.builder.packager import build_cached
    return build_cached(FMU_SRC / "delta_robot.py", portable=True)


@pytest.fixture(scope="session")
def c_host(tmp_path_factory) -> Path:
    """The plain-C FMI importer of tests/c_host, compiled for this session."""
    exe = tmp_path_factory.mktemp("c_host") / "host"
    subprocess.run(["cc", "-O2", "-Wall", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "host.c"),
                    "-o", str(exe), "-ldl", "-lm"], check=True)
    return exe


#: modules that measure wall time, threads or memory, or start Dask clusters or paced runs
SERIAL = {"test_live_pacing", "test_live_udp_run", "test_live_udp", "test_live_udp_native", "test_joystick_tracking",
          "test_live_scope",
          "test_fmu_threads", "test_memory", "test_study_dask", "test_study_cluster", "test_study_tls",
          "test_study_dashboard", "test_study_rough_edges", "test_peg_robustness", "test_troubleshooting_docs",
          "test_examples", "test_rough_edges", "test_study_metrics", "test_reliability_results",
          "test_reliability_sweep", "test_reliability_limits", "test_parallel_units", "test_reliability_signals_tools",
          "test_study_snapshots"}
#: modules whose tests share an expensive fixture of their own (a wheel, fresh virtual environments): each
#: runs on one worker (an xdist_group of its own), so that the fixture is made once, and early (xdist hands
#: out the groups with the most tests first, then the ungrouped tests one by one)
OWN_GROUP = {"test_wheel_install", "test_python_hosts", "test_export_fmu", "test_assembly_hold"}
#: modules that start other processes (a C host, another Python, a CLI, a Dask process)
SUBPROCESS = {"test_reliability_signals_tools", "test_component_docs", "test_live_scope", "test_rough_edges",
              "test_study_cluster", "test_study_dask", "test_study_snapshots", "test_study_third_party",
              "test_study_rough_edges", "test_study_tls", "test_troubleshooting_docs", "test_compiler_messages",
              "test_fmi3_clocks", "test_fmu_contents", "test_fmu_requirements", "test_native_kernels",
              "test_native_projection", "test_portable_fmus", "test_python_hosts", "test_wheel_install",
              "test_live_pacing", "test_master_loops", "test_third_party_fmi3", "test_third_party_fmus",
              "test_assembly_portable", "test_oscillator_fmu", "test_delta_control", "test_component_init",
              "test_component_values", "test_fmi3_binary", "test_fmu_logging", "test_fmu_threads",
              "test_fmu_without_fmpy_scipy", "test_memory", "test_symbol_isolation", "test_third_party_masters",
              "test_peg_robustness", "test_examples", "test_reliability_results", "test_reliability_sweep",
              "test_reliability_recipes", "test_reliability_limits", "test_reliability_no_traceback",
              "test_export_fmu", "test_fmi3_cs_events", "test_cli_lazy", "test_cs_native", "test_fmu_state_position",
              "test_cache_installations"}
#: what a module that builds FMUs (or runs scenarios, which build theirs) says somewhere
_BUILDS = re.compile(r"build_fmu|build_cached|_fmu\b|_fmu\(|simulate|resolve_system|\[\"(run|build|sweep|linearize)\"")
#: modules with a test over 10 s on this kind of machine (2 cores; `--durations=25` shows them)
SLOW = {"test_reliability_signals_tools", "test_wheel_install", "test_python_hosts", "test_peg_robustness",
        "test_study_dask", "test_study_cluster",
        "test_study_tls", "test_assembly_portable", "test_portable_fmus", "test_memory", "test_insertion_mpc",
        "test_third_party_masters", "test_fmu_threads", "test_symbol_isolation", "test_joystick_tracking",
        "test_component_docs", "test_mpc_controller", "test_peg_estimator", "test_fmu_without_fmpy_scipy",
        "test_export_fmu", "test_assembly_hold", "test_contact_estimator_consistency",
        "test_peg_estimator_consistency", "test_non_utf8_paths",
        "test_contact_estimator_scenario_consistency"}


def pytest_configure(config) -> None:
    """Where ``PYTHONDONTWRITEBYTECODE`` is set, no process writes the bytecode of what it imports, and
    each of the suite's processes (workers, CLIs, Dask workers, FMU hosts) would compile the package
    from source again: the controller compiles it once, before the workers start. So too the
    environment's packages when they were installed without bytecode (``PIP_NO_COMPILE=0``, as
    .ci/run installs them: pip compiles one file after the other, and the packages' own test
    folders, a third of it, which no process here imports), on every core."""
    if sys.dont_write_bytecode and not hasattr(config, "workerinput"):
        import compileall
        import importlib.util
        import sysconfig

        for folder in (ROOT / "deltafmi", FMU_SRC):
            compileall.compile_dir(folder, quiet=1)
        packages = Path(sysconfig.get_paths()["purelib"])
        if not Path(importlib.util.cache_from_source(pytest.__file__)).exists():
            compileall.compile_dir(packages, quiet=1, workers=os.cpu_count() or 1,
                                   rx=re.compile(re.escape(str(packages)) + r"/.+/tests?/"))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A test's captured output may hold a file name that is not UTF-8 (the tests of such folders):
    xdist's workers send reports as UTF-8 and fail on it, so such characters are sent escaped."""
    outcome = yield
    report = outcome.get_result()
    report.sections = [(title, content.encode("utf-8", "backslashreplace").decode("utf-8"))
                       for title, content in report.sections]


def group_of(nodeid: str) -> str | None:
    """The xdist group of the test ``nodeid`` ("serial", a module of :data:`OWN_GROUP`), or None."""
    module = Path(nodeid.split("::")[0]).stem
    return "serial" if module in SERIAL else module if module in OWN_GROUP else None


@pytest.hookimpl(optionalhook=True)  # a hook of xdist's: none without it (-p no:xdist)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadgroup`` with the groups taken from the tables above by the scheduler itself: xdist
    3.8 finds a test's group in the ``@group`` its workers append to the node id, which pytest 9
    ignores (``Item.nodeid`` no longer reads ``_nodeid``), so that every test would go its own way."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadGroupScheduling

    class SuiteScheduling(LoadGroupScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return group_of(nodeid) or super()._split_scope(nodeid)

    return SuiteScheduling(config, log)


@pytest.hookimpl(tryfirst=True)  # before xdist's, which reads the xdist_group marks given here
def pytest_collection_modifyitems(config, items) -> None:
    builds: dict[Path, bool] = {}
    for item in items:
        path = Path(str(item.fspath))
        module = path.stem
        if path not in builds:
            builds[path] = path.suffix == ".py" and bool(_BUILDS.search(path.read_text()))
        if module in SERIAL:
            item.add_marker(pytest.mark.xdist_group("serial"))
        elif module in OWN_GROUP:
            item.add_marker(pytest.mark.xdist_group(module))
        if module in SUBPROCESS:
            item.add_marker(pytest.mark.subprocess)
        if module in SLOW:
            item.add_marker(pytest.mark.slow)
        if builds[path]:
            item.add_marker(pytest.mark.fmu)


def unzip(fmu: Path, target: Path) -> Path:
    """Extract an FMU and return the directory."""
    with zipfile.ZipFile(fmu) as z:
        z.extractall(target)
    return target


def clean_env(**extra: str) -> dict:
    """An environment with no Python variables and no LD_PRELOAD: a plain C host."""
    env = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}
    env.update(extra)
    return env


def start_model_exchange(fmu) -> None:
    """Take an fmpy ``FMU2Model`` from instantiation to continuous-time mode at t = 0."""
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.newDiscreteStates()
    fmu.enterContinuousTimeMode()
