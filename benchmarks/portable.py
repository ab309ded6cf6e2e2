"""Portable FMUs: sizes, first fmi2Instantiate, and the cost per step of each way an FMU runs.

Prints, all measured in this one run on this machine (medians over --repeats rounds, each running
every path once in a fresh process, so that a slow spell of the shared machine hits all paths):
(a) the zipped size of every fmu_src/ model FMU, non-portable and portable;
(b) the first fmi2Instantiate of the portable DeltaRobot in a C host (a fresh process per run, no
    Python in it: the FMU starts the interpreter it carries) against the non-portable FMU (which
    starts the Python recorded at build time);
(c) microseconds per Co-Simulation step (fmi2DoStep) and per Model Exchange derivative evaluation
    (fmi2SetTime + fmi2SetContinuousStates + fmi2GetDerivatives) of each path, with the ratio to the
    non-portable FMU in fmpy on the builder's Python (today's path):
      C host, non-portable (recorded interpreter) and portable (bundled interpreter);
      fmpy, host interpreter of the same version (this Python), non-portable and portable;
      fmpy, host interpreter of another version (CPython 3.12 by default: the FMU's 3.11 bytecode and
      value access do not load there, its runtime runs from source).
The other-version host is a virtual environment with fmpy made once in the build cache.
Usage: python benchmarks/portable.py [--model delta_robot] [--steps N] [--repeats R] [--other 3.12]
       [--other-python PATH] [--no-sizes]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Optional

import fmpy

ROOT = Path(__file__).resolve().parents[1]
FMU_SRC = ROOT / "fmu_src"
BUILDER = f"{sys.version_info.major}.{sys.version_info.minor}"

# A C importer that times the first fmi2Instantiate, then N CS steps and N ME derivative evaluations.
TIMING_HOST = r'''
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "fmi2Functions.h"
#define LOAD(name) name##TYPE *name = (name##TYPE *)dlsym(lib, #name); if (!name) return 2;
#define OK(call) if ((call) > fmi2Warning) { fprintf(stderr, "%s failed\n", #call); return 3; }
static void logger(fmi2ComponentEnvironment e, fmi2String i, fmi2Status s, fmi2String c, fmi2String m, ...) {
    fprintf(stderr, "[%s] %s\n", c, m);
}
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + 1e-9 * t.tv_nsec; }
int main(int argc, char **argv) {
    char path[4096], uri[4200];
    const char *dir = argv[1], *id = argv[2], *guid = argv[3];
    long n = atol(argv[4]);
    size_t nx = (size_t)atol(argv[5]);
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 2; }
    LOAD(fmi2Instantiate) LOAD(fmi2SetupExperiment) LOAD(fmi2EnterInitializationMode) LOAD(fmi2FreeInstance)
    LOAD(fmi2ExitInitializationMode) LOAD(fmi2DoStep) LOAD(fmi2NewDiscreteStates) LOAD(fmi2EnterContinuousTimeMode)
    LOAD(fmi2GetContinuousStates) LOAD(fmi2SetContinuousStates) LOAD(fmi2GetDerivatives) LOAD(fmi2SetTime)
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    double t0 = now();
    fmi2Component c = fmi2Instantiate("cs", fmi2CoSimulation, guid, uri, &cb, fmi2False, fmi2False);
    double t1 = now();
    if (!c) return 4;
    OK(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    OK(fmi2EnterInitializationMode(c)); OK(fmi2ExitInitializationMode(c));
    double t = 0.0, h = 1e-3, t2 = now();
    for (long i = 0; i < n; i++, t += h) OK(fmi2DoStep(c, t, h, fmi2True));
    double t3 = now();
    fmi2FreeInstance(c);
    fmi2Component m = fmi2Instantiate("me", fmi2ModelExchange, guid, uri, &cb, fmi2False, fmi2False);
    if (!m) return 4;
    OK(fmi2SetupExperiment(m, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    OK(fmi2EnterInitializationMode(m)); OK(fmi2ExitInitializationMode(m));
    fmi2EventInfo info = {fmi2True};
    while (info.newDiscreteStatesNeeded) OK(fmi2NewDiscreteStates(m, &info));
    OK(fmi2EnterContinuousTimeMode(m));
    double x[64], dx[64];
    OK(fmi2GetContinuousStates(m, x, nx));
    double x0 = x[0], t4 = now();
    for (long i = 0; i < n; i++) { /* new states every time: nothing cached can answer */
        x[0] = x0 + 1e-9 * (i % 2);
        OK(fmi2SetTime(m, 1e-6 * i)); OK(fmi2SetContinuousStates(m, x, nx)); OK(fmi2GetDerivatives(m, dx, nx));
    }
    double t5 = now();
    printf("{\"instantiate_s\": %.6f, \"cs_us\": %.3f, \"me_us\": %.3f}\n", t1 - t0, 1e6 * (t3 - t2) / n,
           1e6 * (t5 - t4) / n);
    return 0;
}
'''

# The same measurement through fmpy, run by each Python host.
FMPY_SCRIPT = r'''
import json, sys, time
import fmpy
from fmpy.fmi2 import FMU2Slave, FMU2Model
fmu, n = sys.argv[1], int(sys.argv[2])
md = fmpy.read_model_description(fmu)
directory = fmpy.extract(fmu)
kw = dict(guid=md.guid, unzipDirectory=directory, modelIdentifier=md.coSimulation.modelIdentifier)
start = time.perf_counter()
slave = FMU2Slave(instanceName="cs", **kw)
slave.instantiate()
instantiate = time.perf_counter() - start
slave.setupExperiment(startTime=0.0); slave.enterInitializationMode(); slave.exitInitializationMode()
t, h = 0.0, 1e-3
start = time.perf_counter()
for _ in range(n):
    slave.doStep(t, h); t += h
cs = (time.perf_counter() - start) / n * 1e6
slave.terminate(); slave.freeInstance()
model = FMU2Model(instanceName="me", **kw)
model.instantiate(); model.setupExperiment(startTime=0.0)
model.enterInitializationMode(); model.exitInitializationMode()
info = model.newDiscreteStates()
while info[0]:
    info = model.newDiscreteStates()
model.enterContinuousTimeMode()
from ctypes import c_double
nx = md.numberOfContinuousStates
x, dx = (c_double * nx)(), (c_double * nx)()
model.getContinuousStates(x, nx)
x0 = x[0]
start = time.perf_counter()
for i in range(n):
    x[0] = x0 + 1e-9 * (i % 2)
    model.setTime(1e-6 * i); model.setContinuousStates(x, nx); model.getDerivatives(dx, nx)
me = (time.perf_counter() - start) / n * 1e6
print(json.dumps({"instantiate_s": instantiate, "cs_us": cs, "me_us": me}))
'''


def sizes(portable: bool) -> dict[str, int]:
    """Zipped size in bytes of every packaged model's FMU (from the build cache)."""
    from deltafmi.builder.packager import build_cached
    from deltafmi.models import MODELS
    return {module: build_cached(FMU_SRC / f"{module}.py", portable=portable).stat().st_size
            for module in sorted(MODELS.values())}


def timing_host(workdir: Path) -> Path:
    """``TIMING_HOST`` compiled in ``workdir``."""
    source, exe = workdir / "timing_host.c", workdir / "timing_host"
    source.write_text(TIMING_HOST)
    subprocess.run(["cc", "-O2", f"-I{ROOT / 'deltafmi/runtime/native'}", str(source), "-o", str(exe), "-ldl"],
                   check=True)
    return exe


def median_rounds(commands: dict[str, tuple[list[str], Optional[dict]]], repeats: int) -> dict[str, dict]:
    """name -> median of each figure over ``repeats`` rounds, each running every command (which
    prints JSON) once in a fresh process, so that a slow spell of the shared machine hits every
    path alike; {"error": the FMU's first message} for a path that does not run."""
    runs: dict[str, dict[str, list[float]]] = {name: {} for name in commands}
    errors: dict[str, str] = {}
    for _ in range(repeats):
        for name, (command, env) in commands.items():
            if name in errors:
                continue
            done = subprocess.run(command, capture_output=True, text=True, env=env)
            if done.returncode != 0:
                lines = [line for line in (done.stdout + done.stderr).splitlines() if line.strip()] or ["?"]
                errors[name] = next((line for line in lines if "rror" in line), lines[-1])
                continue
            for key, value in json.loads(done.stdout.strip().splitlines()[-1]).items():
                runs[name].setdefault(key, []).append(value)
    return {name: {"error": errors[name]} if name in errors else
            {key: statistics.median(values) for key, values in runs[name].items()} for name in commands}


def other_version_python(version: str) -> Optional[Path]:
    """A virtual environment of CPython ``version`` with fmpy, made once in the build cache."""
    from deltafmi.toolchain import cache_dir
    venv = cache_dir() / "bench-hosts" / f"fmpy-{version}"
    python = venv / "bin" / "python"
    if python.exists():
        return python
    root = Path(os.environ.get("PYENV_ROOT", Path.home() / ".pyenv")) / "versions"
    interpreters = sorted(root.glob(f"{version}.*/bin/python3"))
    if not interpreters:
        return None
    subprocess.run([str(interpreters[-1]), "-m", "venv", str(venv)], check=True)
    installed = subprocess.run([str(python), "-m", "pip", "install", "-q", "fmpy"], capture_output=True, text=True,
                               env=dict(os.environ, PIP_CACHE_DIR=str(cache_dir() / "pip")))
    if installed.returncode != 0:
        raise RuntimeError(f"pip install fmpy into {venv} failed:\n{installed.stderr[-2000:]}")
    return python


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="delta_robot", help="fmu_src/ model for (b) and (c)")
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--other", default="3.12", help="CPython version of the other-version fmpy host")
    parser.add_argument("--other-python", type=Path, help="that host's python (default: a venv with fmpy "
                        "made once in the build cache)")
    parser.add_argument("--no-sizes", action="store_true", help="skip (a), which builds every portable FMU")
    args = parser.parse_args()
    from deltafmi.builder.packager import build_cached
    source = FMU_SRC / f"{args.model}.py"
    fmus = {"non-portable": build_cached(source), "portable": build_cached(source, portable=True)}

    if not args.no_sizes:
        plain, portable = sizes(False), sizes(True)
        print("(a) zipped FMU sizes (fmu_src/)")
        print(f"  {'model':28s} {'non-portable':>14s} {'portable':>12s}")
        for name in plain:
            print(f"  {name:28s} {plain[name] / 1e3:11.0f} KB {portable[name] / 1e6:9.1f} MB")

    md = fmpy.read_model_description(str(fmus["portable"]))
    identifier, nx = md.coSimulation.modelIdentifier, md.numberOfContinuousStates
    commands: dict[str, tuple[list[str], Optional[dict]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        host = timing_host(Path(tmp))
        for kind, fmu in fmus.items():
            directory = fmpy.extract(str(fmu), unzipdir=str(Path(tmp) / kind))
            commands[f"C host, {kind}"] = ([str(host), directory, identifier, md.guid, str(args.steps), str(nx)],
                                           {"PATH": "/usr/bin:/bin"})  # no Python variables
        pythons = {BUILDER: Path(sys.executable)}
        other = args.other_python or other_version_python(args.other)
        if other is not None:
            pythons[args.other] = other
        for version, python in pythons.items():
            for kind, fmu in fmus.items():
                commands[f"fmpy {version}, {kind}"] = ([str(python), "-c", FMPY_SCRIPT, str(fmu), str(args.steps)],
                                                       None)
        rows = median_rounds(commands, args.repeats)
    baseline = rows[f"fmpy {BUILDER}, non-portable"]
    if "error" in baseline:
        raise SystemExit(f"the baseline, {identifier} non-portable in fmpy {BUILDER}, does not run: "
                         f"{baseline['error']}")
    print(f"(b) first fmi2Instantiate of {identifier} in a C host (fresh process, median of {args.repeats})")
    for kind in fmus:
        row = rows[f"C host, {kind}"]
        print(f"  {kind:14s} " + (f"{row['instantiate_s']:7.3f} s" if "error" not in row else row["error"][:160]))
    print(f"(c) {identifier}: us per CS step (h = 1 ms) and per ME derivative evaluation, median of "
          f"{args.repeats} runs x {args.steps}; ratio to fmpy {BUILDER} non-portable")
    print(f"  {'path':32s} {'CS step':>9s} {'ratio':>6s} {'ME eval':>9s} {'ratio':>6s} {'instantiate':>12s}")
    for name, row in rows.items():
        if "error" in row:
            print(f"  {name:32s} does not run: {row['error'][:160]}")
            continue
        print(f"  {name:32s} {row['cs_us']:9.1f} {row['cs_us'] / baseline['cs_us']:6.2f} {row['me_us']:9.1f} "
              f"{row['me_us'] / baseline['me_us']:6.2f} {row['instantiate_s']:10.3f} s")
    if other is None:
        print(f"  fmpy {args.other}: skipped, no CPython {args.other} (pyenv) on this machine")


if __name__ == "__main__":
    main()
