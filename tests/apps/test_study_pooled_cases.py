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
