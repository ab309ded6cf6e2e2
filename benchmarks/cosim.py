"""Co-simulation master figures: real-time factor of the flagship, and the master's own overhead.

1. Flagship: scenarios/delta_tracking.yaml as written (plant ME through the master's rk4,
   controller and trajectory CS, Gauss-Seidel, 1 kHz): real-time factor end to end (loading the
   FMUs included) and of the stepping loop, where the time goes; and the same scenario with the
   plant on CVODE (BDF, rtol 1e-8) as the baseline.
2. Overhead: the same system with every component as Co-Simulation and Jacobi stepping, run by
   the master (streaming its CSV) and by the plain 20-line fmpy loop (getReal/setReal per
   connection, rows kept in memory); and the same for a chain of cheap oscillators, where FMU
   work is small and the master's own per-step cost shows.

Prints medians over ``--repeats`` runs, all measured now on this machine.
Usage: python benchmarks/cosim.py [--stop 3.5] [--repeats 5]
"""
from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path

from fmpy import extract
from fmpy.fmi2 import FMU2Slave

from deltafmi.cosim.errors import ScenarioError
from deltafmi.cosim.master import Master
from deltafmi.cosim.resolve import System, resolve_system
from deltafmi.cosim.scenario import load_scenario, parse_scenario

ROOT = Path(__file__).resolve().parents[1]
FLAGSHIP = ROOT / "scenarios" / "delta_tracking.yaml"
CHAIN = """\
experiment: {stop: 1.0, step: 1.0e-3}
master: {algorithm: jacobi}
components:
  a: {source: fmu_src/oscillator.py, interface: CS}
  b: {source: fmu_src/oscillator.py, interface: CS}
  c: {source: fmu_src/oscillator.py, interface: CS}
connections:
  - {from: a.energy, to: b.F, factor: 0.05}
  - {from: b.energy, to: c.F, factor: 0.05}
outputs: [a.energy, b.energy, c.energy, b.F, c.F]
"""


def plain_loop(system: System, stop: float) -> float:
    """Wall seconds of the textbook Jacobi loop over fmpy's FMU2Slave for ``system``."""
    slaves, start, h = {}, system.scenario.experiment.start, system.scenario.experiment.step
    for c in system.components:
        md = c.info.md
        s = slaves[c.name] = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(c.fmu)), instanceName=c.name,
                                       modelIdentifier=md.coSimulation.modelIdentifier)
        s.instantiate()
        s.setupExperiment(tolerance=c.spec.solver.get("rtol"), startTime=start, stopTime=stop)  # as the master
        for port, value in c.start_values:
            {"Real": s.setReal, "Integer": s.setInteger, "Boolean": s.setBoolean, "String": s.setString}[port.type](
                [port.vr], [value])
        s.enterInitializationMode()
    for l in system.init_links:
        slaves[l.target.component].setReal([l.target.vr], [l.factor * slaves[l.source.component].getReal(
            [l.source.vr])[0] + l.offset])
    for s in slaves.values():
        s.exitInitializationMode()
    wall = time.perf_counter()
    rows = []
    for k in range(int(round((stop - start) / h))):
        values = [l.factor * slaves[l.source.component].getReal([l.source.vr])[0] + l.offset for l in system.links]
        for l, v in zip(system.links, values):
            slaves[l.target.component].setReal([l.target.vr], [v])
        for s in slaves.values():
            s.doStep(start + k * h, h)
        rows.append([start + (k + 1) * h] + [slaves[p.component].getReal([p.vr])[0] for p in system.recorded
                                             if p.type == "Real"])
    wall = time.perf_counter() - wall
    for s in slaves.values():
        s.terminate()
        s.freeInstance()
    return wall


def master_run(system: System, stop: float, out: Path, algorithm: str | None = None):
    """Summary of a master run."""
    return Master(system, result=out, stop=stop, algorithm=algorithm).run()


def time_shares(system: System, stop: float, out: Path) -> str:
    """Wall time per unit (its steps and reads) and the rest (the master itself), and RHS calls."""
    from deltafmi.cosim.me_integrator import ModelExchangeUnit
    from deltafmi.cosim.units import CoSimulationUnit, Unit

    spent: dict = {}
    originals = {(cls, name): cls.__dict__[name] for cls, name in
                 [(CoSimulationUnit, "do_step"), (ModelExchangeUnit, "do_step"), (Unit, "fetch"),
                  (ModelExchangeUnit, "_rhs")]}

    def timed(function, key):
        def wrapper(unit, *args):
            begin = time.perf_counter()
            try:
                return function(unit, *args)
            finally:
                entry = spent.setdefault((unit.name, key), [0.0, 0])
                entry[0] += time.perf_counter() - begin
                entry[1] += 1
        return wrapper

    for (cls, name), function in originals.items():
        setattr(cls, name, timed(function, name))
    try:
        summary = master_run(system, stop, out)
    finally:
        for (cls, name), function in originals.items():
            setattr(cls, name, function)
    loop = summary.wall_time - summary.setup_time
    units = {n: sum(v[0] for (u, k), v in spent.items() if u == n and k != "_rhs") for n, _ in spent}
    parts = [f"{name} {100 * t / loop:.0f} %" for name, t in units.items()]
    rhs = [f"{u}: {v[1] / summary.steps:.1f} RHS calls/step, {1e6 * v[0] / v[1]:.0f} us each"
           for (u, k), v in spent.items() if k == "_rhs"]
    return (f"time shares: {', '.join(parts)}, master itself {100 * (loop - sum(units.values())) / loop:.0f} %"
            f" (instrumented run); {'; '.join(rhs)}")


def with_plant_solver(system: System, solver: dict = {"rtol": 1e-8, "method": "bdf"}) -> System:
    """``system`` with the plant integrated by the given solver options."""
    components = [dataclasses.replace(c, spec=dataclasses.replace(c.spec, solver=dict(solver)))
                  if c.name == "plant" else c for c in system.components]
    return dataclasses.replace(system, components=components)


def all_cs(system: System) -> System:
    """``system`` with every component stepped as Co-Simulation."""
    components = [dataclasses.replace(c, interface="CS") for c in system.components]
    return dataclasses.replace(system, components=components)


def overhead(name: str, system: System, stop: float, repeats: int, out: Path) -> None:
    steps = int(round((stop - system.scenario.experiment.start) / system.scenario.experiment.step))
    runs = [master_run(system, stop, out, "jacobi") for _ in range(repeats)]
    ours = statistics.median(r.wall_time - r.setup_time for r in runs)  # stepping + CSV, as the loop
    loop = statistics.median(plain_loop(system, stop) for _ in range(repeats))
    print(f"  {name}: master {1e6 * ours / steps:8.1f} us/step, plain fmpy loop {1e6 * loop / steps:8.1f} "
          f"us/step -> master overhead {100 * (ours - loop) / loop:+.1f} % "
          f"({1e6 * (ours - loop) / steps:+.1f} us/step)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop", type=float, default=None,
                        help="simulated seconds per run (default: the flagship's own stop time)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    out = Path(tempfile.mkdtemp(prefix="deltafmi-bench-"))

    try:
        flagship = resolve_system(load_scenario(FLAGSHIP))
    except ScenarioError as exc:
        print(f"flagship cannot run: {exc.message}")
        flagship = None
    stop = args.stop or (flagship.scenario.experiment.stop if flagship else 1.0)
    print(f"1. flagship {FLAGSHIP.relative_to(ROOT)} (plant ME, Gauss-Seidel, 1 kHz), {stop} s:")
    if flagship is not None:
        for label, system in (("as written (plant rk4)", flagship),
                              ("baseline: plant on CVODE BDF rtol 1e-8", with_plant_solver(flagship))):
            runs = [master_run(system, stop, out / "flagship.csv") for _ in range(args.repeats)]
            wall = statistics.median(r.wall_time for r in runs)
            loop = statistics.median(r.wall_time - r.setup_time for r in runs)
            setup = statistics.median(r.setup_time for r in runs)
            print(f"  {label}: {runs[0].steps} steps in {wall:.3f} s (loading {setup:.3f} s): real-time "
                  f"factor {stop / wall:.2f}x end to end, {stop / loop:.2f}x stepping "
                  f"({1e6 * loop / runs[0].steps:.0f} us/step; target >= 10x)")
            print(f"    {time_shares(system, stop, out / 'shares.csv')}")

    print("2. master overhead against the plain 20-line fmpy Jacobi loop (target <= 20 %):")
    if flagship is not None:
        overhead("flagship, all CS", all_cs(flagship), stop, args.repeats, out / "cs.csv")
    chain = resolve_system(parse_scenario(CHAIN, ROOT / "scenarios" / "oscillator_chain.yaml"))
    overhead("3 oscillators, CS", chain, stop, args.repeats, out / "chain.csv")


if __name__ == "__main__":
    main()
