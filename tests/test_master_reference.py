"""Our master against independent formulations of the same co-simulation.

* a 20-line Jacobi loop over fmpy's FMU2Slave written right here (multi-rate included),
* a Gauss-Seidel loop in the same style,
* libcosim through libcosimpy (skipped with the reason when it is missing),

must give the same samples as the master, to 1e-12.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from deltafmi.cosim.master import Master
from deltafmi.cosim.resolve import resolve_system
from deltafmi.cosim.results import columns
from deltafmi.cosim.scenario import load_scenario

H, N = 1.0 / 512, 100  # a step exact in binary and in libcosim's integer nanoseconds
# (source component, output, target component, input, factor, offset)
LINKS = [("robot", "lambda[1]", "a", "F", 1.0, 0.0),
         ("a", "energy", "b", "F", 0.05, -0.3),
         ("b", "energy", "c", "F", 0.05, 0.0)]
RECORD = [("robot", "z[3]"), ("a", "energy"), ("b", "F"), ("b", "energy"), ("c", "F"), ("c", "energy")]


@pytest.fixture(scope="module")
def fmus(build_fmu_from_src) -> dict:
    osc = build_fmu_from_src("oscillator.py")
    return {"robot": build_fmu_from_src("delta_robot.py"), "a": osc, "b": osc, "c": osc}


def reference_loop(fmus: dict, multiples: dict, gauss_seidel: bool = False) -> np.ndarray:
    """A plain fmpy co-simulation: set inputs, doStep, repeat. Jacobi unless ``gauss_seidel``."""
    slaves, vr = {}, {}
    for name, path in fmus.items():
        md = read_model_description(str(path))
        vr[name] = {v.name: v.valueReference for v in md.modelVariables}
        slaves[name] = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)), instanceName=name,
                                 modelIdentifier=md.coSimulation.modelIdentifier)
        slaves[name].instantiate()
        slaves[name].setupExperiment(startTime=0.0, stopTime=N * H)
        slaves[name].enterInitializationMode()
    get = lambda c, v: slaves[c].getReal([vr[c][v]])[0]  # noqa: E731
    feed = lambda links: [slaves[b].setReal([vr[b][u]], [f * value + o])  # noqa: E731
                          for (a, y, b, u, f, o), value in [(l, get(l[0], l[1])) for l in links]]
    for link in LINKS:  # initialization, in dependency order (LINKS is listed in it)
        feed([link])
    for s in slaves.values():
        s.exitInitializationMode()
    rows = [[0.0] + [get(c, v) for c, v in RECORD]]
    for k in range(N):
        due = [n for n in slaves if k % multiples.get(n, 1) == 0]
        if not gauss_seidel:
            feed([l for l in LINKS if l[2] in due])
        for name in due:
            if gauss_seidel:
                feed([l for l in LINKS if l[2] == name])
            slaves[name].doStep(currentCommunicationPoint=k * H, communicationStepSize=multiples.get(name, 1) * H)
        rows.append([(k + 1) * H] + [get(c, v) for c, v in RECORD])
    for s in slaves.values():
        s.terminate()
        s.freeInstance()
    return np.array(rows)


def run_master(tmp_path: Path, fmus: dict, algorithm: str, multiples: dict) -> np.ndarray:
    components = "\n".join(f"  {n}: {{fmu: {p}, interface: CS, step_multiple: {multiples.get(n, 1)}}}"
                           for n, p in fmus.items())
    links = "\n".join(f"  - {{from: '{a}.{y}', to: '{b}.{u}', factor: {f}, offset: {o}}}"
                      for a, y, b, u, f, o in LINKS)
    outputs = ", ".join(f"'{c}.{v}'" for c, v in RECORD)
    path = tmp_path / f"{algorithm}.yaml"
    path.write_text(f"experiment: {{start: 0.0, stop: {N * H}, step: {H}}}\n"
                    f"master: {{algorithm: {algorithm}}}\n"
                    f"components:\n{components}\nconnections:\n{links}\noutputs: [{outputs}]\n")
    Master(resolve_system(load_scenario(path)), result=tmp_path / f"{algorithm}.csv").run()
    c = columns(tmp_path / f"{algorithm}.csv")
    return np.column_stack([c["time"]] + [c[f"{comp}.{var}"] for comp, var in RECORD])


def test_jacobi_equals_plain_fmpy_loop(tmp_path, fmus):
    ours = run_master(tmp_path, fmus, "jacobi", {})
    reference = reference_loop(fmus, {})
    assert ours.shape == reference.shape == (N + 1, len(RECORD) + 1)
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-12)
    assert np.ptp(ours[:, 3]) > 0.05  # the coupling matters: b's force moves


def test_jacobi_multi_rate_equals_plain_fmpy_loop(tmp_path, fmus):
    multiples = {"b": 4, "c": 10}
    ours = run_master(tmp_path, fmus, "jacobi", multiples)
    reference = reference_loop(fmus, multiples)
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-12)
    # b takes a new input only when it steps (k = 0, 4, 8, ...: rows k + 1) and holds it 4 steps
    changes = np.nonzero(np.diff(ours[:, 3]))[0] + 1
    assert set(changes % 4) == {1}


def test_gauss_seidel_equals_plain_sequential_loop(tmp_path, fmus):
    ours = run_master(tmp_path, fmus, "gauss-seidel", {})
    reference = reference_loop(fmus, {}, gauss_seidel=True)
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-12)
    jacobi = reference_loop(fmus, {})
    assert np.max(np.abs(reference[:, 3] - jacobi[:, 3])) > 1e-6  # and it is not Jacobi


def test_jacobi_equals_libcosim(tmp_path, fmus):
    pytest.importorskip("libcosimpy", reason="libcosimpy is not installed (pip install libcosimpy)")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.ERROR)
    plain = [l for l in LINKS if l[4:] == (1.0, 0.0)]  # libcosim connections carry no factor/offset
    execution = CosimExecution.from_step_size(step_size=int(round(H * 1e9)))
    index, vr = {}, {}
    for name in ("robot", "a"):
        index[name] = execution.add_local_slave(CosimLocalSlave(fmu_path=str(fmus[name]), instance_name=name))
        vr[name] = {v.name.decode(): v.reference for v in execution.slave_variables(index[name])}
    for a, y, b, u, _, _ in plain:
        execution.connect_real_variables(index[a], vr[a][y], index[b], vr[b][u])
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    record = [("robot", "z[3]"), ("robot", "lambda[1]"), ("a", "F"), ("a", "energy")]
    samples = []
    for _ in range(N):
        execution.step()
        samples.append([observer.last_real_values(index[c], [vr[c][v]])[0] for c, v in record])

    path = tmp_path / "two.yaml"
    path.write_text(f"experiment: {{stop: {N * H}, step: {H}}}\nmaster: {{algorithm: jacobi}}\n"
                    f"components:\n  robot: {{fmu: {fmus['robot']}, interface: CS}}\n"
                    f"  a: {{fmu: {fmus['a']}, interface: CS}}\n"
                    "connections:\n  - {from: 'robot.lambda[1]', to: a.F}\n"
                    f"outputs: [{', '.join(repr(c + '.' + v) for c, v in record)}]\n")
    Master(resolve_system(load_scenario(path)), result=tmp_path / "two.csv").run()
    c = columns(tmp_path / "two.csv")
    ours = np.column_stack([c[f"{comp}.{var}"] for comp, var in record])[1:]
    np.testing.assert_allclose(ours, np.array(samples), rtol=0, atol=1e-12)
