"""The master's fixed-step loop in C (deltafmi.master.stepping.c_loop) against its Python loop.

The C loop makes the same fmi2 calls with the same arguments in the same order, so a run must be
the same bit for bit, the result files byte for byte: the flagship (ME plant on rk4, CS
controller and trajectory, Gauss-Seidel), the flagship with step events from the plant's loop
projection (the C loop hands each event back to Python mid-step), state events of an ME unit
on rk4 (located by the same bisection after the C loop found the crossing), Jacobi with a step multiple
and a transformed link, Integer and Boolean columns, and a Co-Simulation FMU failing mid-run
(same message, same rows kept). The result writer's C formatting of Reals (Ryu's shortest
digits laid out as repr lays them out) against ``repr`` itself, on random bit patterns, powers of
two and their neighbours (where the rounding interval is lopsided), subnormals and specials.
"""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from deltafmi.master.results.csv_file import CsvWriter
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping import c_loop as native_loop
from deltafmi.master.stepping.master import Master
from deltafmi.errors import SimulationError

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def c_runs(monkeypatch) -> list:
    """Counts the C loop's runs (so a test knows the C loop really stepped)."""
    calls: list = []
    original = native_loop.NativeLoop.run

    def counted(self, k, k_end):
        result = original(self, k, k_end)
        calls.append(result[0])  # why it stopped
        return result
    monkeypatch.setattr(native_loop.NativeLoop, "run", counted)
    return calls


def both(tmp_path: Path, text: str, stop: float):
    """Run the scenario ``text`` with the C loop and with the Python loop: (summaries, csv texts)."""
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(text))
    system = resolve_system(load_scenario(path))
    out = []
    for native in (True, False):
        result = tmp_path / f"{'c' if native else 'python'}.csv"
        summary = Master(system, result=result, stop=stop, native=native).run()
        out.append((summary, result.read_text()))
    return out


def flagship(extra_plant: str = "") -> str:
    text = (ROOT / "scenarios" / "delta_tracking.yaml").read_text()
    return text.replace("      z0: [0.0, 0.0, -1.0]", "      z0: [0.0, 0.0, -1.0]\n" + extra_plant)


def test_flagship_same_bits_in_c(tmp_path, c_runs):
    (c, c_text), (python, python_text) = both(tmp_path, flagship(), stop=0.6)
    assert c_runs and c.steps == python.steps == 600
    assert c_text == python_text
    assert c.rows == python.rows == 601


def test_step_events_handed_back_mid_step(tmp_path, c_runs):
    # the plant projects onto its loops at a step event whenever the residual exceeds 1e-13 m
    (c, c_text), (python, python_text) = both(tmp_path, flagship("      loop_tolerance: 1.0e-13\n"), stop=0.6)
    assert python.events > 10 and c.events == python.events
    assert len(c_runs) > python.events  # C ran again after every event
    assert c_text == python_text


def test_state_events_located_after_c(tmp_path, build_fmu_from_src, c_runs):
    # rk4 in ME with wall impacts (state events) and a force step (a time event: Python steps
    # while it is pending): the C loop hands every crossing back for the bisection
    fmu = build_fmu_from_src("oscillator.py")
    text = f"""\
        experiment: {{stop: 4.0, step: 0.01}}
        components:
          osc: {{fmu: {fmu}, interface: ME, parameters: {{t_step: 0.05, F_step: -20.0}}, solver: {{method: rk4, max_step: 0.005}}}}
        outputs: [osc.x, osc.v, osc.impacts, osc.force_on]
        """
    (c, c_text), (python, python_text) = both(tmp_path, text, stop=4.0)
    assert c_runs.count(native_loop.STATE_EVENT) >= 3 and c.events == python.events
    assert c_text == python_text


OSCILLATORS = """\
    experiment: {{stop: 2.0, step: 0.01}}
    master: {{algorithm: jacobi}}
    components:
      a: {{fmu: {fmu}, interface: CS}}
      b: {{fmu: {fmu}, interface: CS, step_multiple: 2, parameters: {{F_step: {force}, t_step: 1.0}}}}
      c: {{fmu: {fmu}, interface: CS}}
    connections:
      - {{from: a.energy, to: b.F, factor: 0.05, offset: 0.1}}
      - {{from: b.energy, to: c.F, factor: -3.0}}
    outputs: [a.x, b.x, b.F, c.x, c.energy, a.impacts, b.impacts, c.force_on]
    """


def test_jacobi_multi_rate_transformed_integer_boolean_same_bits(tmp_path, build_fmu_from_src, c_runs):
    fmu = build_fmu_from_src("oscillator.py")
    (c, c_text), (python, python_text) = both(tmp_path, OSCILLATORS.format(fmu=fmu, force=2.0), stop=2.0)
    assert c_runs and c.steps == python.steps == 200
    assert c_text == python_text
    rows = [line.split(",") for line in c_text.splitlines()[1:]]
    assert any(int(row[6]) > 0 for row in rows)  # a's wall impacts counted, written as integers


@pytest.mark.parametrize("algorithm, stop, every", [("gauss-seidel", 1.234, 3), ("jacobi", 0.995, 7)])
def test_off_grid_stop_and_sparse_rows_same_bits(tmp_path, build_fmu_from_src, c_runs, algorithm, stop, every):
    # the last step ends at stop (shorter), b's double step there too; every n-th row and the last
    fmu = build_fmu_from_src("oscillator.py")
    text = OSCILLATORS.format(fmu=fmu, force=2.0).replace("{algorithm: jacobi}", f"{{algorithm: {algorithm}}}")
    text = text.rstrip() + f"\n    result: {{every: {every}}}\n"
    (c, c_text), (python, python_text) = both(tmp_path, text, stop=stop)
    assert c_runs and c_text == python_text
    times = [float(line.split(",")[0]) for line in c_text.splitlines()[1:]]
    assert times[-1] == stop and c.rows == python.rows == len(times)


def failed_both_ways(system, folder: Path) -> tuple[list, list]:
    """([its message, ...], [the rows kept, ...]) of a run of ``system`` that fails, by the C loop
    and then the Python loop (the result's path in the message as RESULT)."""
    messages, texts = [], []
    for native in (True, False):
        result = folder / f"{native}.csv"
        with pytest.raises(SimulationError) as failure:
            Master(system, result=result, native=native).run()
        kept = result.with_suffix(".failed.csv")  # a failed run's rows, under a name that says so
        messages.append(str(failure.value.message).replace(str(kept), "RESULT"))
        texts.append(kept.read_text())
    return messages, texts


def test_failure_in_c_same_message_and_rows(tmp_path, build_fmu_from_src, c_runs):
    # an absurd force step at t = 1 s makes b's own CVODE fail inside its fmi2DoStep
    fmu = build_fmu_from_src("oscillator.py")
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(OSCILLATORS.format(fmu=fmu, force=1.0e308)))
    system = resolve_system(load_scenario(path))
    messages, texts = failed_both_ways(system, tmp_path)
    assert c_runs
    assert messages[0] == messages[1] and messages[0].startswith("simulation failed at t = 1 s: b: fmi2DoStep")
    assert texts[0] == texts[1] and len(texts[0].splitlines()) == 1 + 101  # header, t = 0 ... 1 s


def test_csv_reals_written_as_repr(tmp_path):
    rng = np.random.default_rng(16)
    bits = rng.integers(0, 2 ** 64, 90000, dtype=np.uint64).view(np.float64)
    special = [0.0, -0.0, 1.0, 0.1, 1e15, 1e16, 1.5e16, 9999999999999998.0, 1e-4, 1e-5, 5e-324, 2.0 ** -1022,
               1.7976931348623157e308, 1e22, np.nan, np.inf, -np.inf, 7.291122019556398e-304]
    powers = [np.ldexp(1.0, e) for e in range(-1074, 1024)]
    values = np.concatenate([bits, rng.random(2000), np.round(rng.random(2000) * 1e4, 3), special, powers,
                             np.nextafter(powers, 0.0), np.nextafter(powers, np.inf), 10.0 ** np.arange(-323, 308),
                             np.arange(-100, 100) * 0.5])
    reals = values[: len(values) // 3 * 3].reshape(-1, 3)
    integers = rng.integers(-2 ** 31, 2 ** 31, len(reals)).astype(float)  # an int32 bus's values
    rows = np.column_stack([reals, integers])
    writer = CsvWriter(tmp_path / "r.csv", ["a", "b", "n"], chunk=97, kinds=["Real", "Real", "Integer"])
    writer.write_rows(rows[:500])
    for row in rows[500:]:
        writer.write(row[0], row[1:])
    writer.close()
    lines = (tmp_path / "r.csv").read_text().splitlines()[1:]
    assert lines == [f"{t!r},{a!r},{b!r},{int(n)}" for t, a, b, n in rows.tolist()]


def test_csv_text_laid_out_as_repr_in_every_notation_and_repeated(tmp_path):
    # every place the point can take in fixed notation (-4 ... 15 as repr chooses), integral
    # values with zeros after their digits, short digits (a time grid, subnormals: Ryu removes
    # many digits, several at a time), and a value repeated in its column copied from the row
    # above, in rows of one and two columns where the texts sit close together (3 to 24 chars)
    rng = np.random.default_rng(42)
    mantissas = rng.random(400) + 1.0
    fixed = np.concatenate([mantissas * 10.0 ** e for e in range(-6, 18)])
    integral = np.concatenate([np.round(rng.random(50) * 10.0 ** k) for k in range(1, 17)]
                              + [10.0 ** np.arange(17)])
    grid = np.arange(0, 20001) * 1e-3
    # subnormals: wide rounding intervals, cut where the digits removed may round either way
    subnormal = np.arange(1, 30000) * 5e-324
    values = np.concatenate([fixed, -fixed, integral, -integral, grid, 0.1 * np.arange(-500, 500), subnormal])
    repeated = np.repeat(values, rng.integers(1, 4, len(values)))
    for width in (1, 2):
        count = len(repeated) // width * width
        rows = repeated[:count].reshape(-1, width)
        names = ["a"][:width - 1]
        path = tmp_path / f"w{width}.csv"
        writer = CsvWriter(path, names, chunk=211)
        writer.write_rows(rows)
        writer.close()
        lines = path.read_text().splitlines()[1:]
        assert lines == [",".join(repr(v) for v in row) for row in rows.tolist()]


def test_study_recorder_takes_blocks_and_event_rows(tmp_path, c_runs):
    # deltafmi.apps.studies keeps rows in memory: blocks from the C loop between single rows (the
    # initial row, the rows before step events) must come out in order, as the Python loop's
    from deltafmi.apps.studies.runner import MemoryRecorder
    path = tmp_path / "s.yaml"
    path.write_text(flagship("      loop_tolerance: 1.0e-13\n"))
    system = resolve_system(load_scenario(path))
    kept = []

    def recorder(*args, **kwargs):
        kept.append(MemoryRecorder(*args, chunk=50, **kwargs))
        return kept[-1]
    summaries = [Master(system, stop=0.4, writer_class=recorder, native=native).run() for native in (True, False)]
    assert c_runs and summaries[0].events == summaries[1].events > 5
    c, python = (k.columns() for k in kept)
    assert list(c) == list(python) and len(c["time"]) == summaries[1].rows
    for name in c:
        assert np.array_equal(c[name], python[name]), name


@pytest.fixture
def handed_rows(monkeypatch) -> list:
    """The C loop hands the CSV writer's thread of C its rows every 5 rows, while it steps (the
    master's default is every 1024); the rows each run handed over this way."""
    from deltafmi.master.stepping import master as master_module

    monkeypatch.setattr(master_module, "_C_SINK_ROWS", 5)
    counts: list = []
    original = native_loop.NativeLoop.handed

    def counted(self):
        result = original(self)
        counts.append(result[0])
        return result
    monkeypatch.setattr(native_loop.NativeLoop, "handed", counted)
    return counts


def test_rows_handed_to_the_text_thread_by_the_c_loop_keep_their_order(tmp_path, c_runs, handed_rows):
    # the C loop queues rows to the CSV writer's thread of C itself; between its runs the master
    # writes the rows of step events: the file is the Python loop's, byte for byte
    (c, c_text), (python, python_text) = both(tmp_path, flagship("      loop_tolerance: 1.0e-13\n"), stop=0.6)
    assert python.events > 10 and c.events == python.events and sum(handed_rows) > 100
    assert c_text == python_text


def test_a_nan_stops_the_rows_handed_over_by_the_c_loop(tmp_path, c_runs, handed_rows):
    # a component whose output becomes NaN after 0.05 s, stepped as Co-Simulation by the C loop:
    # it hands over only rows whose values are all finite, and the master stops at the first row
    # with a NaN, keeping the rows up to it (t = 0.051 s), as the Python loop does
    import sys

    sys.path.insert(0, str(ROOT / "tests" / "apps"))
    try:
        from test_troubleshooting_docs import NAN_SOURCE
    finally:
        sys.path.remove(str(ROOT / "tests" / "apps"))
    (tmp_path / "nanny.py").write_text(NAN_SOURCE)
    path = tmp_path / "s.yaml"
    path.write_text("experiment: {stop: 0.1, step: 1.0e-3}\ncomponents:\n  n: {source: nanny.py, interface: CS}\n")
    system = resolve_system(load_scenario(path))
    messages, texts = failed_both_ways(system, tmp_path)
    assert c_runs and sum(handed_rows) == 50  # the rows after t = 0 up to 0.05 s, five at a time
    assert messages[0] == messages[1] and messages[0].startswith("n.y is NaN at t = 0.051 s"), messages
    assert texts[0] == texts[1] and len(texts[0].splitlines()) == 1 + 52  # header, t = 0 ... 0.051 s
    assert texts[0].splitlines()[-1].endswith(",nan")


def test_runs_returning_by_their_deadline_same_bits(tmp_path, c_runs, handed_rows, monkeypatch):
    # an unpaced call of the C loop returns once its time is up (here at once: after every 4
    # steps), the master calling it again from there: the file is the Python loop's, byte for byte
    from deltafmi.master.stepping import master as master_module

    monkeypatch.setattr(master_module, "_C_RETURN_SECONDS", -1.0)
    # 3 of a call's 4 rows handed over by C as they are recorded, the 4th as the call returns
    monkeypatch.setattr(master_module, "_C_SINK_ROWS", 3)
    (c, c_text), (python, python_text) = both(tmp_path, flagship(), stop=0.2)
    assert c.steps == python.steps == 200 and len(c_runs) == 50 and set(c_runs) == {native_loop.RAN}
    assert c_text == python_text and sum(handed_rows) == 200
