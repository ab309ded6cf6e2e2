"""Our master against independent formulations of the same co-simulation.

* a 20-line Jacobi loop over fmpy's FMU2Slave written right here (multi-rate included),
* a Gauss-Seidel loop in the same style,
* libcosim through libcosimpy (skipped with the reason when it is missing),

must give the same samples as the master, to 1e-12: on a chain of oscillators fed by the robot,
and on the flagship system (trajectory, controller, robot; all CS). libcosim counts time in
integer nanoseconds, so its comparisons use a step exact in both binary and nanoseconds.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master

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


def reference_loop(fmus: dict, multiples: dict, gauss_seidel: bool = False, links=LINKS, record=RECORD,
                   params: dict | None = None, h: float = H, n: int = N) -> np.ndarray:
    """A plain fmpy co-simulation: set inputs, doStep, repeat. Jacobi unless ``gauss_seidel``.

    ``links`` must be listed in dependency order: initialization feeds them in that order.
    """
    slaves, vr = {}, {}
    for name, path in fmus.items():
        md = read_model_description(str(path))
        vr[name] = {v.name: v.valueReference for v in md.modelVariables}
        slaves[name] = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)), instanceName=name,
                                 modelIdentifier=md.coSimulation.modelIdentifier)
        slaves[name].instantiate()
        slaves[name].setupExperiment(startTime=0.0, stopTime=n * h)
        for var, value in (params or {}).get(name, []):
            setter = slaves[name].setBoolean if isinstance(value, bool) else (
                slaves[name].setInteger if isinstance(value, int) else slaves[name].setReal)
            setter([vr[name][var]], [value])
        slaves[name].enterInitializationMode()
    get = lambda c, v: slaves[c].getReal([vr[c][v]])[0]  # noqa: E731
    feed = lambda links: [slaves[b].setReal([vr[b][u]], [f * value + o])  # noqa: E731
                          for (a, y, b, u, f, o), value in [(l, get(l[0], l[1])) for l in links]]
    for link in links:  # initialization, in dependency order
        feed([link])
    for s in slaves.values():
        s.exitInitializationMode()
    rows = [[0.0] + [get(c, v) for c, v in record]]
    for k in range(n):
        due = [name for name in slaves if k % multiples.get(name, 1) == 0]
        if not gauss_seidel:
            feed([l for l in links if l[2] in due])
        for name in due:
            if gauss_seidel:
                feed([l for l in links if l[2] == name])
            slaves[name].doStep(currentCommunicationPoint=k * h, communicationStepSize=multiples.get(name, 1) * h)
        rows.append([(k + 1) * h] + [get(c, v) for c, v in record])
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


def libcosim_run(fmus: dict, links: list, record: list, params: dict, h: float, n: int) -> np.ndarray:
    """Samples of ``record`` after each of ``n`` libcosim steps (its fixed-step, Jacobi-style algorithm)."""
    pytest.importorskip("libcosimpy", reason="libcosimpy is not installed (pip install libcosimpy)")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_step_size(step_size=int(round(h * 1e9)))
    index, vr = {}, {}
    for name, path in fmus.items():
        index[name] = execution.add_local_slave(CosimLocalSlave(fmu_path=str(path), instance_name=name))
        vr[name] = {v.name.decode(): v.reference for v in execution.slave_variables(index[name])}
        for var, value in params.get(name, []):
            initial = (execution.boolean_initial_value if isinstance(value, bool) else
                       execution.integer_initial_value if isinstance(value, int) else execution.real_initial_value)
            initial(index[name], vr[name][var], value)
    for a, y, b, u, factor, offset in links:
        assert (factor, offset) == (1.0, 0.0)  # libcosim connections carry no factor/offset
        execution.connect_real_variables(index[a], vr[a][y], index[b], vr[b][u])
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    samples = []
    for _ in range(n):
        execution.step()
        samples.append([observer.last_real_values(index[c], [vr[c][v]])[0] for c, v in record])
    return np.array(samples)


def test_jacobi_equals_libcosim(tmp_path, fmus):
    two = {"robot": fmus["robot"], "a": fmus["a"]}
    links = [LINKS[0]]
    record = [("robot", "z[3]"), ("robot", "lambda[1]"), ("a", "F"), ("a", "energy")]
    samples = libcosim_run(two, links, record, {}, H, N)
    path = tmp_path / "two.yaml"
    path.write_text(f"experiment: {{stop: {N * H}, step: {H}}}\nmaster: {{algorithm: jacobi}}\n"
                    f"components:\n  robot: {{fmu: {fmus['robot']}, interface: CS}}\n"
                    f"  a: {{fmu: {fmus['a']}, interface: CS}}\n"
                    "connections:\n  - {from: 'robot.lambda[1]', to: a.F}\n"
                    f"outputs: [{', '.join(repr(c + '.' + v) for c, v in record)}]\n")
    Master(resolve_system(load_scenario(path)), result=tmp_path / "two.csv").run()
    c = columns(tmp_path / "two.csv")
    ours = np.column_stack([c[f"{comp}.{var}"] for comp, var in record])[1:]
    np.testing.assert_allclose(ours, samples, rtol=0, atol=1e-12)


class Flagship:
    """scenarios/delta_tracking.yaml with every component CS and Jacobi, in independent pieces."""

    def __init__(self, build_fmu_from_src, h: float, n: int) -> None:
        self.scenario = yaml.safe_load((Path(__file__).parents[2] / "scenarios" / "delta_tracking.yaml").read_text())
        sources = {"trajectory": "trajectory.py", "controller": "delta_controller.py", "plant": "delta_robot.py"}
        self.fmus = {name: build_fmu_from_src(source) for name, source in sources.items()}
        self.scenario["components"]["controller"]["parameters"]["sample_period"] = h
        self.params = {name: [scalar for var, value in spec.get("parameters", {}).items() for scalar in (
            [(f"{var}[{i + 1}]", v) for i, v in enumerate(value)] if isinstance(value, list) else [(var, value)])]
            for name, spec in self.scenario["components"].items()}
        # in dependency order: the controller's u depends on y and r
        self.links = [("trajectory", f"{s}[{i}]", "controller", f"{s}[{i}]", 1.0, 0.0)
                      for s in ("r", "rd", "rdd") for i in (1, 2, 3)]
        self.links += [("plant", f"{s}[{i}]", "controller", f"{s}[{i}]", 1.0, 0.0) for s in ("y", "yd")
                       for i in (1, 2, 3)]
        self.links += [("controller", f"u[{i}]", "plant", f"u[{i}]", 1.0, 0.0) for i in (1, 2, 3)]
        self.record = [("plant", f"z[{i}]") for i in (1, 2, 3)] + [("controller", f"u[{i}]") for i in (1, 2, 3)]
        self.h, self.n = h, n

    def run_master(self, tmp_path: Path) -> np.ndarray:
        scenario = dict(self.scenario, master={"algorithm": "jacobi"},
                        experiment={"start": 0.0, "stop": self.n * self.h, "step": self.h},
                        outputs=[f"{c}.{v}" for c, v in self.record])
        for name, spec in scenario["components"].items():
            spec.pop("source", None)
            spec.pop("solver", None)  # the plain loops pass no tolerance to fmi2SetupExperiment either
            spec.update(fmu=str(self.fmus[name]), interface="CS")
        path = tmp_path / "flagship.yaml"
        path.write_text(yaml.safe_dump(scenario))
        Master(resolve_system(load_scenario(path)), result=tmp_path / "flagship.csv").run()
        c = columns(tmp_path / "flagship.csv")
        return np.column_stack([c["time"]] + [c[f"{comp}.{var}"] for comp, var in self.record])


def test_flagship_jacobi_equals_plain_fmpy_loop(tmp_path, build_fmu_from_src):
    flagship = Flagship(build_fmu_from_src, h=1e-3, n=150)
    reference = reference_loop(flagship.fmus, {}, links=flagship.links, record=flagship.record,
                               params=flagship.params, h=flagship.h, n=flagship.n)
    ours = flagship.run_master(tmp_path)
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-12)
    assert np.ptp(ours[:, 1]) > 1e-3  # the wrist moved (toward the pick position)


def test_flagship_jacobi_equals_libcosim(tmp_path, build_fmu_from_src):
    flagship = Flagship(build_fmu_from_src, h=H, n=80)  # controller sampled every H too
    samples = libcosim_run(flagship.fmus, flagship.links, flagship.record, flagship.params, flagship.h, flagship.n)
    ours = flagship.run_master(tmp_path)
    np.testing.assert_allclose(ours[1:, 1:], samples, rtol=0, atol=1e-12)
    assert np.ptp(ours[:, 1]) > 1e-4
