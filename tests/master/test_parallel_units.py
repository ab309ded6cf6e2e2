"""Parallel units (``master: {threads: N}``): the plain-C FMUs of tests/third_party step on several
threads, in the master's C loop and in its Python loop, and every result is the one of
``threads: 1`` bit for bit; Gauss-Seidel groups only units that take no input from one another; a
deltafmi FMU whose step runs Python steps on the master's thread; units that exchange nothing step
through blocks of steps with the same results; a bad ``threads`` is bad input at its file and line."""
from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.errors import BadInput, ScenarioError, SimulationError
from deltafmi.master.results.csv_file import columns
from deltafmi.master.scenario.overrides import with_overrides
from deltafmi.master.scenario.resolve import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.master.stepping.parallel import STEP, group_actions, pooled
from third_party.build import build_fmu

ZETA_FREE = 0.05  # c = 0.1, k = m = 1: the free oscillator's damping ratio


@pytest.fixture(scope="module")
def c_fmus(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("c_fmus")
    return {model: build_fmu(model, folder) for model in ("Oscillator", "BouncingBall")}


def oscillators(fmu: Path, algorithm: str, threads: int = 1, stop: float = 0.5) -> str:
    """Six C oscillators: a ring of four coupled through their forces (each takes the position of
    the one before), two free ones between them."""
    names = ["a", "free1", "b", "c", "free2", "d"]
    lines = [f"experiment: {{start: 0.0, stop: {stop}, step: 1.0e-3}}",
             f"master: {{algorithm: {algorithm}, threads: {threads}}}", "components:"]
    lines += [f"  {n}: {{fmu: '{fmu}', interface: CS, parameters: {{k: {1.0 + i}, substep: 1.0e-4}}}}"
              for i, n in enumerate(names) if not n.startswith("free")]
    lines += [f"  {n}: {{fmu: '{fmu}', interface: CS, parameters: {{substep: 1.0e-4}}}}"
              for n in names if n.startswith("free")]
    ring = ["a", "b", "c", "d"]
    lines.append("connections:")
    lines += [f"  - {{from: {ring[i - 1]}.x, to: {ring[i]}.F, factor: 0.3}}" for i in range(4)]
    lines.append(f"outputs: [{', '.join(f'{n}.x' for n in names)}, {', '.join(f'{n}.v' for n in names)}]")
    return "\n".join(lines) + "\n"


def run(tmp_path: Path, text: str, threads: int, native: bool = True, name: str = "run") -> bytes:
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    scenario = load_scenario(path)
    scenario = replace(scenario, master=replace(scenario.master, threads=threads))
    result = tmp_path / f"{name}-{threads}-{native}.csv"
    Master(resolve_system(scenario), result=result, native=native).run()
    return result.read_bytes()


@pytest.mark.parametrize("native", [True, False], ids=["C loop", "Python loop"])
@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_results_are_those_of_one_thread_bit_for_bit(c_fmus, tmp_path, algorithm, native):
    text = oscillators(c_fmus["Oscillator"], algorithm)
    one = run(tmp_path, text, 1, native)
    for threads in (2, 3, 8):
        assert run(tmp_path, text, threads, native) == one, threads
    result = columns(tmp_path / f"run-1-{native}.csv")
    t = result["time"]  # the free ones against the closed form of a damped oscillator from x = 1 at rest
    w = np.sqrt(1 - ZETA_FREE ** 2)
    exact = np.exp(-ZETA_FREE * t) * (np.cos(w * t) + ZETA_FREE / w * np.sin(w * t))
    for name in ("free1.x", "free2.x"):
        assert np.abs(result[name] - exact).max() < 1e-12
    assert np.abs(result["b.x"] - result["free1.x"]).max() > 1e-3  # the ring is coupled


def test_the_c_and_the_python_loop_agree_with_threads(c_fmus, tmp_path):
    text = oscillators(c_fmus["Oscillator"], "jacobi")
    assert run(tmp_path, text, 2, native=True) == run(tmp_path, text, 2, native=False)


def open_master(tmp_path: Path, text: str) -> Master:
    path = tmp_path / "open.yaml"
    path.write_text(text)
    master = Master(resolve_system(load_scenario(path)), result=tmp_path / "open.csv")
    master.open()
    return master


def step_groups(master: Master, algorithm: str) -> list:
    actions, groups = group_actions(master.stepping_blocks(), algorithm, master.system.links)
    found: dict = {}
    for (unit, action, _), group in zip(actions, groups):
        if action == STEP:
            found.setdefault(group, []).append(unit.name)
    return [found[g] for g in sorted(found) if g], found.get(0, [])


def test_gauss_seidel_groups_no_unit_with_one_it_takes_input_from(c_fmus, tmp_path):
    master = open_master(tmp_path, oscillators(c_fmus["Oscillator"], "gauss-seidel"))
    try:
        order = [unit.name for unit in master.stepping_blocks()]
        grouped, alone = step_groups(master, "gauss-seidel")
        inputs = {(link.source.component, link.target.component) for link in master.system.links}
        for group in grouped:
            assert len(group) > 1 and not [(s, t) for s in group for t in group if (s, t) in inputs]
            positions = sorted(order.index(name) for name in group)
            assert positions == list(range(positions[0], positions[0] + len(group)))  # consecutive in the order
        covered = [name for group in grouped for name in group] + alone
        assert sorted(covered) == sorted(order)
        # each unit after the first of a group takes an input from the group before it, or it would have joined it
        assert sum(map(len, grouped)) >= 2
        jacobi, alone = step_groups(master, "jacobi")
        assert jacobi == [[u.name for u in master.stepping_blocks()]] and alone == []
    finally:
        master.close()


def test_a_unit_whose_step_runs_python_steps_on_the_masters_thread(c_fmus, tmp_path):
    fmu = c_fmus["Oscillator"]
    text = (f"experiment: {{start: 0.0, stop: 0.01, step: 1.0e-3}}\nmaster: {{algorithm: jacobi, threads: 2}}\n"
            f"components:\n  c1: {{fmu: '{fmu}', interface: CS}}\n  c2: {{fmu: '{fmu}', interface: CS}}\n"
            "  ours: {source: deltafmi.models:Oscillator, interface: CS}\n  ours2: {fmu: '"
            + str(fmu) + "', interface: ME}\noutputs: [c1.x, ours.x]\n")
    master = open_master(tmp_path, text)
    try:
        ours = next(unit for unit in master.units if unit.name == "ours")
        # a deltafmi FMU steps on the threads when it takes its Co-Simulation steps in C (Python at events only)
        in_c = (Path(ours.fmu.unzipDirectory) / "resources/python/deltafmi/runtime/cs_native.py").is_file()
        kinds = {unit.name: pooled(unit) for unit in master.units}
        assert kinds == {"c1": True, "c2": True, "ours": in_c, "ours2": False}
        grouped, alone = step_groups(master, "jacobi")
        assert grouped == [["c1", "c2", "ours"] if in_c else ["c1", "c2"]]
        assert alone == (["ours2"] if in_c else ["ours", "ours2"])
    finally:
        master.close()
    shutil.rmtree(tmp_path / "open.csv", ignore_errors=True)


def test_a_failing_group_reports_the_first_unit_in_stepping_order(c_fmus, tmp_path):
    fmu = c_fmus["BouncingBall"]  # max_step below the communication step: every fmi2DoStep is discarded
    text = ("experiment: {start: 0.0, stop: 0.1, step: 1.0e-3}\nmaster: {algorithm: jacobi}\ncomponents:\n"
            + "".join(f"  {n}: {{fmu: '{fmu}', interface: CS, parameters: {{max_step: 1.0e-4}}}}\n"
                      for n in ("first", "second"))
            + "outputs: [first.h, second.h]\n")
    (tmp_path / "fail.yaml").write_text(text)
    messages = []
    for threads in (1, 2):
        with pytest.raises(SimulationError) as raised:
            import deltafmi
            deltafmi.simulate(tmp_path / "fail.yaml", threads=threads)
        messages.append(str(raised.value))
    assert messages[0] == messages[1] and "first" in messages[0] and "second" not in messages[0]


@pytest.mark.parametrize("value, words", [("0", "minimum"), ("1.5", "integer"), ("'two'", "integer"),
                                          ("300", "maximum")])
def test_a_bad_threads_value_is_named_at_its_line(tmp_path, value, words):
    path = tmp_path / "bad.yaml"
    path.write_text("experiment: {start: 0.0, stop: 1.0, step: 1.0e-3}\nmaster:\n  algorithm: jacobi\n"
                    f"  threads: {value}\ncomponents:\n  ball: {{source: deltafmi.models:BouncingBall}}\n")
    with pytest.raises(ScenarioError) as raised:
        load_scenario(path)
    assert [(d.line, "master.threads" in d.message and words in d.message) for d in raised.value.diagnostics] \
        == [(4, True)]
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2 and f"{path}:4:" in result.output


def test_bad_threads_options_are_bad_input(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("experiment: {start: 0.0, stop: 0.01, step: 1.0e-3}\ncomponents:\n"
                    "  ball: {source: deltafmi.models:BouncingBall}\n")
    result = CliRunner().invoke(main, ["run", str(path), "--threads", "0", "-o", str(tmp_path / "r.csv")])
    assert result.exit_code == 2 and "--threads" in result.output and "0" in result.output
    for bad in (0, -1, 2.0, True, 257):
        with pytest.raises(BadInput, match="threads"):
            with_overrides(load_scenario(path), threads=bad)
    assert with_overrides(load_scenario(path), threads=4).master.threads == 4


def test_sweep_takes_threads_and_keeps_the_studys_identity(tmp_path):
    from deltafmi.apps.studies.plan import _fingerprint

    runner = CliRunner()
    bad = runner.invoke(main, ["sweep", "gain_payload", "--threads", "0", "--dry-run"])
    assert bad.exit_code == 2 and "--threads" in bad.output
    from deltafmi.apps.studies.commands import _plan, _with_threads
    from deltafmi.shipped import find_input

    planned = _plan(str(find_input("gain_payload", "study")))
    threaded = _with_threads(planned, 2)
    assert threaded.plan.scenario.master.threads == 2 and planned.plan.scenario.master.threads == 1
    # the same cases, the same results: earlier results of the study stay valid
    assert _fingerprint(threaded.plan.scenario, threaded.plan.fmus, threaded.plan.metrics) == planned.plan.fingerprint


def test_the_threads_end_with_the_run(c_fmus, tmp_path):
    import os

    text = oscillators(c_fmus["Oscillator"], "jacobi", stop=0.2)
    run(tmp_path, text, 1, native=True)  # the C loop loaded
    before = len(os.listdir("/proc/self/task"))
    for native in (True, False):
        run(tmp_path, text, 4, native=native)
        assert len(os.listdir("/proc/self/task")) == before, native


def _thread_states() -> int:
    """The interpreter's thread states (CPython's C API through ctypes)."""
    import ctypes

    api = ctypes.pythonapi
    api.PyInterpreterState_Get.restype = ctypes.c_void_p
    api.PyInterpreterState_ThreadHead.restype = ctypes.c_void_p
    api.PyInterpreterState_ThreadHead.argtypes = [ctypes.c_void_p]
    api.PyThreadState_Next.restype = ctypes.c_void_p
    api.PyThreadState_Next.argtypes = [ctypes.c_void_p]
    count, state = 0, api.PyInterpreterState_ThreadHead(api.PyInterpreterState_Get())
    while state:
        count, state = count + 1, api.PyThreadState_Next(state)
    return count


def test_a_worker_that_ran_an_fmus_python_leaves_no_thread_state(tmp_path):
    """Bouncing balls stepped in C on the threads run their Python at every bounce, on whichever
    thread steps them: the pool's workers get thread states there, and give them back as they end
    with the run (they were kept for good, one per worker per run)."""
    lines = ["experiment: {start: 0.0, stop: 1.5, step: 1.0e-3}", "master: {algorithm: jacobi, threads: 2}",
             "components:"]
    lines += [f"  b{i}: {{source: deltafmi.models:BouncingBall, interface: CS}}" for i in range(4)]
    lines.append("outputs: [b0.q, b0.contact, b3.contact]")
    text = "\n".join(lines) + "\n"
    run(tmp_path, text, 2)  # built, loaded, the interpreter's own threads started
    before = _thread_states()
    for _ in range(3):
        run(tmp_path, text, 2)
    assert _thread_states() == before
    # the balls reached the table (the contact events ran)
    result = columns(tmp_path / "run-2-True.csv")
    assert result["b0.contact"].max() > 0 and result["b3.contact"].max() > 0 and result["b0.q"].min() < 0.01


def components_of_runs(monkeypatch) -> list:
    """The components of each C loop made from here on (unit names; none: the units step in lockstep)."""
    from deltafmi.master.stepping import master as master_module

    made = []

    class Recorded(master_module.NativeLoop):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(sorted(sorted(names) for names in self.components))

    monkeypatch.setattr(master_module, "NativeLoop", Recorded)
    return made


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_units_that_exchange_nothing_step_in_blocks_with_the_results_of_one_thread(c_fmus, tmp_path, monkeypatch,
                                                                                     algorithm):
    """The ring and the two free oscillators are three components: each steps through blocks of steps
    on a thread of its own, its rows written there; every fourth row recorded (result.every)."""
    made = components_of_runs(monkeypatch)
    text = oscillators(c_fmus["Oscillator"], algorithm, stop=0.3) + "result: {every: 4}\n"
    one = run(tmp_path, text, 1)
    assert made == [[]]
    for threads in (2, 3):
        assert run(tmp_path, text, threads) == one, threads
    assert made[1:] == [[["a", "b", "c", "d"], ["free1"], ["free2"]]] * 2
    result = columns(tmp_path / "run-1-True.csv")
    assert len(result["time"]) == 76 and np.allclose(np.diff(result["time"]), 4e-3)  # 0, 4 ms, ..., 0.3 s


def test_blocks_of_steps_end_where_the_rows_are_full(c_fmus, tmp_path, monkeypatch):
    """Room for 64 rows a call of the C loop (the least it takes): a call of more steps stops in a
    block when the rows are full (ROWS_FULL) and the next goes on from there, as with one thread."""
    from deltafmi.master.stepping import master as master_module

    made = components_of_runs(monkeypatch)
    monkeypatch.setattr(master_module, "_C_ROWS_BYTES", 1)
    monkeypatch.setattr(master_module, "_C_STEPS", 100)  # the first call already more steps than rows
    text = oscillators(c_fmus["Oscillator"], "jacobi", stop=0.5)
    one = run(tmp_path, text, 1)
    assert run(tmp_path, text, 2) == one and len(made[1]) == 3
    assert len(one.decode().splitlines()) == 1 + 501


def test_a_unit_ending_the_run_inside_a_block(c_fmus, tmp_path, monkeypatch):
    """A Ticker ends the run at its 25th tick (fmi2Discard, fmi2Terminated) in the middle of a block: the
    rows before are those of one thread, and so are the run's end and the Ticker's last row."""
    folder = tmp_path / "fmus"
    folder.mkdir()
    ticker = build_fmu("Ticker", folder)
    fmu = c_fmus["Oscillator"]
    lines = ["experiment: {start: 0.0, stop: 1.0, step: 1.0e-3}", "master: {algorithm: jacobi}", "components:",
             f"  ticker: {{fmu: '{ticker}', interface: CS, parameters: {{period: 0.0037, max_ticks: 25}}}}"]
    lines += [f"  o{i}: {{fmu: '{fmu}', interface: CS, parameters: {{k: {1.0 + i}, substep: 1.0e-4}}}}"
              for i in range(3)]
    lines.append("outputs: [ticker.ticks, ticker.held, o0.x, o1.x, o2.x]")
    text = "\n".join(lines) + "\n"
    made = components_of_runs(monkeypatch)
    one, two = (run(tmp_path, text, threads) for threads in (1, 2))
    assert len(made[1]) == 4
    first, second = one.decode().splitlines(), two.decode().splitlines()
    assert len(first) == len(second) and first[:-1] == second[:-1]
    last_one, last_two = first[-1].split(","), second[-1].split(",")
    assert last_one[:3] == last_two[:3]  # time, ticker.ticks, ticker.held
    assert float(last_one[0]) == pytest.approx(25 * 0.0037) and last_one[1] == "25"
