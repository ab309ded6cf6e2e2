"""A third-party FMU in a study: the plain-C bouncing ball of tests/third_party (no Python inside,
its own state snapshots) run case after case on one worker's pooled instance, as Co-Simulation and
as Model Exchange (an event at every bounce), records exactly what the same case run alone on a
fresh instance records, bit for bit: after a case that repeats an earlier initialization (restored
from the ball's own FMU state, its fmi2Terminate held back), after a case whose parameters changed
(reset), after a case whose ball bounced (events) and after a case that failed (a Co-Simulation
step longer than the ball's ``max_step`` is discarded: the instance is freed and the next case gets
a new one). The metric is the height of the first rebound, ``e**2`` times the drop height."""
from __future__ import annotations

from pathlib import Path
from typing import Dict

import numpy as np
import pytest

from deltafmi.apps.studies.plan import plan_study
from deltafmi.apps.studies.pool import FmuPool
from deltafmi.apps.studies.runner import FAILED, OK, CaseTemplate, MemoryRecorder, run_case
from deltafmi.apps.studies.spec import load_study
from deltafmi.master.stepping.master import Master
from third_party.build import build_fmu

#: (restitution, max_step) of the cases, in the order one worker runs them
CASES = [(0.7, 0.0), (0.5, 0.0), (0.7, 0.0), (0.7, 0.001), (0.7, 0.0), (0.5, 0.0)]
STEP = 0.01


@pytest.fixture(scope="module")
def ball(tmp_path_factory) -> Path:
    return build_fmu("BouncingBall", tmp_path_factory.mktemp("ball"))


def alone(template: CaseTemplate, values: Dict[str, float]) -> Dict[str, np.ndarray]:
    """The case run by itself: a master that loads and instantiates the FMU for it."""
    recorders = []

    def recorder(path, names, kinds=None):
        recorders.append(MemoryRecorder(path, names, kinds))
        return recorders[-1]

    system, stop = template.system(values)
    Master(system, result=Path("alone"), stop=stop, writer_class=recorder).run()
    return dict(recorders[0].columns())


@pytest.mark.parametrize("interface", ["CS", "ME"])
@pytest.mark.parametrize("snapshots", [True, False])
def test_pooled_third_party_cases_equal_cases_run_alone(ball, tmp_path, interface, snapshots):
    (tmp_path / "ball.yaml").write_text(f"""\
experiment: {{stop: 1.5, step: {STEP}}}
components:
  ball: {{fmu: {ball}, interface: {interface}, solver: {{rtol: 1.0e-10}}}}
outputs: [ball.h, ball.v, ball.bounces]
""")
    study = tmp_path / "study.yaml"
    study.write_text(f"""\
scenario: ball.yaml
vary:
  zip:
    ball.e: {[e for e, _ in CASES]}
    ball.max_step: {[m for _, m in CASES]}
metrics:
  rebound: {{signal: ball.h, statistic: max, window: {{from: 0.5}}}}
""")
    planned = plan_study(load_study(study))
    template = CaseTemplate(planned.plan, planned.fmu_files)
    pool = FmuPool(snapshots=snapshots)
    try:
        results = [run_case(template, pool, case.id, case.values, keep_timeseries=True) for case in planned.cases]
        restored, created = pool.restored, pool.created
    finally:
        pool.close()
    fails = interface == "CS"  # max_step limits Co-Simulation steps only
    assert [r.status for r in results] == [OK, OK, OK, FAILED if fails else OK, OK, OK], [r.error for r in results]
    if fails:
        assert "longer than the 0.001 s this FMU can take" in results[3].error
    # restored: the third case (its first initialization again); under ME also the fifth and the
    # sixth (the fourth, failed under CS, freed the instance and its snapshots: a new one after it)
    assert restored == (0 if not snapshots else 1 if fails else 3)
    assert created == (2 if fails else 1)
    for case, result in zip(planned.cases, results):
        if result.status != OK:
            continue
        expected = alone(template, case.values)
        assert set(result.timeseries) == set(expected)
        for name, column in expected.items():
            assert np.array_equal(result.timeseries[name], column), (case.id, name)
        # dropped from 1 m, the ball rebounds to e**2 m (sampled every 10 ms: at most g/2 (5 ms)**2 below)
        e = case.values["ball.e"]
        assert e ** 2 - 1.3e-4 <= result.metrics["rebound"] <= e ** 2 + 1e-9, (case.id, result.metrics)
    if interface == "ME":  # every bounce an event, two rows at its time: at t1 = sqrt(2 h / g) and t1 (1 + 2 e)
        t = results[0].timeseries["time"]
        t1 = np.sqrt(2.0 / 9.81)
        np.testing.assert_allclose(t[1:][t[1:] == t[:-1]], [t1, t1 * (1 + 2 * 0.7)], rtol=0, atol=1e-8)
