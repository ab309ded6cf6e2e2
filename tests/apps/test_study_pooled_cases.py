"""Cases run one after another on one worker's pooled FMUs (reset instead of loaded again, the
case's start values set in one call per type after the scenario's) record exactly what a plain
``deltafmi run`` of the same case exported as a scenario records, bit for bit, whatever ran before
on those instances, with the master's buses and wiring of the case before used again (here without
Dask: the worker's own loop, run_case on one FmuPool)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.apps.studies.plan import plan_study
from deltafmi.apps.studies.pool import FmuPool
from deltafmi.apps.studies.runner import OK, CaseTemplate, run_case
from deltafmi.apps.studies.spec import load_study
from deltafmi.master.results.csv_file import columns as read_columns

ROOT = Path(__file__).resolve().parents[2]
STUDY = f"""\
scenario: {ROOT / 'scenarios' / 'delta_tracking.yaml'}
vary:
  zip:
    controller.pole: [5, 12, 8]
    plant.payload: [0.0, 2.0, 0.7]
    plant.z0[3]: [-1.0, -1.05, -0.95]   # one element of a start value the scenario sets whole
    experiment.stop: [0.3, 0.3, 0.3]
metrics:
  max_error: {{signal: plant.z - trajectory.r, statistic: max}}
"""


def plain_run(study: Path, case: int, folder: Path) -> dict:
    """The columns of ``deltafmi run`` of the case exported by ``deltafmi study-case``."""
    scenario, csv = folder / f"case{case}.yaml", folder / f"case{case}.csv"
    exported = CliRunner().invoke(main, ["study-case", str(study), str(case), "-o", str(scenario)])
    assert exported.exit_code == 0, exported.output
    ran = CliRunner().invoke(main, ["run", str(scenario), "-o", str(csv), "-q"])
    assert ran.exit_code == 0, ran.output
    return read_columns(csv)


def test_pooled_cases_equal_plain_runs_bit_for_bit(tmp_path):
    study = tmp_path / "pooled.yaml"
    study.write_text(STUDY)
    planned = plan_study(load_study(study))
    template = CaseTemplate(planned.plan, planned.fmu_files)
    pool = FmuPool()
    try:
        order = [planned.cases[i] for i in (0, 1, 2, 0)]  # case 0 again, after the others used the instances
        results = [run_case(template, pool, case.id, case.values, keep_timeseries=True) for case in order]
    finally:
        pool.close()
    assert [r.status for r in results] == [OK] * 4, [r.error for r in results]
    # the later cases ran on the first one's buses and input/output wiring (same instances)
    assert [w.reuses for w in template.wirings.values()] == [3]
    plain = {case.id: plain_run(study, case.id, tmp_path) for case in planned.cases}
    for case, result in zip(order, results):
        expected = plain[case.id]
        assert set(result.timeseries) == set(expected)
        for name, column in expected.items():
            assert np.array_equal(result.timeseries[name], column), (case.id, name)
    # the cases differ (the comparison above could not pass by accident) and the repeat is exact
    assert not np.array_equal(results[0].timeseries["plant.z[3]"], results[1].timeseries["plant.z[3]"])
    # each started where its case put it (initialization projects onto the constraints: round-off apart)
    assert abs(results[0].timeseries["plant.z[3]"][0] + 1.0) < 1e-12
    assert abs(results[1].timeseries["plant.z[3]"][0] + 1.05) < 1e-12


def test_case_after_an_interrupted_case_reuses_the_c_loop_and_records_the_same_bytes(tmp_path):
    """A case on the instances, wiring and C loop plan of a case stopped part way (its plan left
    where C stopped: mid-run, rows block part filled, solver pointers of the units of that run)
    records exactly what the same case records on a fresh worker (new pool, new plan)."""
    from deltafmi.apps.studies.runner import MemoryRecorder
    from deltafmi.master.stepping.master import Master

    study = tmp_path / "pooled.yaml"
    study.write_text(STUDY)
    planned = plan_study(load_study(study))
    first, stopped, last = planned.cases[0], planned.cases[1], planned.cases[2]
    template = CaseTemplate(planned.plan, planned.fmu_files)
    pool = FmuPool()
    fresh_pool = FmuPool()
    try:
        assert run_case(template, pool, first.id, first.values).status == OK
        wiring, = template.wirings.values()
        loop = wiring.native
        assert loop is not None
        system, stop = template.system(stopped.values)
        master = Master(system, result=tmp_path / "stopped", stop=stop, fmus=pool.lend, writer_class=MemoryRecorder,
                        wirings=template.wirings)
        master.open()
        master.begin_fixed_steps()
        master.advance(37)  # stopped there, as an interrupted case is
        assert master._native is loop and master.steps == 37
        master.close()  # the instances go back to the pool, not discarded
        again = run_case(template, pool, last.id, last.values, keep_timeseries=True)
        assert wiring.native is loop and wiring.reuses == 2
        fresh = run_case(CaseTemplate(planned.plan, planned.fmu_files), fresh_pool, last.id, last.values,
                         keep_timeseries=True)
    finally:
        pool.close()
        fresh_pool.close()
    assert again.status == OK and fresh.status == OK, (again.error, fresh.error)
    assert set(again.timeseries) == set(fresh.timeseries)
    for name, column in fresh.timeseries.items():
        assert column.tobytes() == again.timeseries[name].tobytes(), name
    assert again.metrics == fresh.metrics
    assert len(fresh.timeseries["time"]) > 100
