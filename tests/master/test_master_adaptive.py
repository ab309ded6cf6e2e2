"""Adaptive communication step with rollback (fmi2GetFMUstate/fmi2SetFMUstate).

System: oscillator ``a`` (CS, bouncing on its wall: its energy drops at every impact) drives the
force on oscillator ``b`` (ME, no wall). Reference: the same system at a 20x finer fixed step.
"""
from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master

SYSTEM = """\
experiment: {{stop: 2.0, step: {step}}}
master:
  adaptive: {{enabled: {adaptive}, tolerance: {tol}, abs_tolerance: {atol}, error_estimate: {estimate}}}
components:
  a: {{fmu: {a}, interface: CS, solver: {{rtol: 1.0e-10}}, parameters: {{t_step: 100.0}}}}
  b: {{fmu: {b}, interface: ME, solver: {{rtol: 1.0e-10}}, parameters: {{wall: {wall}, t_step: 100.0}}}}
connections:
  - {{from: a.energy, to: b.F, factor: 0.1}}
outputs: [a.energy, b.x, b.v, b.impacts]
"""


@pytest.fixture(scope="module")
def osc(build_fmu_from_src) -> Path:
    return build_fmu_from_src("oscillator.py")


def run(tmp_path: Path, name: str, osc_a: Path, osc_b: Path, warnings: list | None = None, **values):
    settings = dict(step=0.01, adaptive="true", tol=1e-4, atol=1e-6, estimate="double-step", wall=-5.0)
    settings.update(values)
    path = tmp_path / f"{name}.yaml"
    path.write_text(SYSTEM.format(a=osc_a, b=osc_b, **settings))
    warn = (warnings.append if warnings is not None else lambda message: None)
    summary = Master(resolve_system(load_scenario(path)), result=tmp_path / f"{name}.csv", warn=warn).run()
    return summary, columns(tmp_path / f"{name}.csv")


@pytest.fixture(scope="module")
def reference(tmp_path_factory, osc):
    _, c = run(tmp_path_factory.mktemp("ref"), "fine", osc, osc, adaptive="false", step=5e-4)
    return c


def error(c, reference) -> float:
    return float(np.max(np.abs(c["b.x"] - np.interp(c["time"], reference["time"], reference["b.x"]))))


def test_double_step_meets_tolerance_with_fewer_steps(tmp_path, osc, reference):
    _, fixed = run(tmp_path, "fixed", osc, osc, adaptive="false")
    loose, c_loose = run(tmp_path, "loose", osc, osc, tol=1e-4, atol=1e-6)
    tight, c_tight = run(tmp_path, "tight", osc, osc, tol=1e-6, atol=1e-8)
    assert c_loose["time"][-1] == 2.0 and c_tight["time"][-1] == 2.0
    assert loose.rejected > 0 and tight.rejected > 0
    # loose: about as accurate as 200 fixed steps of 10 ms, with a fifth of the steps
    assert loose.steps < 60 and error(c_loose, reference) < 3 * error(fixed, reference)
    # a tighter tolerance costs steps and buys accuracy
    assert tight.steps > 2 * loose.steps
    assert error(c_tight, reference) < 0.5 * error(c_loose, reference)
    steps = np.diff(c_loose["time"])
    assert steps.min() < 0.02 < steps.max()  # the step really adapts


def test_io_gap_estimate_runs_to_stop(tmp_path, osc):
    summary, c = run(tmp_path, "gap", osc, osc, estimate="io-gap", tol=1e-3, atol=1e-4)
    assert c["time"][-1] == 2.0 and summary.steps > 0
    assert summary.rejected > 0  # the energy of a drops at each impact: a big gap, a retry


def test_events_inside_rejected_trials_are_recorded_once(tmp_path, osc):
    # b now bounces on its own wall: its events happen inside trial steps that may be rolled back
    summary, c = run(tmp_path, "events", osc, osc, wall=-0.5)
    t, impacts = c["time"], c["b.impacts"]
    jumps = np.nonzero(np.diff(impacts))[0]
    assert len(jumps) == impacts[-1] >= 2
    for i in jumps:  # each impact: a row just before and a row just after, same time stamp
        assert t[i] == t[i + 1]
    assert np.all(np.diff(t) >= 0)
    assert summary.events >= impacts[-1]


def test_falls_back_to_fixed_step_without_fmu_state(tmp_path, osc):
    stateless = tmp_path / "stateless.fmu"
    with zipfile.ZipFile(osc) as source, zipfile.ZipFile(stateless, "w") as target:
        for item in source.infolist():
            data = source.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'canGetAndSetFMUstate="true"', b'canGetAndSetFMUstate="false"')
            target.writestr(item, data)
    warnings: list = []
    summary, c = run(tmp_path, "fallback", stateless, osc, warnings=warnings)
    assert any("adaptive step needs fmi2GetFMUstate/fmi2SetFMUstate, which a cannot do" in w
               for w in warnings)
    assert summary.steps == 200 and summary.rejected == 0


def test_restore_replays_a_step(tmp_path, osc):
    path = tmp_path / "replay.yaml"
    path.write_text(SYSTEM.format(a=osc, b=osc, step=0.01, adaptive="false", tol=1e-4, atol=1e-6,
                                  estimate="double-step", wall=-0.5))
    master = Master(resolve_system(load_scenario(path)), result=tmp_path / "replay.csv")
    master.open()
    try:
        units = master.ordered_units()
        for k in range(30):
            master.step_all(units, k * 0.01, 0.01)
        snapshot = master.save()
        master.step_all(units, 0.30, 0.07)  # crosses an impact of a and of b
        first = master.buses["Real"].copy()
        master.restore(snapshot)
        master.step_all(units, 0.30, 0.07)
        replay = master.buses["Real"]
        assert replay[0] == first[0]  # a (CS): its whole state is the FMU state
        # b (ME): the FMU state is exact; CVODE restarts from it (its step history is not part of it)
        np.testing.assert_allclose(replay[1:], first[1:], rtol=1e-7)
        master.release(snapshot)
    finally:
        master.close()
    shutil.rmtree(tmp_path, ignore_errors=True)
