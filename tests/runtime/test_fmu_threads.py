"""Many host threads, one interpreter: FMUs instantiated at the same moment from a pthread C host.

tests/c_host/threads_host.c opens the FMUs' binaries, lines its threads up at a barrier, calls
fmi2Instantiate in all of them at once and steps them concurrently in Co-Simulation. The races
happen while the process starts Python and imports the models, so every run is a fresh process,
four at a time, each compared with a serial run of the same jobs in one thread (every digit: the
instances share nothing but the interpreter). Before the process-wide start-up lock and the boot
code's import lock, these runs failed (crash, or fmi2Instantiate NULL) in 98-100 of 100 with two
different FMUs, 16-24 of 100 with four instances of one FMU, 98-100 of 100 with a portable and
non-portable FMUs, and 40-44 of 50 in fmpy (docs/portability.md, "Threads and start-up"). Each
case makes as many runs as miss a race failing that often with a chance under 1 in 1000
(:func:`runs_against`), and at least ten.
"""
from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from concurrent.futures import ThreadPoolExecutor
import math
from pathlib import Path

import numpy as np
import pytest

from conftest import NATIVE, ROOT, clean_env, unzip
from oscillator_analytic import solution



def runs_against(failure_rate: float, miss: float = 1e-3) -> int:
    """Fresh-process runs that all pass with chance under ``miss`` when each fails at ``failure_rate``."""
    return max(10, math.ceil(math.log(miss) / math.log(1.0 - failure_rate)))


STOP, STEP = 0.3, 0.01
OUTPUTS = {"Oscillator": ("x", "v"), "Trajectory": ("r[1]", "r[2]", "rd[1]")}


@pytest.fixture(scope="module")
def threads_host(tmp_path_factory) -> Path:
    exe = tmp_path_factory.mktemp("threads_host") / "threads_host"
    subprocess.run(["cc", "-O2", "-Wall", f"-I{NATIVE}", str(ROOT / "tests" / "c_host" / "threads_host.c"),
                    "-o", str(exe), "-ldl", "-lm", "-lpthread"], check=True)
    return exe


def job(fmu: Path, directory: Path) -> list[str]:
    """threads_host's four arguments for one instance of the FMU unpacked into ``directory``."""
    if not directory.exists():
        unzip(fmu, directory)
    root = ET.parse(directory / "modelDescription.xml").getroot()
    identifier = root.find("CoSimulation").get("modelIdentifier")
    vrs = {v.get("name"): v.get("valueReference") for v in root.iter("ScalarVariable")}
    outputs = ",".join(vrs[name] for name in OUTPUTS[root.get("modelName")])
    return [str(directory.resolve()), identifier, root.get("guid"), outputs]


@pytest.fixture(scope="module")
def jobs(build_fmu_from_src, tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("threads")
    return {"oscillator": job(build_fmu_from_src("oscillator.py"), out / "oscillator"),
            "trajectory": job(build_fmu_from_src("trajectory.py"), out / "trajectory")}


def run(host: Path, mode: str, jobs: list[list[str]]) -> subprocess.CompletedProcess:
    command = [str(host), mode, str(STOP), str(STEP), *[a for j in jobs for a in j]]
    return subprocess.run(command, capture_output=True, text=True, env=clean_env(), timeout=300)


def rows(stdout: str, index: int) -> np.ndarray:
    """The rows ``t, value...`` that threads_host printed for job ``index``."""
    lines = [line.split()[1:] for line in stdout.splitlines() if line.split()[0] == str(index)]
    return np.array(lines, dtype=float)


def check_concurrent_runs(host: Path, jobs: list[list[str]], runs: int) -> str:
    """``runs`` parallel runs, each equal to the serial run; returns the serial run's output."""
    serial = run(host, "serial", jobs)
    assert serial.returncode == 0, serial.stderr
    for index in range(len(jobs)):
        assert len(rows(serial.stdout, index)) == round(STOP / STEP) + 1
    with ThreadPoolExecutor(max_workers=4) as pool:
        results = list(pool.map(lambda _: run(host, "parallel", jobs), range(runs)))
    failed = [r for r in results if r.returncode != 0 or r.stdout != serial.stdout]
    first = failed[0] if failed else None
    assert not failed, (f"{len(failed)} of {runs} runs failed or differ from the serial run; the first: exit "
                        f"status {first.returncode}, stderr:\n{first.stderr[-2000:]}")
    return serial.stdout


def assert_oscillator(stdout: str, index: int) -> None:
    """The Oscillator's x(t) against the closed-form solution (as for the single-threaded C host)."""
    t_x = rows(stdout, index)
    x, _, _ = solution(t_x[:, 0])
    assert np.max(np.abs(t_x[:, 1] - x)) < 1e-5


def test_two_different_fmus_start_python_once(threads_host, jobs):
    """Two FMU binaries (no shared statics) instantiated at once: one interpreter start-up."""
    stdout = check_concurrent_runs(threads_host, [jobs["oscillator"], jobs["trajectory"]], runs_against(0.98))
    assert_oscillator(stdout, 0)
    path = rows(stdout, 1)
    assert np.ptp(path[:, 1:], axis=0).max() > 1e-3  # the trajectory moves: a real output


def test_instances_of_one_fmu_import_it_once(threads_host, jobs):
    """Four instances of one FMU (one binary) instantiated at once: the model is imported once.
    (Four, not two: with two instances the old race showed in only ~1 run of 50 on a busy machine.)"""
    stdout = check_concurrent_runs(threads_host, [jobs["oscillator"]] * 4, runs_against(0.16))
    assert_oscillator(stdout, 0)
    for index in (1, 2, 3):
        assert np.array_equal(rows(stdout, index), rows(stdout, 0))


def test_portable_and_non_portable_fmus_share_one_interpreter(threads_host, jobs, portable_oscillator_fmu,
                                                              tmp_path_factory):
    """A portable FMU (its own interpreter) and non-portable ones (the builder's): whichever thread
    takes the start-up lock first starts its Python, and the other FMUs run in it. A portable
    interpreter carries only what its own model imports: the non-portable FMUs borrow the rest
    (the Trajectory's standard library modules, the Oscillator's SUNDIALS) from their builder."""
    portable = job(portable_oscillator_fmu, tmp_path_factory.mktemp("threads") / "oscillator_portable")
    mix = [portable, jobs["oscillator"], jobs["trajectory"]]
    stdout = check_concurrent_runs(threads_host, mix, runs_against(0.98))
    assert_oscillator(stdout, 0)
    assert np.array_equal(rows(stdout, 0), rows(stdout, 1))
    builder_first = run(threads_host, "serial", mix[1:] + mix[:1])  # the builder's Python for sure
    assert builder_first.returncode == 0, builder_first.stderr
    for index in range(3):
        assert np.array_equal(rows(builder_first.stdout, (index + 2) % 3), rows(stdout, index))


FMPY_HOST = """
import sys, threading
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave

mode, directories = sys.argv[1], sys.argv[2:]
barrier, results = threading.Barrier(len(directories)), [None] * len(directories)
fmus = []
for index, directory in enumerate(directories):  # fmpy's model description reader is not thread-safe
    md = read_model_description(directory)
    vrs = [v.valueReference for v in md.modelVariables if v.causality in ("output", "local")][:3]
    fmus.append((FMU2Slave(guid=md.guid, unzipDirectory=directory, modelIdentifier=md.coSimulation.modelIdentifier,
                           instanceName=f"job{index}"), vrs))

def run(index, directory):
    fmu, vrs = fmus[index]
    if mode == "parallel":
        barrier.wait(timeout=600)
    fmu.instantiate()  # a NULL instance raises; the thread's result stays None
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    rows = []
    for k in range(30):
        fmu.doStep(k * 0.01, 0.01)
        rows.append(" ".join(repr(value) for value in fmu.getReal(vrs)))
    fmu.terminate()
    fmu.freeInstance()
    results[index] = rows

threads = [threading.Thread(target=run, args=item) for item in enumerate(directories)]
for thread in threads:
    thread.start()
    if mode == "serial":
        thread.join()
for thread in threads:
    thread.join()
print("results", results)  # the last line; fmpy's logger prints above it
sys.exit(0 if None not in results else 1)
"""


def test_python_host_threads(jobs, portable_oscillator_fmu, tmp_path_factory):
    """fmpy (ctypes releases the GIL around fmi2 calls) from four Python threads at once: two FMUs,
    two instances of one, a portable one; each run a fresh process, as for the C host."""
    portable = job(portable_oscillator_fmu, tmp_path_factory.mktemp("threads") / "oscillator_portable")
    directories = [jobs["oscillator"][0], jobs["trajectory"][0], jobs["oscillator"][0], portable[0]]

    def run_python(mode: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-c", FMPY_HOST, mode, *directories], capture_output=True,
                              text=True, timeout=300)

    runs = runs_against(0.80)
    serial = run_python("serial")
    assert serial.returncode == 0, serial.stdout[-2000:] + serial.stderr[-2000:]
    with ThreadPoolExecutor(max_workers=4) as pool:
        results = list(pool.map(lambda _: run_python("parallel"), range(runs)))
    last = serial.stdout.splitlines()[-1]
    failed = [r for r in results if r.returncode != 0 or r.stdout.splitlines()[-1:] != [last]]
    assert not failed, (f"{len(failed)} of {runs} runs failed or differ from the serial run; the first's "
                        f"output:\n{failed[0].stdout[-2000:]}{failed[0].stderr[-2000:]}")
