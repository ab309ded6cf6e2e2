"""Issue 26's baseline: the flagship against a C transcription of its own kernels.

benchmarks/native/flagship.c transcribes what the flagship (scenarios/delta_tracking.yaml)
computes, in the order the Python computes it: the DeltaRobot's state derivative (mass matrix,
constraint Jacobian, multipliers by the 6x6 Schur complement, Baumgarte) and outputs, the
DeltaController's sample (Newton forward kinematics warm-started, control Jacobian, inverse
dynamics with gravity, PID with feed-forward and anti-windup, the half-sample lead, saturation),
the Trajectory's minimum-jerk path, and the master's classical RK4 with the inputs held, closed
in the master's Gauss-Seidel order (as benchmarks/cosim.py's in-process floor). Its closed loop
reproduces the flagship's CSV bit for bit (checked here at every run, and by
tests/builder/test_native_baseline.py).

It is compiled here with ``cc -std=c99 -O2`` (no -march=native: the binary a user would build)
into a temporary directory and loaded with ctypes. Figures, medians over ``--repeats`` rounds,
both sides measured in the same run (the machine may be shared: read the ratios, not the
microseconds):

- C closed-loop step: a whole flagship run in C (3.5 s, rows kept in memory) / steps;
- C plant derivative: one state derivative on the flagship's state at a few instants, called in
  bursts by a C loop; C controller sample: the flagship's samples replayed (its recorded inputs)
  through a fresh C controller;
- deltafmi: the flagship stepping through FMI (the master, as benchmarks/cosim.py times it), with
  the FMUs' compiled kernels (C generated from the Python, deltafmi/builder/codegen) and, for the
  before/after, on their Python methods (``DELTAFMI_NATIVE=0``: the Python the FMU carries, what
  every step ran before the kernels; the two runs' CSVs are compared bit for bit); the plant
  derivative through FMI (fmi2SetTime + fmi2SetContinuousStates + fmi2GetDerivatives in C,
  cosim.py's rhs_pair) and the Python path's (``state_derivative`` of the FMU's Python modules,
  in-process); the controller sample through FMI (inputs set + fmi2DoStep + outputs read, timed
  by the master's C loop) and the Python path's (``DeltaController.step``, in-process, replaying
  the same samples as the C controller);
- the flagship's CPU time, of the whole process and of the stepping thread alone (the rows become
  text on a thread of C the C loop hands them to while it steps: where that thread has a core to
  itself, the wall time comes to the stepping thread's CPU time and the last rows' text), the
  stepping thread's split into its time in the master's C loop (handing the rows over included)
  and the Python around it, the process's CPU and wall time with the text
  made on the stepping thread instead (no text thread), the difference (the rows' text), and the
  CPU time of the CSV writer alone writing the same rows (formatted and written, on one thread:
  the text's own cost, without a second thread beside the stepping);
- the ratios against issue 26's targets (medians of the rounds' ratios): flagship <= 5x the C
  closed-loop step, plant derivative <= 2x, controller sample <= 3x, through FMI (what a solver
  and the master pay); the Python paths' ratios for reference (the issue's "today" column).

With ``--limit-only ROUNDS`` it prints the at-the-limit ratios alone (wall and CPU with the rows
written as CSV, the stepping thread's CPU, CPU with the rows recorded as binary every third
round), medians of ROUNDS short rounds' ratios: quick enough to run two checkouts interleaved
(``PYTHONPATH=<checkout> python <checkout>/benchmarks/native.py --limit-only 25``) for a
before/after on a shared machine.

Usage: python benchmarks/native.py [--repeats 5] [--stop 3.5] [--limit-only ROUNDS]
"""
from __future__ import annotations

import argparse
import ctypes
import os
import statistics
import subprocess
import sys
import tempfile
import time
from ctypes import POINTER, c_double, c_int, c_long
from pathlib import Path
from typing import Any, NamedTuple, Optional

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SOURCE = Path(__file__).resolve().parent / "native" / "flagship.c"
FLAGSHIP = ROOT / "scenarios" / "delta_tracking.yaml"
#: the flagship's CSV columns that a row of the C closed loop holds, in its order
COLUMNS = (["time"] + [f"plant.z[{i}]" for i in (1, 2, 3)] + [f"plant.zd[{i}]" for i in (1, 2, 3)]
           + [f"trajectory.r[{i}]" for i in (1, 2, 3)] + [f"controller.u[{i}]" for i in (1, 2, 3)]
           + ["controller.status", "plant.residual"])
#: issue 26's targets: deltafmi / C at most
TARGETS = {"step": 5.0, "derivative": 2.0, "controller": 3.0}
#: the flagship through the master with every row written, at most this times the C transcription
LIMIT = 1.5

# --- the C side's data, as flagship.h declares it -----------------------------------------------
ROBOT = ("l0", "l1", "l2", "l3", "m1", "r1", "J1", "Jm", "m2", "mp", "payload", "g", "damping")


class DeltaParams(ctypes.Structure):
    _fields_ = [(name, c_double) for name in ROBOT]


class ControlLawSpec(ctypes.Structure):
    _fields_ = [("model", DeltaParams), ("kI", c_double), ("kP", c_double), ("kD", c_double),
                ("integral_max", c_double), ("feedforward", c_int), ("coriolis", c_int), ("zoh_lead", c_int),
                ("newton", c_int), ("torque_limit", c_double), ("cond_limit", c_double),
                ("newton_tol", c_double), ("newton_max_iter", c_int), ("sample_period", c_double)]


MAX_WAYPOINTS = 8


class PathSpec(ctypes.Structure):
    _fields_ = [("n", c_int), ("wp", (c_double * 3) * MAX_WAYPOINTS), ("T", c_double * (MAX_WAYPOINTS - 1)),
                ("dwell", c_double), ("t0", c_double)]


class Flagship(ctypes.Structure):
    _fields_ = [("plant", DeltaParams), ("pole", c_double), ("z0", c_double * 3), ("f", c_double * 3),
                ("law", ControlLawSpec), ("path", PathSpec), ("start", c_double), ("h", c_double)]


class PathState(ctypes.Structure):  # flagship.h's Path
    _fields_ = [("spec", PathSpec), ("starts", c_double * (MAX_WAYPOINTS - 1))]


ROW_WIDTH = len(COLUMNS)
_D = POINTER(c_double)


def compile_baseline(directory: Path) -> Path:
    """flagship.c compiled into ``directory`` (``cc -std=c99 -O2``, ``$CC`` honoured).

    Raises deltafmi's NoCompilerError when there is no C compiler, RuntimeError when it fails."""
    from deltafmi.toolchain import require_compiler

    cc = require_compiler(SOURCE)
    library = Path(directory) / "flagship.so"
    done = subprocess.run([*cc, "-std=c99", "-O2", "-shared", "-fPIC", str(SOURCE), "-o", str(library), "-lm"],
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"compiling {SOURCE} failed:\n{done.stderr}")
    return library


class Baseline:
    """The compiled transcription, loaded with ctypes."""

    def __init__(self, library: Path) -> None:
        lib = self._lib = ctypes.CDLL(str(library))
        lib.flagship_run.argtypes = [POINTER(Flagship), c_long, _D, _D]
        lib.flagship_run.restype = c_int
        lib.flagship_state_derivative.argtypes = [POINTER(DeltaParams), c_double, _D, _D, _D, _D]
        lib.flagship_state_derivative.restype = c_int
        lib.flagship_repeat_derivative.argtypes = [POINTER(DeltaParams), c_double, _D, _D, _D, c_long]
        lib.flagship_repeat_derivative.restype = c_double
        lib.flagship_replay_controller.argtypes = [POINTER(ControlLawSpec), _D, c_long, _D]
        lib.flagship_replay_controller.restype = c_double
        lib.flagship_path_init.argtypes = [POINTER(PathState), POINTER(PathSpec)]
        lib.flagship_path_init.restype = None
        lib.flagship_path_evaluate.argtypes = [POINTER(PathState), c_double, _D]
        lib.flagship_path_evaluate.restype = None

    def run(self, spec: Flagship, steps: int) -> tuple[np.ndarray, np.ndarray, float]:
        """The closed loop over ``steps`` communication steps: rows (steps + 1, 15) as
        :data:`COLUMNS`, the plant's states (steps + 1, 18) and the wall seconds of the run."""
        rows, states, wall, _ = self.timed_run(spec, steps)
        return rows, states, wall

    def timed_run(self, spec: Flagship, steps: int) -> tuple[np.ndarray, np.ndarray, float, float]:
        """:meth:`run`'s rows, states and wall seconds, and the CPU seconds of the process."""
        rows, states = np.empty((steps + 1, ROW_WIDTH)), np.empty((steps + 1, 18))
        cpu, begin = time.process_time(), time.perf_counter()
        failed = self._lib.flagship_run(ctypes.byref(spec), steps, _ptr(rows), _ptr(states))
        wall, cpu = time.perf_counter() - begin, time.process_time() - cpu
        if failed:
            raise ArithmeticError("the C transcription's plant hit a singularity")
        return rows, states, wall, cpu

    def state_derivative(self, spec: Flagship, x, u) -> np.ndarray:
        """dx/dt (18) of the plant at state ``x`` (18) under torques ``u`` (3)."""
        x, u, dx = _doubles(x), _doubles(u), np.empty(18)
        if self._lib.flagship_state_derivative(ctypes.byref(spec.plant), spec.pole, _ptr(x), _ptr(u),
                                               spec.f, _ptr(dx)):
            raise ArithmeticError("the constraint Jacobian lost rank")
        return dx

    def repeat_derivative(self, spec: Flagship, x, u, calls: int) -> float:
        """Wall seconds of ``calls`` state derivatives at (x, u), looped in C."""
        x, u = _doubles(x), _doubles(u)
        begin = time.perf_counter()
        self._lib.flagship_repeat_derivative(ctypes.byref(spec.plant), spec.pole, _ptr(x), _ptr(u), spec.f, calls)
        return time.perf_counter() - begin

    def path(self, spec: Flagship, t: float) -> np.ndarray:
        """r, rd, rdd (9) of the flagship's path at ``t``."""
        path, out = PathState(), np.empty(9)
        self._lib.flagship_path_init(ctypes.byref(path), ctypes.byref(spec.path))
        self._lib.flagship_path_evaluate(ctypes.byref(path), t, _ptr(out))
        return out

    def replay_controller(self, spec: Flagship, inputs: np.ndarray) -> tuple[np.ndarray, float]:
        """A fresh controller through ``inputs`` (samples x 15: y, yd, r, rd, rdd): its torques
        (samples x 3) and the wall seconds of the replay."""
        inputs = np.ascontiguousarray(inputs, dtype=float)
        u = np.empty((len(inputs), 3))
        begin = time.perf_counter()
        self._lib.flagship_replay_controller(ctypes.byref(spec.law), _ptr(inputs), len(inputs), _ptr(u))
        return u, time.perf_counter() - begin


def _doubles(values) -> np.ndarray:
    return np.ascontiguousarray(values, dtype=float)


def _ptr(array: np.ndarray):
    return array.ctypes.data_as(_D)


# --- the flagship's parameters, from its scenario -----------------------------------------------
class Models(NamedTuple):
    """The flagship's pieces as the model's own Python objects, built from its scenario."""

    plant: Any          #: DeltaParams of the plant
    pole: float         #: the plant's Baumgarte pole
    z0: list            #: initial wrist position
    f: list             #: external wrist force
    controller: Any     #: a fresh mechanics DeltaController, as the DeltaController component builds it
    waypoints: list     #: the path: MinimumJerkPath(waypoints, durations, dwell, t0)
    durations: list
    dwell: float
    t0: float


def flagship_models(system, delta=None, control=None) -> Models:
    """The values a resolved flagship scenario gives its components ``plant``, ``controller``
    and ``trajectory``, else their declared starts, as the mechanics objects their FMUs build;
    ``delta`` and ``control``: the mechanics modules to build them with (default: this
    deltafmi's; cosim.py's floor passes an FMU's copies). SystemExit when the scenario uses an
    option the C transcription does not have (it has the flagship's)."""
    from deltafmi.models import DeltaController, DeltaRobot, Trajectory

    if delta is None:
        from deltafmi.physics import delta
        from deltafmi.physics.delta import control
    given = {c.name: {p.name: p.value for p in c.spec.parameters} for c in system.components}
    missing = {"plant", "controller", "trajectory"} - set(given)
    if missing:
        raise SystemExit(f"{FLAGSHIP}: no component named {', '.join(sorted(missing))} (the flagship's)")

    def value(cls, component: str, name: str):
        declared = getattr(cls, name)
        return given[component].get(name, declared.start if declared.shape else declared.start[0])

    p = lambda name: value(DeltaRobot, "plant", name)  # noqa: E731
    c = lambda name: value(DeltaController, "controller", name)  # noqa: E731
    t = lambda name: value(Trajectory, "trajectory", name)  # noqa: E731
    solver = next(comp.spec.solver for comp in system.components if comp.name == "plant")
    as_transcribed = {
        "controller.impedance false": not c("impedance"), "controller.tactile_gain 0": c("tactile_gain") == 0,
        "controller.force 0": not any(c("force")), "trajectory.mode 0": t("mode") == 0,
        "plant.loop_tolerance 0": p("loop_tolerance") == 0, "plant solver {method: rk4}": solver == {"method": "rk4"},
        "controller.sample_period = the step": c("sample_period") == system.scenario.experiment.step,
        "algorithm gauss-seidel": system.scenario.master.algorithm == "gauss-seidel"}
    differ = [what for what, same in as_transcribed.items() if not same]
    if differ:
        raise SystemExit(f"{FLAGSHIP}: the C transcription has the flagship's options only; the scenario "
                         f"differs in: {', '.join(differ)}")
    model = delta.DeltaParams(**{n: float(c(n)) for n in ROBOT})
    controller = control.DeltaController(  # as DeltaController.initialize builds it
        model, pole=c("pole"), kI=c("kI"), kP=c("kP"), kD=c("kD"), integral_limit=c("integral_limit"),
        feedforward=c("feedforward"), torque_limit=c("torque_limit"), sample_period=c("sample_period"),
        coriolis=c("coriolis"), zoh_lead=c("zoh_lead"), fk="newton" if c("newton_fk") else "closed",
        cond_limit=c("cond_limit"))
    n = int(t("n_waypoints"))
    return Models(delta.DeltaParams(**{name: float(p(name)) for name in ROBOT}), float(p("pole")),
                  [float(v) for v in p("z0")], [float(v) for v in p("f")], controller,
                  [[float(v) for v in point] for point in zip(t("wp_x")[:n], t("wp_y")[:n], t("wp_z")[:n])],
                  [float(v) for v in t("wp_T")[:n - 1]], float(t("dwell")), float(t("t_start")))


def flagship_spec(system) -> Flagship:
    """The C side's data for a resolved flagship scenario (see :func:`flagship_models`); the
    controller's gains and limits are those its law derives (make_law)."""
    m = flagship_models(system)
    spec = Flagship()
    spec.plant = DeltaParams(**{n: getattr(m.plant, n) for n in ROBOT})
    spec.pole = m.pole
    spec.z0[:], spec.f[:] = m.z0, m.f
    ctl, law = m.controller, m.controller.law
    spec.law = ControlLawSpec(DeltaParams(**{n: getattr(ctl.params, n) for n in ROBOT}), law.kI, law.kP, law.kD,
                              law.integral_max, law.feedforward, law.coriolis, ctl.zoh_lead, law.fk == "newton",
                              law.torque_limit, law.cond_limit, law.newton_tol, law.newton_max_iter,
                              ctl.sample_period)
    spec.path.n = len(m.waypoints)
    for k, point in enumerate(m.waypoints):
        spec.path.wp[k][:] = point
    spec.path.T[:len(m.durations)] = m.durations
    spec.path.dwell, spec.path.t0 = m.dwell, m.t0
    spec.start = system.scenario.experiment.start
    spec.h = system.scenario.experiment.step
    return spec


def load_flagship():
    """The flagship's resolved scenario."""
    from deltafmi import resolve_system
    from deltafmi.master.scenario.spec import load_scenario

    return resolve_system(load_scenario(FLAGSHIP))


def controller_inputs(baseline: "Baseline", spec: Flagship, rows: np.ndarray, states: np.ndarray) -> np.ndarray:
    """The controller's samples of a closed-loop run, as it took them: (y, yd, r, rd, rdd) per
    sample; the one at the start, then one per step from the second on (at the step's end)."""
    samples = [0] + list(range(2, len(rows)))
    inputs = np.empty((len(samples), 15))
    for i, row in enumerate(samples):
        x = states[row]
        inputs[i, 0:3], inputs[i, 3:6] = x[0:9:3], x[9:18:3]
        t = spec.start if row == 0 else (spec.start + (row - 1) * spec.h) + spec.h  # as the trajectory FMU's time
        inputs[i, 6:15] = baseline.path(spec, t)
    return inputs


# --- the benchmark ------------------------------------------------------------------------------
def gap(a: np.ndarray, b: np.ndarray) -> float:
    """Largest |a - b| / max(|b|) per column, over the columns (0.0: bit for bit)."""
    scale = np.maximum(np.max(np.abs(b), axis=0), 1e-300)
    return float(np.max(np.max(np.abs(a - b), axis=0) / scale))


def compare(rows: np.ndarray, csv: Path) -> str:
    """How the C closed loop's rows agree with the flagship's CSV (plant.z, controller.u, all)."""
    from deltafmi.master.results.csv_file import read_csv

    names, reference = read_csv(csv)
    reference = reference[:, [names.index(n) for n in COLUMNS]]
    if reference.shape != rows.shape:
        raise SystemExit(f"the flagship wrote {reference.shape[0]} rows, the C transcription {rows.shape[0]}")
    z, u = slice(1, 4), slice(10, 13)
    if np.array_equal(rows, reference):
        return f"bit for bit (all {rows.shape[1]} columns, {rows.shape[0]} rows)"
    return (f"NOT bit for bit: plant.z within {gap(rows[:, z], reference[:, z]):.1e}, controller.u within "
            f"{gap(rows[:, u], reference[:, u]):.1e}, all columns within {gap(rows, reference):.1e} (relative "
            f"to each column's largest value)")


def c_derivative(baseline: Baseline, spec: Flagship, rows: np.ndarray, states: np.ndarray, instants: list[int],
                 calls: int) -> float:
    """Microseconds of one C state derivative: the median over ``instants`` (rows of the run) of a
    burst of ``calls`` on the state there, under the torque held over the next step."""
    per = [baseline.repeat_derivative(spec, states[k], rows[min(k + 1, len(rows) - 1), 10:13], calls) / calls
           for k in instants]
    return 1e6 * statistics.median(per)


def python_controller(controller, inputs: np.ndarray) -> tuple[np.ndarray, float]:
    """A fresh mechanics ``controller`` (DeltaController) replayed through ``inputs`` (as
    :func:`controller_inputs`): its torques and the wall seconds."""
    samples = [(i[0:3], i[3:6], i[6:9], i[9:12], i[12:15]) for i in inputs.tolist()]
    force, u = (0.0, 0.0, 0.0), []
    step = controller.step
    begin = time.perf_counter()
    for y, yd, r, rd, rdd in samples:
        u.append(step(y, yd, r, rd, rdd, force, 0.0))
    wall = time.perf_counter() - begin
    return np.array(u), wall


def cpu_master_run(cosim, system, stop: float, out: Path, thread: Optional[list] = None,
                   in_c: Optional[list] = None, text_thread: bool = True, closed: Optional[list] = None) -> tuple:
    """A master run (as cosim.master_run) and the CPU seconds the process spent stepping (the
    fixed-step loop, with the rows formatted and written as they go, on the stepping thread or
    the result writer's; the last CSV block's at close is not in it, as in the summary's stepping
    time). On a shared machine the wall time of a run that lasts several scheduler slices
    includes other processes' turns; its CPU time does not. ``thread``: a list that gets the CPU
    seconds of the stepping thread alone appended (what the wall time comes to where the rows'
    thread has a core of its own); ``in_c``: a list that gets the stepping thread's CPU seconds
    inside the master's C loop appended (the calls of :meth:`NativeLoop.run`: the FMUs, their
    kernels, the Runge-Kutta steps and the rows gathered; the rest of the stepping thread's is
    the Python around them: laying out the C loop, handing the rows to the writer); with
    ``text_thread`` False a CSV result is written by a CsvWriter of the benchmark's own (no text
    thread: the master gives blocks of rows a thread of their own for its own CsvWriter only), its
    text made on the stepping thread, its close counted as stepping; ``closed`` gets the close's
    wall seconds appended."""
    from deltafmi.master.results.csv_file import CsvWriter
    from deltafmi.master.stepping.c_loop import NativeLoop
    from deltafmi.master.stepping.master import Master

    run_fixed, run_c, spent, closing = Master._run_fixed, NativeLoop.run, [0.0, 0.0, 0.0], [0.0]

    def timed(master):
        begin, own = time.process_time(), time.thread_time()
        try:
            return run_fixed(master)
        finally:
            spent[0] += time.process_time() - begin
            spent[1] += time.thread_time() - own

    def timed_c(loop, *args):
        begin = time.thread_time()
        try:
            return run_c(loop, *args)
        finally:
            spent[2] += time.thread_time() - begin

    class SteppingThreadCsv(CsvWriter):
        """The master's CSV writer, not its exact class: its rows become text where they are recorded.
        The rows it still holds when the loop ends become text at close, on the stepping thread too:
        the close is counted as stepping (CPU and wall time)."""

        def close(self) -> None:
            begin, own, wall = time.process_time(), time.thread_time(), time.perf_counter()
            try:
                super().close()
            finally:
                spent[0] += time.process_time() - begin
                spent[1] += time.thread_time() - own
                closing[0] += time.perf_counter() - wall

    Master._run_fixed, NativeLoop.run = timed, timed_c
    try:
        if text_thread:
            summary = cosim.master_run(system, stop, out)
        else:
            summary = Master(system, result=out, stop=stop, writer_class=SteppingThreadCsv).run()
    finally:
        Master._run_fixed, NativeLoop.run = run_fixed, run_c
    if thread is not None:
        thread.append(spent[1])
    if in_c is not None:
        in_c.append(spent[2])
    if closed is not None:
        closed.append(closing[0])
    return summary, spent[0]


def csv_text_cpu(rows: np.ndarray, out: Path) -> float:
    """CPU seconds of the flagship's rows (as :data:`COLUMNS`) written by the CSV result writer
    alone on this thread (numbers formatted and written to ``out``, flushed), as the result
    thread writes a run's blocks."""
    from deltafmi.master.results.csv_file import CsvWriter

    kinds = ["Integer" if name == "controller.status" else "Real" for name in COLUMNS[1:]]
    writer = CsvWriter(out, COLUMNS[1:], kinds=kinds)
    try:
        begin = time.thread_time()
        writer.write_rows(rows)
        writer.flush()
        return time.thread_time() - begin
    finally:
        writer.close()


def verdict(ratio: float, target: float) -> str:
    return f"{ratio:6.1f}x (target <= {target:g}x: {'met' if ratio <= target else 'NOT met'})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="rounds; every figure is a median over them")
    parser.add_argument("--stop", type=float, default=None, help="simulated seconds (default: the flagship's)")
    parser.add_argument("--limit-only", type=int, default=0, metavar="ROUNDS",
                        help="only the at-the-limit ratios, medians over ROUNDS short rounds")
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import cosim  # benchmarks/cosim.py: the master's timings and the in-process floor

    with tempfile.TemporaryDirectory(prefix="deltafmi-native-") as scratch:
        if args.limit_only:
            at_the_limit(cosim, Path(scratch), args.limit_only, args.stop)
        else:
            measure(cosim, Path(scratch), args.repeats, args.stop)


def at_the_limit(cosim, out: Path, rounds: int, stop: Optional[float]) -> None:
    """The flagship against the C transcription with its rows written, ``rounds`` rounds (each
    a C run and a CSV run back to back, every third a binary run too): medians of the rounds'
    ratios."""
    baseline = Baseline(compile_baseline(out))
    system = load_flagship()
    spec = flagship_spec(system)
    stop = stop or system.scenario.experiment.stop
    steps = int(round((stop - spec.start) / spec.h))
    cpu_master_run(cosim, system, stop, out / "flagship.csv")  # FMUs built and loaded, caches warm
    ratios: dict = {}
    load = os.getloadavg()[0]
    for i in range(rounds):
        _, _, wall, cpu = baseline.timed_run(spec, steps)
        own: list = []
        run, process = cpu_master_run(cosim, system, stop, out / "flagship.csv", own)
        ratios.setdefault("wall time, rows written as CSV", []).append(run.stepping_time / wall)
        ratios.setdefault("CPU time, rows written as CSV", []).append(process / cpu)
        ratios.setdefault("CPU time of the stepping thread", []).append(own[0] / cpu)
        ratios.setdefault("C step CPU us", []).append(1e6 * cpu / steps)
        if i % 3 == 0:
            _, _, _, cpu = baseline.timed_run(spec, steps)
            _, process = cpu_master_run(cosim, system, stop, out / "flagship.parquet")
            ratios.setdefault("CPU time, rows recorded as binary", []).append(process / cpu)
    print(f"the flagship at the limit, {rounds} rounds ({steps} steps each), medians of the rounds' ratios "
          f"(target <= {LIMIT:g}x the C transcription); load average {load:.2f} at the start, "
          f"{os.getloadavg()[0]:.2f} at the end:")
    for label, values in ratios.items():
        if label.endswith("us"):
            print(f"  {label:38s} {statistics.median(values):6.2f} us")
        else:
            ratio = statistics.median(values)
            print(f"  {label:38s} {ratio:6.2f}x (target <= {LIMIT:g}x: {'met' if ratio <= LIMIT else 'NOT met'})")


def measure(cosim, out: Path, repeats: int, stop: Optional[float]) -> None:
    """Check the transcription against the flagship, then time both (module docstring)."""
    baseline = Baseline(compile_baseline(out))
    system = load_flagship()
    spec = flagship_spec(system)
    stop = stop or system.scenario.experiment.stop
    steps = int(round((stop - spec.start) / spec.h))
    rows, states, _ = baseline.run(spec, steps)
    cosim.master_run(system, stop, out / "flagship.csv")
    print(f"flagship {FLAGSHIP.relative_to(ROOT)}, {stop} s ({steps} steps); C transcription "
          f"{SOURCE.relative_to(ROOT)} (cc -std=c99 -O2) against the flagship's CSV: {compare(rows, out / 'flagship.csv')}")
    inputs = controller_inputs(baseline, spec, rows, states)
    u_c, _ = baseline.replay_controller(spec, inputs)
    floor = cosim.Floor(system, out)
    fresh = lambda: flagship_models(system, floor.delta, floor.control).controller  # noqa: E731
    u_py, _ = python_controller(fresh(), inputs)
    if not (np.array_equal(u_c, u_py) and np.array_equal(u_c[1:], rows[2:, 10:13])):
        raise SystemExit("the replayed controller does not reproduce the closed loop's torques")
    instants = sorted({0, *(int(round(f * steps)) for f in (0.1, 0.2, 0.4, 0.6, 0.8))})

    fig: dict = {}
    for _ in range(repeats):
        _, _, wall, cpu = baseline.timed_run(spec, steps)
        fig.setdefault("c step", []).append(1e6 * wall / steps)
        fig.setdefault("c step cpu", []).append(1e6 * cpu / steps)
        own, in_c = [], []
        run, cpu = cpu_master_run(cosim, system, stop, out / "flagship.csv", own, in_c)
        fig.setdefault("fmi step", []).append(1e6 * run.stepping_time / run.steps)
        fig.setdefault("fmi step cpu", []).append(1e6 * cpu / run.steps)
        fig.setdefault("fmi thread cpu", []).append(1e6 * own[0] / run.steps)
        fig.setdefault("fmi text cpu", []).append(fig["fmi step cpu"][-1] - fig["fmi thread cpu"][-1])
        fig.setdefault("fmi c loop cpu", []).append(1e6 * in_c[0] / run.steps)
        fig.setdefault("fmi python cpu", []).append(1e6 * (own[0] - in_c[0]) / run.steps)
        closed: list = []
        run, cpu = cpu_master_run(cosim, system, stop, out / "flagship.csv", text_thread=False, closed=closed)
        fig.setdefault("fmi same thread cpu", []).append(1e6 * cpu / run.steps)
        fig.setdefault("fmi same thread step", []).append(1e6 * (run.stepping_time + closed[0]) / run.steps)
        run, cpu = cpu_master_run(cosim, system, stop, out / "flagship.parquet")
        fig.setdefault("fmi binary cpu", []).append(1e6 * cpu / run.steps)
        fig.setdefault("csv alone cpu", []).append(1e6 * csv_text_cpu(rows, out / "text.csv") / len(rows))
        os.environ["DELTAFMI_NATIVE"] = "0"  # read when the FMUs are instantiated
        try:
            run = cosim.master_run(system, stop, out / "python.csv")
        finally:
            del os.environ["DELTAFMI_NATIVE"]
        fig.setdefault("py step", []).append(1e6 * run.stepping_time / run.steps)
        fig.setdefault("c rhs", []).append(c_derivative(baseline, spec, rows, states, instants, 2000))
        fmi, direct = cosim.rhs_pair(system, floor, out / "rhs.csv")
        fig.setdefault("fmi rhs", []).append(fmi)
        fig.setdefault("py rhs", []).append(direct)
        _, wall = baseline.replay_controller(spec, inputs)
        fig.setdefault("c ctl", []).append(1e6 * wall / len(inputs))
        _, wall = python_controller(fresh(), inputs)
        fig.setdefault("py ctl", []).append(1e6 * wall / len(inputs))
        timed, in_units = cosim.timed_master_run(system, stop, out / "timed.csv")
        fig.setdefault("fmi ctl", []).append(1e6 * in_units["controller"] / timed.steps)
    med = {key: statistics.median(values) for key, values in fig.items()}
    spread = {key: (min(values), max(values)) for key, values in fig.items()}

    def line(label: str, key: str) -> str:
        low, high = spread[key]
        return f"  {label:88s} {med[key]:7.2f} us  ({low:.2f}-{high:.2f})"

    print(f"medians of {repeats} rounds (range), both sides measured in each round on this machine:")
    print(line("C closed-loop step (plant rk4 + controller + path + row, 1 ms)", "c step"))
    print(line("deltafmi: flagship stepping through FMI (master, stepping time / steps)", "fmi step"))
    print(line("C closed-loop step, CPU time", "c step cpu"))
    print(line("deltafmi: flagship stepping through FMI, CPU time of the process (rows written)", "fmi step cpu"))
    print(line("deltafmi: the same, CPU time of the stepping thread (the rows become text on another)",
               "fmi thread cpu"))
    print(line("deltafmi: of the stepping thread's, in the master's C loop (FMUs, kernels, RK, rows)",
               "fmi c loop cpu"))
    print(line("deltafmi: of the stepping thread's, Python around the C loop (set-up, rows handed over)",
               "fmi python cpu"))
    print(line("deltafmi: the same, CPU time of the process, CSV text on the stepping thread (no thread)",
               "fmi same thread cpu"))
    print(line("deltafmi: the same, stepping time / steps, CSV text on the stepping thread", "fmi same thread step"))
    print(line("deltafmi: the same, CPU time of the process, rows recorded as binary (-o x.parquet)",
               "fmi binary cpu"))
    print(line("deltafmi: the rows' text in the CSV run, CPU (process less stepping thread) per step",
               "fmi text cpu"))
    print(line("deltafmi: the same rows written by the CSV writer alone (format + write), CPU per row",
               "csv alone cpu"))
    same = (out / "flagship.csv").read_bytes() == (out / "python.csv").read_bytes()
    print(line(f"deltafmi: the same, FMUs on their Python methods (DELTAFMI_NATIVE=0; CSV "
               f"{'the same bits' if same else 'DIFFERENT'})", "py step"))
    print(line(f"C plant derivative (one call, median over {len(instants)} instants of the run)", "c rhs"))
    print(line("deltafmi: plant derivative through FMI (SetTime + SetContinuousStates + GetDerivatives)",
               "fmi rhs"))
    print(line("deltafmi: plant derivative, Python path (state_derivative, in-process)", "py rhs"))
    print(line("C controller sample (the run's samples replayed)", "c ctl"))
    print(line("deltafmi: controller through FMI (SetReal + DoStep + GetReal, master's C loop)", "fmi ctl"))
    print(line("deltafmi: controller sample, Python path (DeltaController.step, in-process)", "py ctl"))
    print("ratios deltafmi / C, medians of the rounds' ratios (issue 26's targets):")
    for label, fmi, c, target in (("flagship step through FMI", "fmi step", "c step", "step"),
                                  ("plant derivative through FMI", "fmi rhs", "c rhs", "derivative"),
                                  ("controller sample through FMI", "fmi ctl", "c ctl", "controller")):
        ratio = statistics.median(a / b for a, b in zip(fig[fmi], fig[c]))
        print(f"  {label:36s} {verdict(ratio, TARGETS[target])}")
    print(f"the flagship at the limit, rows written (target <= {LIMIT:g}x the C transcription):")
    for label, fmi, c in (("wall time, rows written as CSV", "fmi step", "c step"),
                          ("CPU time, rows written as CSV", "fmi step cpu", "c step cpu"),
                          ("CPU time of the stepping thread", "fmi thread cpu", "c step cpu"),
                          ("CPU time, CSV text on stepping thread", "fmi same thread cpu", "c step cpu"),
                          ("wall time, CSV text on stepping thread", "fmi same thread step", "c step"),
                          ("CPU time, rows recorded as binary", "fmi binary cpu", "c step cpu")):
        ratio = statistics.median(a / b for a, b in zip(fig[fmi], fig[c]))
        print(f"  {label:38s} {verdict(ratio, LIMIT)}")
    for label, key in (("of which the rows' text", "fmi text cpu"),
                       ("the stepping thread in the C loop", "fmi c loop cpu"),
                       ("the stepping thread in Python", "fmi python cpu"),
                       ("the CSV writer alone on the same rows", "csv alone cpu")):
        print(f"  {label:38s} {statistics.median(a / b for a, b in zip(fig[key], fig['c step cpu'])):6.2f}x "
              f"the C step's CPU time")
    print("the Python paths (before the compiled kernels), deltafmi / C:")
    for label, py, c in (("flagship step, Python kernels", "py step", "c step"),
                         ("plant derivative, Python path", "py rhs", "c rhs"),
                         ("controller sample, Python path", "py ctl", "c ctl")):
        print(f"  {label:36s} {statistics.median(a / b for a, b in zip(fig[py], fig[c])):6.1f}x")
    speedup = statistics.median(a / b for a, b in zip(fig["py step"], fig["fmi step"]))
    print(f"flagship through FMI, compiled kernels against Python kernels: {speedup:.1f}x faster; real-time "
          f"factor {1e6 * spec.h / med['fmi step']:.0f}x against {1e6 * spec.h / med['py step']:.0f}x "
          f"(stepping only, 1 ms steps)")

if __name__ == "__main__":
    main()
