"""Study throughput: a loop of ``deltafmi run`` processes against ``deltafmi sweep`` on Dask.

The cases are flagship runs (scenarios/studies/gain_payload.yaml: pick-and-place, 3.5 s
simulated, outer-loop pole x unknown payload), spread over its grid. Measured in one run, on this
machine, all with the same cases:

1. baseline: a sequential loop of ``deltafmi run case<i>.yaml`` processes (the cases exported
   as plain scenarios; each process starts Python, loads and instantiates the FMUs, runs);
2. the sweep on a LocalCluster of 1 worker process and of 2 (the cluster already started: its
   start-up is printed apart; FMU shipping, loading and every case's metrics included);
3. the per-case overhead of the sweep against the simulation itself (the master's stepping loop
   on the worker): reset + initialization, and everything else (Dask, metrics, transfer); and in
   all, the sweep's time per case minus those cases' stepping (target <= 1 ms); the CPU time of
   the same on a worker without Dask (this process, thread CPU time: what a loaded machine moves
   least), with and without FMU state snapshots, and with each case's wiring built anew instead of
   taken over from the case before; and the CPU time per case of a whole 1-worker
   sweep (worker process, client and scheduler) minus the same cases' stepping in that worker,
   with results streamed per case and per task;
4. the scaling from 1 to 2 workers, against what two plain processes running the same cases at
   once (no Dask) get done on this machine against one alone: the hardware's own ceiling.

Targets on a 2-core machine: 2 workers >= 1.8x one worker, per-case overhead <= 5 % of a
flagship case, sweep >= 3x the loop of processes.

Usage: python benchmarks/sweep.py [--cases 24] [--repeats 1]
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Dict, List, NamedTuple, Tuple

from deltafmi.apps.studies.cases import Case
from deltafmi.apps.studies.driver import dask_client, open_store, run_study
from deltafmi.apps.studies.export import case_scenario
from deltafmi.apps.studies.plan import PlannedStudy, plan_study
from deltafmi.apps.studies.spec import load_study

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "scenarios" / "studies" / "gain_payload.yaml"
DELTAFMI = Path(sys.executable).parent / "deltafmi"


def spread(cases: List[Case], n: int) -> List[Case]:
    """``n`` cases evenly spread over the study's cases."""
    step = max(1, len(cases) // n)
    return cases[::step][:n]


def process_loop(planned: PlannedStudy, cases: List[Case], folder: Path) -> float:
    """Wall seconds of running every case as its own ``deltafmi run`` process, one after another."""
    files = []
    for case in cases:
        path = folder / f"case{case.id}.yaml"
        path.write_text(case_scenario(planned, case))
        files.append(path)
    subprocess.run([str(DELTAFMI), "run", str(files[0]), "-q", "-o", str(folder / "warm.csv")], check=True,
                   capture_output=True)  # builds anything the interpreter of deltafmi needs, untimed
    wall = time.perf_counter()
    for path in files:
        subprocess.run([str(DELTAFMI), "run", str(path), "-q", "-o", str(path.with_suffix(".csv"))], check=True,
                       capture_output=True)
    return time.perf_counter() - wall


# one flagship case run in one plain process, again and again (after an untimed first run)
WORKLOAD = """
import sys, tempfile, time
from pathlib import Path
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
system = resolve_system(load_scenario(Path(sys.argv[1])))
out = Path(tempfile.mkdtemp()) / "run.csv"
Master(system, result=out).run()
start = time.perf_counter()
for _ in range(int(sys.argv[2])):
    Master(system, result=out).run()
print(time.perf_counter() - start)
"""


def machine_scaling(case_file: Path, runs: int = 4) -> float:
    """What two processes running flagship cases at once get done against one alone, with no Dask
    (2.0 on two free physical cores; less where the two cores share one physical core or the
    host is busy): the ceiling of any 2-worker scaling of this workload on this machine."""
    def at_once(n: int) -> float:
        procs = [subprocess.Popen([sys.executable, "-c", WORKLOAD, str(case_file), str(runs)], stdout=subprocess.PIPE,
                                  text=True) for _ in range(n)]
        return max(float(p.communicate()[0].split()[-1]) for p in procs)
    alone = at_once(1)
    return 2 * alone / at_once(2)


class SweepRun(NamedTuple):
    """One sweep on a LocalCluster (seconds)."""

    startup: float  #: the cluster's start-up (not in ``wall``)
    wall: float  #: the sweep, registration to wrap-up
    rows: List[dict]  #: the result rows
    registration: float  #: the study registered on the workers
    wrapup: float  #: after the last result reached the client


def sweep(planned: PlannedStudy, cases: List[Case], workers: int, folder: Path, streamed: bool = True) -> SweepRun:
    """The cases on a LocalCluster of ``workers``; ``streamed``: each case's result sent to the
    client as it finishes (the default), else only with its task's (the earlier way, with batches
    of at most MAX_BATCH cases)."""
    from deltafmi.apps.studies import driver

    driver.STREAM_RESULTS = streamed
    started = time.perf_counter()
    last = 0.0  # when the last result reached the client

    def arrived(result: object) -> None:
        nonlocal last
        last = time.perf_counter()

    with dask_client(workers=workers) as client:
        client.wait_for_workers(workers)
        startup = time.perf_counter() - started
        store = open_store(planned, folder / f"sweep{workers}.parquet", timeseries=False)
        todo = store.open(cases, fresh=True)
        wall = time.perf_counter()
        report = run_study(planned, store, todo, scheduler=client.scheduler.address,
                           on_result=arrived)
        end = time.perf_counter()
        store.close()
    driver.STREAM_RESULTS = True
    errors = [row["error"] for row in store.rows.values() if row["status"] != "ok"]
    assert report.failed == 0, f"{report.failed} benchmark case(s) failed: {errors[:3]}"
    return SweepRun(startup, end - wall, [store.rows[c.key] for c in cases], report.setup_time, end - last)


def _time_stepping() -> None:
    """In a worker process: count the thread CPU time of the master's stepping loop (the cases'
    ``Master._run_fixed``) in ``Master.bench_stepping``."""
    from deltafmi.master.stepping.master import Master

    if "bench_stepping" in vars(Master):
        return
    original = Master._run_fixed

    def timed(master: Master) -> None:
        start = time.thread_time()
        try:
            original(master)
        finally:
            Master.bench_stepping += time.thread_time() - start  # type: ignore[attr-defined]

    Master.bench_stepping = 0.0  # type: ignore[attr-defined]
    Master._run_fixed = timed  # type: ignore[method-assign]


def _worker_clocks() -> Tuple[float, float]:
    """In a worker process: its CPU time and its stepping's so far (see :func:`_time_stepping`)."""
    from deltafmi.master.stepping.master import Master

    return time.process_time(), getattr(Master, "bench_stepping", 0.0)


def sweep_cpu(planned: PlannedStudy, cases: List[Case], streamed: bool = True) -> Dict[str, float]:
    """CPU milliseconds per case of a 1-worker sweep of ``cases``, from the first result (the first
    case loads the FMUs) to the last: the worker process (all its threads: the cases, Dask's
    messages and its own upkeep), this process (the client and the local scheduler), and the
    stepping of those cases in the worker (the master's loop, thread CPU time); what a loaded
    machine moves far less than wall time. ``streamed`` as for :func:`sweep`."""
    import cloudpickle

    from deltafmi.apps.studies import driver

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the worker cannot import this script
    marks: List[tuple] = []

    def mark(result: object) -> None:
        if not marks or len(marks) == 1 and done[0] == len(cases) - 1:
            (cpu, stepping), = client.run(_worker_clocks).values()
            marks.append((cpu, time.process_time(), stepping))
        done[0] += 1

    done = [0]
    driver.STREAM_RESULTS = streamed
    folder = Path(tempfile.mkdtemp(prefix="deltafmi-bench-cpu-"))
    try:
        with dask_client(workers=1) as client:
            client.wait_for_workers(1)
            client.run(_time_stepping)
            store = open_store(planned, folder / "cpu.parquet", timeseries=False)
            report = run_study(planned, store, store.open(cases, fresh=True), client=client, workers=1,
                               on_result=mark)
            store.close()
    finally:
        driver.STREAM_RESULTS = True
        shutil.rmtree(folder, ignore_errors=True)
    assert report.failed == 0 and len(marks) == 2, "a benchmark case failed"
    (worker0, client0, stepping0), (worker1, client1, stepping1) = marks
    n = len(cases) - 1
    return {"worker": 1e3 * (worker1 - worker0) / n, "client": 1e3 * (client1 - client0) / n,
            "stepping": 1e3 * (stepping1 - stepping0) / n}


def per_case(rows: List[dict], wall: float, once: float) -> Dict[str, float]:
    """Per-case figures of a 1-worker sweep of ``wall`` seconds, ``once`` of them registration and
    wrap-up: medians over the cases after the first (which loads the FMUs) of the simulation (the
    stepping loop), reset + initialization and the rest on the worker (case set-up, closing,
    metrics); and Dask plus the client: the time the worker spent outside the cases, per case."""
    first = max(rows, key=lambda r: r["setup_time"])
    steady = [r for r in rows if r is not first]
    # what a case costs the sweep beyond its own stepping: the sweep's time per case (its first
    # case, which loads the FMUs, left out) minus the stepping of the same cases, same run
    per_case_time = (wall - once - first["wall_time"]) / max(1, len(steady))
    return {"simulation": statistics.median(r["sim_time"] for r in steady),
            "overhead": per_case_time - statistics.fmean(r["sim_time"] for r in steady),
            "reset": statistics.median(r["setup_time"] for r in steady),
            "worker_rest": statistics.median(r["wall_time"] - r["setup_time"] - r["sim_time"] for r in steady),
            "dask": (wall - once - sum(r["wall_time"] for r in rows)) / len(rows),
            "load": first["setup_time"]}


def worker_cpu(planned: PlannedStudy, cases: List[Case], snapshots: bool = True,
               wiring: bool = True) -> Dict[str, float]:
    """CPU milliseconds per case (the thread's: a loaded machine moves it much less than wall
    time) of what a worker does for a case, the cases run one after another on a thread of this
    process on one FmuPool as a worker runs them (no Dask): the whole case, its stepping (the master's
    fixed-step loop) and the rest (reset, start values, initialization, wiring, metrics); medians
    over the cases after the first (which loads the FMUs). ``snapshots``: units whose
    initialization repeats the case before's are restored from an FMU state snapshot (the
    default), else every unit is reset and initialized. ``wiring``: a case on the instances of the
    case before takes over its buses and input/output wiring (the default), else wires anew."""
    from deltafmi.apps.studies.pool import FmuPool
    from deltafmi.apps.studies.runner import CaseTemplate, run_case
    from deltafmi.master.stepping.master import Master

    stepping: List[float] = []
    original = Master._run_fixed

    def timed(master: Master) -> None:  # the stepping's CPU time, around the master's own loop
        start = time.thread_time()
        try:
            original(master)
        finally:
            stepping.append(time.thread_time() - start)

    template = CaseTemplate(planned.plan, planned.fmu_files)
    if not wiring:
        template.wirings = None  # type: ignore[assignment]
    pool = FmuPool(snapshots=snapshots)
    whole: List[float] = []
    failures: List[str] = []

    def work() -> None:  # on a thread of its own, as a Dask worker runs its tasks (no signal handlers)
        for case in cases:
            start = time.thread_time()
            result = run_case(template, pool, case.id, case.values)
            whole.append(time.thread_time() - start)
            if result.status != "ok":
                failures.append(result.error)

    Master._run_fixed = timed  # type: ignore[method-assign]
    try:
        thread = threading.Thread(target=work)
        thread.start()
        thread.join()
    finally:
        Master._run_fixed = original  # type: ignore[method-assign]
        pool.close()
    assert not failures and len(whole) == len(cases), failures[:3]
    rest = [w - s for w, s in zip(whole[1:], stepping[1:])]
    return {"case": 1e3 * statistics.median(whole[1:]), "stepping": 1e3 * statistics.median(stepping[1:]),
            "rest": 1e3 * statistics.median(rest), "restored": pool.restored / max(1, len(cases) - 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=24, help="flagship cases per measurement (the studies in "
                        "scenarios/studies have 91 and 200)")
    parser.add_argument("--repeats", type=int, default=1, help="repeat each measurement, report medians")
    args = parser.parse_args()
    planned = plan_study(load_study(STUDY))
    cases = spread(planned.cases, args.cases)
    n = len(cases)
    folder = Path(tempfile.mkdtemp(prefix="deltafmi-bench-sweep-"))
    try:
        print(f"{n} flagship cases of {STUDY.relative_to(ROOT)} ({planned.system.scenario.experiment.stop} s "
              f"simulated each), {args.repeats} repeat(s), medians:")
        loop = statistics.median(process_loop(planned, cases, folder) for _ in range(args.repeats))
        print(f"  loop of `deltafmi run` processes: {n} cases in {loop:.2f} s: {n / loop:.2f} cases/s "
              f"({loop / n:.3f} s per case)")
        # 1 and 2 workers and the machine's own ceiling alternate in each repeat, and the ratios
        # are medians of the repeats' ratios: a slow spell of the shared host hits every side
        runs: Dict[int, List[SweepRun]] = {1: [], 2: []}
        ceilings, scalings = [], []
        for _ in range(args.repeats):
            for workers in (1, 2):
                runs[workers].append(sweep(planned, cases, workers, folder))
            scalings.append(runs[1][-1].wall / runs[2][-1].wall)
            ceilings.append(machine_scaling(folder / f"case{cases[0].id}.yaml"))
        best = {}
        for workers in (1, 2):
            startup = statistics.median(r.startup for r in runs[workers])
            wall = statistics.median(r.wall for r in runs[workers])
            best[workers] = min(runs[workers], key=lambda r: r.wall)
            print(f"  sweep, {workers} worker{'s' * (workers > 1)}: {n} cases in {wall:.2f} s: {n / wall:.2f} cases/s "
                  f"= {loop / wall:.2f}x the loop (target >= 3x); cluster start-up {startup:.2f} s apart "
                  f"({n / (wall + startup):.2f} cases/s with it)")
        scaling, ceiling = statistics.median(scalings), statistics.median(ceilings)
        # without registration, wrap-up and the first case's loading of the FMUs (in parallel on the workers)
        steady_rate = {w: n / (best[w].wall - best[w].registration - best[w].wrapup
                               - max(r["setup_time"] for r in best[w].rows)) for w in (1, 2)}
        print(f"  scaling: 2 workers {scaling:.2f}x one worker (target >= 1.8x), efficiency {scaling / 2:.0%}; "
              f"without the once-per-sweep costs below: "
              f"{steady_rate[2] / steady_rate[1]:.2f}x; the machine itself: two processes running flagship "
              f"cases at once (no Dask) do {ceiling:.2f}x one alone, so the sweep gets "
              f"{scaling / ceiling:.0%} of what two workers can get here")
        stats = per_case(best[1].rows, best[1].wall, best[1].registration + best[1].wrapup)
        steady = stats["reset"] + stats["worker_rest"] + stats["dask"]
        print(f"  per case, 1 worker: simulation {stats['simulation']:.3f} s; overhead {1e3 * steady:.1f} ms = "
              f"{steady / stats['simulation']:.1%} of it (target <= 5 %): reset + initialization "
              f"{1e3 * stats['reset']:.1f} ms, case set-up + metrics + closing on the worker "
              f"{1e3 * stats['worker_rest']:.1f} ms, Dask and the client {1e3 * stats['dask']:.1f} ms")
        print(f"  per-case overhead, 1 worker (the sweep's time per case minus the same cases' stepping, same run): "
              f"{1e3 * stats['overhead']:.2f} ms (target <= 1 ms; load average {os.getloadavg()[0]:.1f} "
              f"on {os.cpu_count()} cores)")
        # without snapshots, with, and with the wiring built anew, alternating: the same spell of
        # load hits all three
        triples = [(worker_cpu(planned, cases, snapshots=False), worker_cpu(planned, cases),
                    worker_cpu(planned, cases, wiring=False)) for _ in range(5)]
        cpu = {k: statistics.median(t[1][k] for t in triples) for k in triples[0][1]}
        plain = {k: statistics.median(t[0][k] for t in triples) for k in triples[0][0]}
        anew = {k: statistics.median(t[2][k] for t in triples) for k in triples[0][2]}
        units = len(planned.system.components)
        print(f"  per-case CPU on a worker (no Dask, a thread of this process, medians of 5 x {n - 1} cases): {cpu['case']:.2f} ms "
              f"a case, of which stepping {cpu['stepping']:.2f} ms; the rest (reset or snapshot, start values, "
              f"initialization, wiring, metrics) {cpu['rest']:.2f} ms, {cpu['restored']:.1f} of the {units} units "
              f"restored from a snapshot per case; every unit reset and initialized "
              f"(no snapshots, same run): {plain['rest']:.2f} ms, {plain['rest'] / cpu['rest']:.2f}x; "
              f"every case wired anew (same run): {anew['rest']:.2f} ms, {anew['rest'] / cpu['rest']:.2f}x")
        # the whole sweep's CPU, results streamed per case and per task as before, alternating
        sides: Dict[bool, List[Dict[str, float]]] = {False: [], True: []}
        for _ in range(3):
            for streamed in (False, True):
                sides[streamed].append(sweep_cpu(planned, cases, streamed))
        total = {s: statistics.median(r["worker"] + r["client"] for r in sides[s]) for s in sides}
        worker = {s: statistics.median(r["worker"] for r in sides[s]) for s in sides}
        # around the stepping: the sweep's CPU minus the same cases' stepping in the same worker
        around = {s: statistics.median(r["worker"] + r["client"] - r["stepping"] for r in sides[s]) for s in sides}
        print(f"  per-case CPU of a 1-worker sweep, first result to last (worker process + client and scheduler, "
              f"medians of 3 x {n - 1} cases): {total[True]:.2f} ms (worker {worker[True]:.2f}); around the stepping "
              f"(the same cases' stepping in the same worker taken off) {around[True]:.2f} ms (target <= 1 ms); "
              f"results per task as before (same run): {total[False]:.2f} ms (worker {worker[False]:.2f}), around "
              f"the stepping {around[False]:.2f} ms, {around[False] / around[True]:.2f}x "
              f"(load average {os.getloadavg()[0]:.1f})")
        print(f"  once per sweep: registration (FMUs shipped, stored, scenario resolved on the worker) "
              f"{1e3 * best[1].registration:.0f} ms; wrap-up (study removed from the workers, final tables) "
              f"{1e3 * best[1].wrapup:.0f} ms; per worker, its first case loads and instantiates the FMUs: "
              f"{1e3 * stats['load']:.0f} ms (the loop of processes pays both in every case)")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
