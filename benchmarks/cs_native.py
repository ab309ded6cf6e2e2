"""Per-step cost of our Co-Simulation step (fmi2DoStep, CVODE inside the FMU) against the same
FMU run as Model Exchange by a C host's own CVODE at the same tolerances, in a plain C host.

For each model (Oscillator, BouncingBall with its contact events, DeltaRobot with projection and
its exact Jacobian) three runs of ``benchmarks/native/cs_host.c`` take turns, repeated:

- ``cs C``: fmi2DoStep as built (the CVODE loop in C, native/cs_step.c);
- ``cs Python``: the same FMU with ``DELTAFMI_NATIVE_CS=0`` (the loop in Python, as before);
- ``me``: Model Exchange, CVODE (BDF, dense, rtol and atol as our CS solver uses) in the host.

The figures are the CPU time of the stepping thread (the machine these run on is shared; the wall
time, in brackets, counts the time other processes ran too). CS's first step, which makes the
FMU's solver as the ME run makes its own before its loop, is timed apart ("1st step ms", wall).

Prints the medians (microseconds per 1 ms step, the stepping loop only) and the ratios
``cs / me`` before and after, all measured in this run. The final rows of the C and the Python
loop must agree bit for bit (printed as "identical").

Usage: python benchmarks/cs_native.py [--steps N] [--repeats R]
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NATIVE = ROOT / "deltafmi" / "runtime" / "native"

#: model file, outputs read each step, seconds simulated per run
MODELS = {
    "Oscillator": ("oscillator.py", ["x", "v", "energy"], 4.0),
    "BouncingBall": ("bouncing_ball.py", ["q", "v", "energy"], 3.0),
    "DeltaRobot": ("delta_robot.py", ["q[1]", "q[2]", "q[3]", "residual"], 1.0),
}
H = 1e-3


def compile_host(work: Path) -> Path:
    exe = work / "cs_host"
    subprocess.run(["cc", "-O2", "-Wall", f"-I{NATIVE}", str(ROOT / "benchmarks" / "native" / "cs_host.c"),
                    "-o", str(exe), "-ldl", "-lm"], check=True)
    return exe


def tolerances(source: str) -> tuple[float, float]:
    """(rtol, atol factor on the nominals) our CS solver uses for the component (instance.py _make_solver)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_model", ROOT / "fmu_src" / source)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    from deltafmi.component import Component

    cls = next(v for v in vars(module).values()
               if isinstance(v, type) and issubclass(v, Component) and v.__module__ == module.__name__)
    options = dict(cls.cs_options)
    rtol = options.get("rtol", cls.default_experiment.tolerance) * options.get("rtol_factor", 1.0)
    atol = options.get("atol")
    if atol is not None and any(n != 1.0 for n in cls._layout.nominals):
        raise SystemExit(f"{source}: an absolute atol with nominals != 1 is not what the host reproduces")
    return rtol, float(atol) if atol is not None else rtol


def run(exe: Path, fmu_dir: Path, md: dict, mode: str, steps: int, outputs: list[str], extra: list[str],
        env: dict) -> tuple[float, float, float, str]:
    """(CPU us per step of the stepping thread, wall us per step, wall us of CS's first step
    (it makes the solver; NaN for ME), the last row)."""
    vrs = [str(md["vr"][name]) for name in outputs]
    args = [str(exe), str(fmu_dir), md["id"], md["guid"], mode, str(steps), repr(H), *extra, *vrs]
    done = subprocess.run(args, capture_output=True, text=True, env=env, timeout=600)
    if done.returncode != 0:
        raise SystemExit(f"{mode} failed ({done.returncode}): {done.stderr[-2000:]}")
    lines = done.stdout.splitlines()
    figure = {line.split(",")[0]: float(line.split(",")[1]) for line in lines if "_per_step," in line}
    first = next((float(line.split(",")[1]) for line in lines if line.startswith("first_step_us,")), float("nan"))
    return figure["cpu_us_per_step"], figure["us_per_step"], first, lines[-2]


def describe(fmu_dir: Path) -> dict:
    root = ET.parse(fmu_dir / "modelDescription.xml").getroot()
    return {"guid": root.get("guid"), "id": root.find("CoSimulation").get("modelIdentifier"),
            "vr": {v.get("name"): int(v.get("valueReference")) for v in root.iter("ScalarVariable")},
            "nx": len(root.find("ModelStructure").find("Derivatives") or []),
            "nz": int(root.get("numberOfEventIndicators") or 0)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=0, help="steps per run (default: each model's stop time)")
    parser.add_argument("--repeats", type=int, default=5)
    opts = parser.parse_args()
    from deltafmi.builder.packager import build_cached
    from deltafmi.runtime import sundials

    sundials_dir = str(sundials.library_directory())
    work = Path(tempfile.mkdtemp(prefix="cs_native_"))
    try:
        exe = compile_host(work)
        base = {k: v for k, v in os.environ.items() if k not in ("DELTAFMI_NATIVE_CS", "DELTAFMI_NATIVE")}
        print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; medians of {opts.repeats} runs, "
              f"us per {H * 1e3:g} ms step: CPU time of the stepping thread (wall time in brackets: on a "
              f"loaded machine it counts others' time too)")
        print(f"{'model':14s} {'me (host CVODE)':>18s} {'cs Python':>18s} {'cs C':>18s} "
              f"{'Python/me':>10s} {'C/me':>6s} {'Python/C':>9s} {'1st step ms':>11s}  C and Python loops")
        for name, (source, outputs, stop) in MODELS.items():
            fmu = build_cached(ROOT / "fmu_src" / source)
            fmu_dir = work / name
            with zipfile.ZipFile(fmu) as z:
                z.extractall(fmu_dir)
            md = describe(fmu_dir)
            rtol, atol = tolerances(source)
            steps = opts.steps or round(stop / H)
            me_env = dict(base, CS_HOST_NX=str(md["nx"]), CS_HOST_NZ=str(md["nz"]))
            cpu: dict[str, list[float]] = {"me": [], "py": [], "c": []}
            wall: dict[str, list[float]] = {"me": [], "py": [], "c": []}
            rows, first_steps = {}, []
            for _ in range(opts.repeats):
                for key, mode, extra, env in (
                        ("c", "cs", [], base), ("py", "cs", [], dict(base, DELTAFMI_NATIVE_CS="0")),
                        ("me", "me", [repr(rtol), repr(atol), sundials_dir], me_env)):
                    us_cpu, us_wall, first, rows[key] = run(exe, fmu_dir, md, mode, steps, outputs, extra, env)
                    if key == "c":
                        first_steps.append(first)
                    cpu[key].append(us_cpu)
                    wall[key].append(us_wall)
            me, py, c = (statistics.median(cpu[k]) for k in ("me", "py", "c"))
            cells = " ".join(f"{statistics.median(cpu[k]):8.2f} ({statistics.median(wall[k]):7.2f})"
                             for k in ("me", "py", "c"))
            same = "identical" if rows["c"] == rows["py"] else f"DIFFER: {rows['c']} vs {rows['py']}"
            print(f"{name:14s} {cells} {py / me:10.2f} {c / me:6.2f} {py / c:9.2f} "
                  f"{statistics.median(first_steps) / 1e3:11.1f}  {same}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
