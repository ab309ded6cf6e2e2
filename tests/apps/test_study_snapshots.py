"""A pooled unit whose initialization repeats one of its earlier ones is restored from an FMU
state snapshot (fmi2GetFMUstate right after that initialization, fmi2SetFMUstate instead of reset
and initialized again): the cases record exactly what a plain ``deltafmi run`` of each records, bit
for bit, on a real Dask worker; and a unit whose parameters take a new value is initialized afresh.

The flagship's trajectory never changes in these studies, the controller only where its pole does
(it is restored when an earlier case had the same pole: the values copied into it at
initialization, from the trajectory and the plant, are the same), the plant (Model Exchange, its
payload varied) where an earlier case had the same payload.
"""
from __future__ import annotations

import struct
from pathlib import Path
from typing import List

import numpy as np
import pytest

from deltafmi.apps.studies.driver import dask_client, open_store, run_study
from deltafmi.apps.studies.plan import plan_study
from deltafmi.apps.studies.pool import FmuPool
from deltafmi.apps.studies.runner import OK, CaseResult, CaseTemplate, run_case
from deltafmi.apps.studies.spec import load_study
from deltafmi.apps.studies.worker import worker_cache
from test_study_pooled_cases import plain_run  # a case exported by study-case, then deltafmi run

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "delta_tracking.yaml"


def assert_same_as_plain(study: Path, results: List[CaseResult], folder: Path) -> None:
    plain = {case: plain_run(study, case, folder) for case in sorted({r.case for r in results})}
    for result in results:
        assert result.status == OK, result.error
        expected = plain[result.case]
        assert set(result.timeseries) == set(expected)
        for name, column in expected.items():
            assert np.array_equal(result.timeseries[name], column), (result.case, name)


def _stream_seconds(seconds: float) -> float:
    """Set the worker's time between two sends of results; the time it had (run on the worker)."""
    from deltafmi.apps.studies import worker

    before, worker.STREAM_SECONDS = worker.STREAM_SECONDS, seconds
    return before


def restored_on_workers(client) -> int:
    return sum(client.run(lambda: worker_cache().pool.restored).values())


@pytest.fixture(scope="module")
def client():
    """A local cluster of one worker process (cases run one after another, in order)."""
    with dask_client(workers=1) as made:
        yield made


def test_snapshot_cases_equal_plain_runs_on_dask(client, tmp_path):
    study = tmp_path / "snapshots.yaml"
    study.write_text(f"""\
scenario: {SCENARIO}
vary:
  zip:
    controller.pole: [5, 5, 8, 8, 5]
    plant.payload: [0.0, 2.0, 2.0, 0.5, 0.0]
    experiment.stop: [0.3, 0.3, 0.3, 0.3, 0.3]
metrics:
  max_error: {{signal: plant.z - trajectory.r, statistic: max}}
result: {{timeseries: true}}
""")
    planned = plan_study(load_study(study))
    results: List[CaseResult] = []
    before = restored_on_workers(client)
    store = open_store(planned, tmp_path / "snapshots.parquet", timeseries=True)
    todo = store.open(planned.cases, fresh=True)
    report = run_study(planned, store, todo, client=client, workers=1, on_result=results.append)
    store.close()
    restored = restored_on_workers(client) - before
    assert report.failed == 0 and len(results) == 5
    # one worker ran the five cases in order: the trajectory was restored in the four after the
    # first, the controller in the three whose pole an earlier case had (cases 1, 3 and 4), the
    # plant (Model Exchange) in the two whose payload an earlier case had (cases 2 and 4)
    assert restored == 4 + 3 + 2
    assert_same_as_plain(study, results, tmp_path)
    by_case = {r.case: r for r in results}
    assert not np.array_equal(by_case[0].timeseries["controller.u[1]"], by_case[2].timeseries["controller.u[1]"])


def test_changed_parameters_initialize_afresh(tmp_path):
    study = tmp_path / "trajectory.yaml"
    study.write_text(f"""\
scenario: {SCENARIO}
vary:
  zip:
    trajectory.dwell: [0.1, 0.1, 0.25, 0.25]
    plant.payload: [0.0, 1.0, 1.0, 1.0]
    experiment.stop: [0.4, 0.4, 0.4, 0.4]
metrics:
  max_error: {{signal: plant.z - trajectory.r, statistic: max}}
""")
    planned = plan_study(load_study(study))
    template = CaseTemplate(planned.plan, planned.fmu_files)
    pool = FmuPool()
    restored: List[int] = []
    try:
        results = []
        for case in planned.cases:
            results.append(run_case(template, pool, case.id, case.values, keep_timeseries=True))
            restored.append(pool.restored)
    finally:
        pool.close()
    # case 1: trajectory and controller as in case 0 (the plant's payload is not copied into the
    # controller at initialization), the plant's payload new; case 2: the trajectory's dwell
    # changed, so the trajectory is initialized, while the controller is restored (what the
    # trajectory gives it at t = 0, the first waypoint at rest, does not depend on the dwell) and
    # the plant too (case 1's payload); case 3 repeats case 2
    assert np.diff([0] + restored).tolist() == [0, 2, 2, 3]
    assert_same_as_plain(study, results, tmp_path)
    # the changed dwell holds the reference at its first waypoint longer: the trajectory did change
    assert not np.array_equal(results[1].timeseries["trajectory.r[1]"], results[2].timeseries["trajectory.r[1]"])
    assert np.array_equal(results[2].timeseries["trajectory.r[1]"], results[3].timeseries["trajectory.r[1]"])


def test_without_snapshots_same_records(tmp_path):
    """A pool without snapshots resets and initializes every unit, with the same records."""
    study = tmp_path / "plain.yaml"
    study.write_text(f"""\
scenario: {SCENARIO}
vary:
  zip:
    controller.pole: [6, 6]
    plant.payload: [0.0, 1.5]
    experiment.stop: [0.2, 0.2]
metrics:
  max_error: {{signal: plant.z - trajectory.r, statistic: max}}
""")
    planned = plan_study(load_study(study))
    template = CaseTemplate(planned.plan, planned.fmu_files)
    records = {}
    for snapshots in (False, True):
        pool = FmuPool(snapshots=snapshots)
        try:
            records[snapshots] = [run_case(template, pool, c.id, c.values, keep_timeseries=True)
                                  for c in planned.cases]
            assert pool.restored == (2 if snapshots else 0)
        finally:
            pool.close()
    for fresh, restored in zip(records[False], records[True]):
        assert fresh.status == restored.status == OK
        for name, column in fresh.timeseries.items():
            assert np.array_equal(restored.timeseries[name], column), name


def test_results_reach_the_files_while_their_batch_runs(client, tmp_path):
    """Without time series the cases' results are streamed to the client as they finish (a few at
    a time): rows of a batch are in the journal while the batch's task is still running, and
    stopping the study there keeps them (a re-run does only the rest)."""
    study = tmp_path / "streamed.yaml"
    study.write_text(f"""\
scenario: {SCENARIO}
vary:
  grid:
    plant.payload: {{from: 0.0, to: 1.1, step: 0.1}}
    controller.pole: [6, 7]
metrics:
  max_error: {{signal: plant.z - trajectory.r, statistic: max}}
""")
    planned = plan_study(load_study(study))
    assert len(planned.cases) == 24
    store = open_store(planned, tmp_path / "streamed.parquet", timeseries=False)
    todo = store.open(planned.cases, fresh=True)
    seen: List[tuple] = []

    def arrived(result: CaseResult) -> None:
        processing = {key for keys in client.processing().values() for key in keys}
        lines = store.journal.read_text().count("\n") - 1  # the first line names the study
        seen.append((result.case, processing, lines))
        if len(seen) == 12:
            raise KeyboardInterrupt  # as Ctrl-C does, in the middle of the study

    # the worker sends each result as soon as its case ends: with its usual 0.25 s between sends, a
    # fast machine runs the whole batch (24 cases of ~10 ms) before the first send, and no result
    # would arrive while its task runs, which is what this test looks at
    every = client.run(lambda: _stream_seconds(0.0))
    try:
        report = run_study(planned, store, todo, client=client, workers=1, on_result=arrived)
    finally:
        client.run(lambda: _stream_seconds(min(every.values())))
    store.close()
    assert report.interrupted
    # a worker runs one task at a time, tasks hold cases in order and are named after their first
    # case: a case that arrived while a task of a first case at or before it was running arrived
    # while its own task ran (the batches after the first two hold several cases)
    def first_case(key: str) -> int:
        return int(key.split("-")[3])

    during = [(case, lines) for case, processing, lines in seen
              if any(first_case(key) <= case for key in processing)]
    assert len(during) >= 3, seen
    # each in the journal when it came
    assert all(lines == [c for c, _, _ in seen].index(case) + 1 for case, lines in during), seen
    # stopped there: the twelve, and what had arrived meanwhile, stay recorded; a re-run does the rest
    again = open_store(planned, tmp_path / "streamed.parquet", timeseries=False)
    left = again.open(planned.cases)
    again.close()
    done = {case for case, _, _ in seen}
    assert len(done) >= 12 and {c.id for c in left} == {c.id for c in planned.cases} - done


def test_the_least_recently_used_snapshot_goes_beyond_the_limit(tmp_path):
    """With one initialization kept per instance, a pole or payload seen two cases before is
    initialized again (the snapshot was dropped for the one between); the records are those of a
    pool without snapshots, bit for bit."""
    study = tmp_path / "limit.yaml"
    study.write_text(f"""\
scenario: {SCENARIO}
vary:
  zip:
    controller.pole: [5, 5, 8, 8, 5]
    plant.payload: [0.0, 2.0, 2.0, 0.5, 0.0]
    experiment.stop: [0.2, 0.2, 0.2, 0.2, 0.2]
metrics:
  max_error: {{signal: plant.z - trajectory.r, statistic: max}}
""")
    planned = plan_study(load_study(study))
    template = CaseTemplate(planned.plan, planned.fmu_files)
    records, restored = {}, {}
    for keep in (0, 1, 32):
        pool = FmuPool(snapshots=keep > 0, keep=keep)
        try:
            records[keep] = [run_case(template, pool, c.id, c.values, keep_timeseries=True) for c in planned.cases]
            restored[keep] = pool.restored
        finally:
            pool.close()
    # trajectory 4 either way; controller in cases 1 and 3 (and 4 with pole 5 still kept); plant in
    # case 2 (and 4 with payload 0 still kept)
    assert restored == {0: 0, 1: 4 + 2 + 1, 32: 4 + 3 + 2}
    for keep in (1, 32):
        for fresh, result in zip(records[0], records[keep]):
            assert fresh.status == result.status == OK
            for name, column in fresh.timeseries.items():
                assert np.array_equal(result.timeseries[name], column), (keep, result.case, name)


def test_fmi3_units_are_restored_too(tmp_path):
    """The flagship built as FMI 3.0 (fmi3GetFMUState right after fmi3ExitInitializationMode,
    fmi3SetFMUState instead of fmi3Reset and initialized again): the records of a pool without
    snapshots, bit for bit. The controller, a sampled FMI 3.0 unit, has a periodic Clock whose
    interval the master asks in initialization (fmi3GetIntervalDecimal, into arrays of its own that
    a transcript does not fill): it is initialized as usual in every case."""
    (tmp_path / "flagship3.yaml").write_text(f"fmi_version: 3\n{SCENARIO.read_text()}")
    study = tmp_path / "fmi3.yaml"
    study.write_text("""\
scenario: flagship3.yaml
vary:
  zip:
    controller.pole: [5, 5, 8, 5]
    plant.payload: [0.0, 2.0, 2.0, 0.0]
    experiment.stop: [0.2, 0.2, 0.2, 0.2]
metrics:
  max_error: {signal: plant.z - trajectory.r, statistic: max}
""")
    planned = plan_study(load_study(study))
    template = CaseTemplate(planned.plan, planned.fmu_files)
    records, restored = {}, {}
    for snapshots in (False, True):
        pool = FmuPool(snapshots=snapshots)
        try:
            records[snapshots] = [run_case(template, pool, c.id, c.values, keep_timeseries=True)
                                  for c in planned.cases]
            restored[snapshots] = pool.restored
        finally:
            pool.close()
    # trajectory in cases 1-3, plant in 2 and 3
    assert restored == {False: 0, True: 3 + 2}
    for fresh, result in zip(records[False], records[True]):
        assert fresh.status == result.status == OK, (fresh.error, result.error)
        for name, column in fresh.timeseries.items():
            assert np.array_equal(result.timeseries[name], column), (result.case, name)


def test_call_keys_of_mixed_numbers_are_bit_exact():
    """A set call's values of floats and ints (a study's integer grid value among the scenario's
    floats) match only the same values of the same types, bit for bit."""
    from deltafmi.apps.studies.snapshots import call_key

    def key(values):
        return call_key("setReal", ([1, 2, 3], values), {})

    assert key([0.5, 0.0, 3]) == key([0.5, 0.0, 3])
    assert key([0.5, 0.0, 3]) != key([0.5, 0.0, 3.0])  # 3 is not 3.0
    assert key([0.5, 0.0, 3]) != key([0.5, -0.0, 3])  # nor -0.0 0.0
    assert key([0.5, float("nan"), 3]) == key([0.5, float("nan"), 3])
    big = 2 ** 53
    assert key([0.5, big, 3]) != key([0.5, big + 1, 3])  # the same double, not the same int
    assert key([0.5, True]) != key([0.5, 1])  # a bool is not an int
    quiet, other = struct.unpack("<d", struct.pack("<Q", 0x7FF8000000000001))[0], float("nan")
    assert key([quiet]) != key([other])  # NaNs of other payloads
    assert key((0.5, 1)) == key([0.5, 1])  # a tuple is taken as a list
    text, built = "ab", "".join(["a", "b"])
    assert text is not built and call_key("setString", ([1, 2], [text, text]), {}) == \
        call_key("setString", ([1, 2], [text, built]), {})  # equal strings, whether one object or two
    assert call_key("setupExperiment", (), {"startTime": 0.0, "stopTime": 1.0}) == \
        call_key("setupExperiment", (), {"stopTime": 1.0, "startTime": 0.0})
    assert call_key("getReal", ([1],), {"x": lambda: 0}) != call_key("getReal", ([1],), {"x": lambda: 0})
