"""How a sweep groups cases into Dask tasks (deltafmi/apps/studies/batches.py)."""
from deltafmi.apps.studies.batches import MAX_BATCH, TASK_SECONDS, Batcher
from deltafmi.apps.studies.cases import Case


def cases(n):
    return [Case(i, {"p": float(i)}) for i in range(n)]


def drain(batcher):
    batches = []
    while batcher:
        batches.append(batcher.next())
    return batches


def test_one_case_per_task_until_a_case_has_been_timed():
    batcher = Batcher(cases(100), workers=2)
    assert [len(batcher.next().cases) for _ in range(3)] == [1, 1, 1]


def test_tasks_hold_about_task_seconds_and_leave_every_worker_a_share_of_the_rest():
    batcher = Batcher(cases(200), workers=2)
    for _ in range(5):
        batcher.observe(TASK_SECONDS / 4)  # four cases per task
    sizes = [len(b.cases) for b in drain(batcher)]
    assert sizes[0] == 4 and sum(sizes) == 200
    # the end: never more than the remaining cases over twice the workers
    remaining = 200
    for size in sizes:
        assert size == 1 or size <= remaining // 4
        remaining -= size
    assert sizes[-4:] == [1, 1, 1, 1]


def test_short_cases_are_capped_and_long_ones_go_alone():
    short = Batcher(cases(1000), workers=1)
    short.observe(1e-6)
    assert len(short.next().cases) == MAX_BATCH
    long = Batcher(cases(1000), workers=1)
    long.observe(10 * TASK_SECONDS)
    assert len(long.next().cases) == 1


def test_the_cases_of_a_task_whose_worker_died_run_again_first_and_alone():
    batcher = Batcher(cases(40), workers=1)
    batcher.observe(TASK_SECONDS / 5)
    died = batcher.next()
    assert len(died.cases) == 5 and not died.alone
    batcher.run_again(died)
    again = [batcher.next() for _ in range(5)]
    assert [b.cases[0].id for b in again] == [c.id for c in died.cases]
    assert all(b.alone and len(b.cases) == 1 for b in again)
    rest = drain(batcher)
    assert not any(b.alone for b in rest)
    assert sorted(c.id for b in [died, *rest] for c in b.cases) == list(range(40))


def test_streamed_results_allow_long_tasks_and_one_worker_takes_the_rest_at_once():
    from deltafmi.apps.studies.batches import STREAMED_BATCH, STREAMED_SECONDS

    one = Batcher(cases(100), workers=1, streamed=True)
    assert len(one.next().cases) == 100  # nothing to balance with: no case timed first
    one = Batcher(cases(100), workers=1, streamed=True)
    one.observe(STREAMED_SECONDS / 1000)
    assert len(one.next().cases) == 100  # no other worker to share the end with
    big = Batcher(cases(10_000), workers=1, streamed=True)
    big.observe(1e-6)
    assert len(big.next().cases) == STREAMED_BATCH
    two = Batcher(cases(100), workers=2, streamed=True)
    two.observe(STREAMED_SECONDS / 1000)
    sizes = [len(b.cases) for b in drain(two)]
    assert sizes[0] == 25 and sum(sizes) == 100 and sizes[-1] == 1  # each worker a share of the end


def test_streamed_only_the_case_that_was_running_when_the_worker_died_runs_alone():
    batcher = Batcher(cases(40), workers=1, streamed=True)
    batcher.observe(0.5)  # ten cases per task of STREAMED_SECONDS
    died = batcher.next()
    assert len(died.cases) == 10
    # the first three were streamed before the death: the driver hands back the other seven
    batcher.run_again(type(died)(died.cases[3:]))
    alone = batcher.next()
    assert alone.alone and [c.id for c in alone.cases] == [died.cases[3].id]
    rest = drain(batcher)
    assert not any(b.alone for b in rest)
    assert [c.id for b in rest for c in b.cases] == [c.id for c in died.cases[4:]] + list(range(10, 40))
