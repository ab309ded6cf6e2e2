"""Co-simulation master figures: real-time factor of the flagship, and the master's own overhead.

1. Flagship: scenarios/delta_tracking.yaml as written (plant ME through the master's rk4,
   controller and trajectory CS, Gauss-Seidel, 1 kHz): real-time factor end to end (loading the
   FMUs included) and of the stepping loop, where the time goes; and the same scenario with the
   plant on CVODE (BDF, rtol 1e-8) as the baseline.
2. Overhead: the same system with every component as Co-Simulation and Jacobi stepping, run by
   the master (streaming its CSV) and by the plain 20-line fmpy loop (getReal/setReal per
   connection, rows kept in memory); and the same for a chain of cheap oscillators, where FMU
   work is small and the master's own per-step cost shows.

3. The crossing of FMI (issue 16): the flagship's stepping against its in-process floor, the same
   physics in one Python loop with no FMI: the Python modules shipped in the DeltaRobot FMU
   (imported from that FMU's own ``resources/python``), the same classical RK4 (four
   ``state_derivative`` stages per 1 ms step, inputs held), the plant's recorded outputs from one
   ``evaluate_plant``, the same ``MinimumJerkPath.evaluate`` and ``DeltaController.step``; rows
   kept in memory; its samples are compared with the flagship's. Target: flagship / floor <= 1.5x.
   Since issue 26 the FMUs run C generated from those kernels (their Python methods with
   ``DELTAFMI_NATIVE=0``): the floor is then the Python the FMUs no longer run between events,
   and the master's own cost per FMU-step (issue 26: <= 1 us) is the figure that matters here;
   benchmarks/native.py compares the flagship with a C transcription.
   Then each piece as the master runs it (its C loop timing its own fmi2 calls along the real run)
   against the same piece timed inside the floor's loop: the plant's step (rk4 + completed step
   + outputs read) against four stages plus ``evaluate_plant``, trajectory fmi2DoStep + outputs
   read against ``path.evaluate``, controller inputs set + fmi2DoStep + outputs read against
   ``ctl.step`` (targets <= 1.5x); and one plant right-hand side (fmi2SetTime +
   fmi2SetContinuousStates + fmi2GetDerivatives, looped in C by the master's Runge-Kutta kernel)
   against ``state_derivative`` on the same state (target: <= 1 us more). The master's own cost
   is its stepping less the time inside its units' fmi2 calls. Each round measures both sides
   back to back; ratios are medians of the rounds' ratios (the machine is shared).

Prints medians over ``--repeats`` runs, all measured now on this machine.
Usage: python benchmarks/cosim.py [--stop 3.5] [--repeats 5] [--only crossing]
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from fmpy import extract
from fmpy.fmi2 import FMU2Slave

from deltafmi import resolve_system
from deltafmi.master.scenario.system import System
from deltafmi.master.scenario.spec import load_scenario, parse_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.errors import ScenarioError

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


def unit_times(system: System, stop: float, out: Path) -> tuple:
    """One instrumented master run: its summary, and wall seconds per unit of each unit's own
    calls (pull, do_step, fetch: timed in Python, or by the master's C loop where it runs the
    steps) and of each ME unit's right-hand sides, with their counts."""
    from deltafmi.master.stepping.me_integrator import ModelExchangeUnit
    from deltafmi.master.stepping.units import CoSimulationUnit, Unit

    spent: dict = {}
    depth = [0]  # an ME unit's pull calls Unit.pull: count the outer call only
    originals = {(cls, name): cls.__dict__[name] for cls, name in
                 [(CoSimulationUnit, "do_step"), (ModelExchangeUnit, "do_step"), (Unit, "fetch"), (Unit, "pull"),
                  (ModelExchangeUnit, "pull"), (ModelExchangeUnit, "_rhs")]}

    def timed(function, key):
        def wrapper(unit, *args):
            depth[0] += 1
            begin = time.perf_counter()
            try:
                return function(unit, *args)
            finally:
                depth[0] -= 1
                if depth[0] == 0 or key == "_rhs":
                    entry = spent.setdefault((unit.name, key), [0.0, 0])
                    entry[0] += time.perf_counter() - begin
                    entry[1] += 1
        return wrapper

    for (cls, name), function in originals.items():
        setattr(cls, name, timed(function, name))
    try:
        summary, in_c = timed_master_run(system, stop, out)
    finally:
        for (cls, name), function in originals.items():
            setattr(cls, name, function)
    for name, seconds in in_c.items():
        spent[(name, "in C")] = [seconds, 0]
    return summary, spent


def time_shares(system: System, stop: float, out: Path) -> str:
    """Wall time per unit (its steps and reads) and the rest (the master itself), and RHS calls."""
    summary, spent = unit_times(system, stop, out)
    loop = summary.stepping_time
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
    ours = statistics.median(r.stepping_time for r in runs)  # stepping + CSV, as the loop
    loop = statistics.median(plain_loop(system, stop) for _ in range(repeats))
    print(f"  {name}: master {1e6 * ours / steps:8.1f} us/step, plain fmpy loop {1e6 * loop / steps:8.1f} "
          f"us/step -> master overhead {100 * (ours - loop) / loop:+.1f} % "
          f"({1e6 * (ours - loop) / steps:+.1f} us/step)")


# --- 3. the in-process floor --------------------------------------------------------------------
@contextlib.contextmanager
def _fmu_python(unzip_dir: str):
    """Inside the block ``import deltafmi...`` resolves to an FMU's own copy (its Python modules)."""
    python_dir = str(Path(unzip_dir) / "resources" / "python")
    ours = lambda name: name == "deltafmi" or name.startswith("deltafmi.")  # noqa: E731
    saved = {name: sys.modules.pop(name) for name in [n for n in sys.modules if ours(n)]}
    sys.path.insert(0, python_dir)
    try:
        yield
    finally:
        sys.path.remove(python_dir)
        for name in [n for n in sys.modules if ours(n)]:
            del sys.modules[name]
        sys.modules.update(saved)


class Floor:
    """The flagship's physics in one Python loop, no FMI: each component's kernels as shipped in
    its own FMU (an FMU carries only the modules its component reaches: the plant's has no
    controller)."""

    def __init__(self, system: System, unzip_dir: Path) -> None:
        by_name = {c.name: c for c in system.components}

        def shipped(component: str, module: str):
            with _fmu_python(extract(str(by_name[component].fmu), unzipdir=str(Path(unzip_dir) / component))):
                return importlib.import_module(module)

        self.delta = shipped("plant", "deltafmi.physics.delta")
        self.control = shipped("controller", "deltafmi.physics.delta.control")
        self.trajectory = shipped("trajectory", "deltafmi.physics.delta.trajectory")
        self.system = system
        given = {c.name: {p.name: p.value for p in c.spec.parameters} for c in system.components}
        self.given = given
        self.h = system.scenario.experiment.step
        self.start = system.scenario.experiment.start

    def fresh(self):
        """(plant params, pole, x0, controller, path) at the scenario's start."""
        delta, given = self.delta, self.given
        fields = set(delta.DeltaParams.__dataclass_fields__)
        plant = delta.DeltaParams(**{k: v for k, v in given["plant"].items() if k in fields})
        pole = float(given["plant"].get("pole", 5.0))
        q0 = delta.inverse_kinematics(plant, given["plant"].get("z0", [0.0, 0.0, -1.0]))
        x0 = [float(v) for v in q0] + [0.0] * 9
        c = given["controller"]
        model = delta.DeltaParams(**{k: v for k, v in c.items() if k in fields})
        ctl = self.control.DeltaController(model, pole=float(c.get("pole", 7.0)),
                                           sample_period=float(c.get("sample_period", 1e-3)),
                                           feedforward=bool(c.get("feedforward", True)))
        t = given["trajectory"]
        n = int(t["n_waypoints"])
        path = self.trajectory.MinimumJerkPath(list(zip(t["wp_x"][:n], t["wp_y"][:n], t["wp_z"][:n])),
                                               t["wp_T"][:n - 1], dwell=float(t.get("dwell", 0.2)),
                                               t0=float(t.get("t_start", 0.0)))
        return plant, pole, x0, ctl, path

    def plant_step(self, plant, pole: float, x: list, u) -> tuple:
        """One classical RK4 step (the master's stage structure), then the plant's outputs."""
        derivative, h = self.delta.state_derivative, self.h
        half, sixth, f = 0.5 * h, h / 6.0, (0.0, 0.0, 0.0)
        k1 = derivative(plant, x, u, f, pole)
        k2 = derivative(plant, [a + half * b for a, b in zip(x, k1)], u, f, pole)
        k3 = derivative(plant, [a + half * b for a, b in zip(x, k2)], u, f, pole)
        k4 = derivative(plant, [a + h * b for a, b in zip(x, k3)], u, f, pole)
        x = [a + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4) for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4)]
        return x, self.delta.evaluate_plant(plant, x[:9], x[9:], u, f, pole)

    def run(self, steps: int, timed: bool = False) -> tuple:
        """Wall seconds of ``steps`` steps, the rows (time, z, zd, r, u, status, residual), and
        with ``timed`` the seconds spent per piece (trajectory, plant, controller; the loop then
        pays for the clock)."""
        plant, pole, x, ctl, path = self.fresh()
        plant_step, evaluate_plant = self.plant_step, self.delta.evaluate_plant
        h, t0 = self.h, self.start
        f, force = [0.0, 0.0, 0.0], (0.0, 0.0, 0.0)
        rows = np.empty((steps + 1, 15))
        # initialization: the controller samples once at the start (the FMUs do the same)
        r, rd, rdd = path.evaluate(t0)
        q, v = x[:9], x[9:]
        u = ctl.step(q[0::3], v[0::3], r.tolist(), rd.tolist(), rdd.tolist(), force, 0.0)
        ev = evaluate_plant(plant, q, v, u, f, pole)
        rows[0] = [t0, *ev.z, *ev.zd, *r, *u, ctl.status, ev.residual]
        spent = {"trajectory": 0.0, "plant": 0.0, "controller": 0.0}
        clock = time.perf_counter
        wall = clock()
        if not timed:
            for k in range(steps):
                t = t0 + (k + 1) * h
                r, rd, rdd = path.evaluate(t)
                x, ev = plant_step(plant, pole, x, u)
                q, v = x[:9], x[9:]
                if k > 0:  # the sample at the start was taken at initialization
                    u = ctl.step(q[0::3], v[0::3], r.tolist(), rd.tolist(), rdd.tolist(), force, 0.0)
                rows[k + 1] = [t, *ev.z, *ev.zd, *r, *u, ctl.status, ev.residual]
            return clock() - wall, rows, spent
        for k in range(steps):
            t = t0 + (k + 1) * h
            a = clock()
            r, rd, rdd = path.evaluate(t)
            b = clock()
            x, ev = plant_step(plant, pole, x, u)
            c = clock()
            q, v = x[:9], x[9:]
            if k > 0:
                u = ctl.step(q[0::3], v[0::3], r.tolist(), rd.tolist(), rdd.tolist(), force, 0.0)
            d = clock()
            spent["trajectory"] += b - a
            spent["plant"] += c - b
            spent["controller"] += d - c
            rows[k + 1] = [t, *ev.z, *ev.zd, *r, *u, ctl.status, ev.residual]
        return clock() - wall, rows, spent


def rhs_pair(system: System, floor: Floor, out: Path, calls: int = 500, bursts: int = 9) -> tuple:
    """Microseconds of one plant right-hand side through FMI (fmi2SetTime +
    fmi2SetContinuousStates + fmi2GetDerivatives looped in C by the master's Runge-Kutta kernel,
    as its rk4 does, Euler steps of 1e-9 s from the plant's initial state) and in-process
    (``state_derivative`` on the same state): medians of ``bursts`` bursts of ``calls`` each,
    the two sides alternating (one call takes a few us: a single burst is at the mercy of the
    shared machine's slow spells)."""
    from deltafmi.master.stepping.explicit_rk import ExplicitRungeKutta

    master = Master(system, result=out)
    master.open()
    try:
        plant = next(u for u in master.units if u.name == "plant")
        x, t0, tiny = plant.solver.x.copy(), master.start, 1e-9
        euler = ExplicitRungeKutta(plant.fmu, x, t0, "euler", max_step=tiny)
        params, pole, _, _, _ = floor.fresh()
        derivative, xl, f = floor.delta.state_derivative, [float(v) for v in x], (0.0, 0.0, 0.0)
        u = [float(v) for v in master.buses["Real"][plant.inputs[0].index]]
        fmi, direct = [], []
        for burst in range(1, bursts + 1):
            begin = time.perf_counter()
            euler.advance(t0 + (burst * calls - 0.5) * tiny)
            fmi.append(time.perf_counter() - begin)
            begin = time.perf_counter()
            for _ in range(calls):
                derivative(params, xl, u, f, pole)
            direct.append(time.perf_counter() - begin)
    finally:
        master.close()
    return 1e6 * statistics.median(fmi) / calls, 1e6 * statistics.median(direct) / calls


def timed_master_run(system: System, stop: float, out: Path) -> tuple:
    """A master run whose C loop times its FMI calls: (summary, {unit: seconds in its calls})."""
    from deltafmi.master.stepping import master as master_module
    loops = []

    class TimedLoop(master_module.NativeLoop):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.timed()
            loops.append(self)

    master_module.NativeLoop = TimedLoop
    try:
        summary = master_run(system, stop, out)
    finally:
        master_module.NativeLoop = TimedLoop.__bases__[0]
    spent: dict = {}
    for loop in loops:
        for name, seconds in loop.unit_seconds().items():
            spent[name] = spent.get(name, 0.0) + seconds
    return summary, spent


def crossing(system: System, stop: float, repeats: int, out: Path) -> None:
    """Section 3: flagship stepping against the in-process floor, and per piece; every figure
    a median over ``repeats`` rounds, each round measuring both sides back to back (the ratios
    are medians of the rounds' ratios, so a busy spell on the shared machine hits both sides)."""
    steps = int(round((stop - system.scenario.experiment.start) / system.scenario.experiment.step))
    floor = Floor(system, out / "floor-fmu")
    _, reference, _ = floor.run(steps)
    fig: dict = {}

    def add(key: str, fmi: float, direct: float) -> None:
        fig.setdefault(key, []).append((fmi, direct, fmi / direct))
    for _ in range(repeats):
        run = master_run(system, stop, out / "crossing.csv")
        wall, _, _ = floor.run(steps)
        add("flagship", 1e6 * run.stepping_time / run.steps, 1e6 * wall / steps)
        timed, in_units = timed_master_run(system, stop, out / "timed.csv")
        if not in_units:
            raise SystemExit("the flagship did not run in the master's C loop")
        wall, _, spent = floor.run(steps, timed=True)
        for name in ("trajectory", "plant", "controller"):
            add(name, 1e6 * in_units[name] / timed.steps, 1e6 * spent[name] / steps)
        fig.setdefault("own", []).append(1e6 * (timed.stepping_time - sum(in_units.values())) / timed.steps)
        add("rhs", *rhs_pair(system, floor, out / "rhs.csv"))
    from deltafmi.master.results.csv_file import read_csv
    _, rows = read_csv(out / "crossing.csv")
    gap = float(np.max(np.abs(rows - reference)[:, 1:]))
    med = lambda key, i: statistics.median(v[i] for v in fig[key])  # noqa: E731
    print(f"  flagship stepping {med('flagship', 0):6.1f} us/step, in-process floor {med('flagship', 1):6.1f} us/step "
          f"(the Python modules the FMUs carry; "
          f"its samples within {gap:.1e} of the flagship's) -> ratio {med('flagship', 2):.2f}x (target <= 1.5x)")
    print(f"  {'piece, us per step (per call for the RHS)':60s} {'FMI':>7s} {'direct':>7s} {'ratio':>6s} {'over':>7s}")
    for key, label in (("rhs", "plant RHS: SetTime + SetContinuousStates + GetDerivatives"),
                       ("plant", "plant: rk4 (4 RHS) + CompletedIntegratorStep + GetReal"),
                       ("trajectory", "trajectory: DoStep + GetReal"),
                       ("controller", "controller: SetReal + DoStep + GetReal")):
        print(f"  {label:60s} {med(key, 0):7.2f} {med(key, 1):7.2f} {med(key, 2):6.2f} "
              f"{med(key, 0) - med(key, 1):+7.2f}")
    own, units = statistics.median(fig["own"]), len(system.components)
    print(f"  master's own cost: stepping less the time in its units' FMI calls (timed by its C loop) = "
          f"{own:.1f} us/step (CSV rows included), {own / units:.2f} us per FMU-step ({units} FMUs)")
    print("  targets: RHS overhead <= 1 us; trajectory, controller <= 1.5x; the master <= 1 us per FMU-step "
          "(issue 26)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop", type=float, default=None,
                        help="simulated seconds per run (default: the flagship's own stop time)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--only", choices=["crossing"], help="run only section 3 (the floor and the pieces)")
    args = parser.parse_args()
    out = Path(tempfile.mkdtemp(prefix="deltafmi-bench-"))

    try:
        flagship = resolve_system(load_scenario(FLAGSHIP))
    except ScenarioError as exc:
        print(f"flagship cannot run: {exc.message}")
        flagship = None
    stop = args.stop or (flagship.scenario.experiment.stop if flagship else 1.0)
    if args.only == "crossing":
        if flagship is not None:
            print(f"3. crossing FMI: flagship against the same physics in-process, {stop} s:")
            crossing(flagship, stop, args.repeats, out)
        return
    print(f"1. flagship {FLAGSHIP.relative_to(ROOT)} (plant ME, Gauss-Seidel, 1 kHz), {stop} s:")
    if flagship is not None:
        for label, system in (("as written (plant rk4)", flagship),
                              ("baseline: plant on CVODE BDF rtol 1e-8", with_plant_solver(flagship))):
            runs = [master_run(system, stop, out / "flagship.csv") for _ in range(args.repeats)]
            wall = statistics.median(r.wall_time for r in runs)
            loop = statistics.median(r.stepping_time for r in runs)
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
    if flagship is not None:
        print(f"3. crossing FMI: flagship against the same physics in-process, {stop} s:")
        crossing(flagship, stop, args.repeats, out)


if __name__ == "__main__":
    main()
