"""fmi2GetDirectionalDerivative: every FMU of fmu_src/ against central differences taken as an
importer takes them (fmpy, through the FMI calls); the delta robot's exact derivatives against
Richardson-extrapolated differences of the library; the master's CVODE with those derivatives."""
from __future__ import annotations

import ctypes
from pathlib import Path
from typing import Optional

import fmpy
import numpy as np
import pytest
from fmpy.fmi2 import FMU2Model
from fmpy.validation import validate_fmu

from conftest import FMU_SRC, MODEL_FILES
from deltafmi.physics import delta as d
from deltafmi.physics.delta.jacobian import plant_jacobian

SOURCES = MODEL_FILES
#: start values: Newton's cradle's balls touch at rest, where the contact force has a kink (and
#: pressed together they meet a law stiff as overlap^4): with 1 cm between them every contact is free
START = {"newtons_cradle.py": {"gap": 0.01}}


def _pointer(a: np.ndarray):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


class _Importer:
    """What an importer sees of an ME FMU in continuous-time mode (fmpy calls only)."""

    def __init__(self, fmu: Path, directory: Path, start: Optional[dict] = None) -> None:
        md = self.md = fmpy.read_model_description(str(fmu))
        self.model = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu), str(directory)),
                               modelIdentifier=md.modelExchange.modelIdentifier)
        self.model.instantiate()
        self.model.setupExperiment(startTime=0.0)
        for name, value in (start or {}).items():
            self.model.setReal([next(v.valueReference for v in md.modelVariables if v.name == name)], [value])
        self.model.enterInitializationMode()
        self.model.exitInitializationMode()
        while self.model.newDiscreteStates()[0]:
            pass
        self.nx = md.numberOfContinuousStates
        self.states = [u.variable.derivative.valueReference for u in md.derivatives]
        self.derivatives = [u.variable.valueReference for u in md.derivatives]
        real = [v for v in md.modelVariables if v.type == "Real"]
        self.inputs = [v.valueReference for v in real if v.causality == "input" and v.variability == "continuous"]
        self.outputs = [v.valueReference for v in real if v.causality == "output" and v.variability == "continuous"]
        self.discrete_outputs = [v.valueReference for v in real if v.causality == "output" and v.variability == "discrete"]
        self.nominal = {v.valueReference: abs(float(v.nominal)) for v in real if v.nominal}
        self.names = {v.valueReference: v.name for v in md.modelVariables}

    def get_x(self) -> np.ndarray:
        x = np.zeros(self.nx)
        self.model.getContinuousStates(_pointer(x), self.nx)
        return x

    def set_x(self, x: np.ndarray) -> None:
        if self.nx:
            x = np.ascontiguousarray(x, dtype=float)
            self.model.setContinuousStates(_pointer(x), self.nx)

    def unknown_values(self, unknowns: list) -> np.ndarray:
        dx = np.zeros(max(self.nx, 1))
        if self.nx:
            self.model.getDerivatives(_pointer(dx), self.nx)
        index = {vr: i for i, vr in enumerate(self.derivatives)}
        others = [vr for vr in unknowns if vr not in index]
        values = dict(zip(others, self.model.getReal(others))) if others else {}
        return np.array([dx[index[vr]] if vr in index else values[vr] for vr in unknowns])

    def directional(self, unknowns: list, knowns: list) -> np.ndarray:
        """One column per known, as an importer builds a Jacobian: seed 1 on that known."""
        return np.column_stack([self.model.getDirectionalDerivative(unknowns, [k], [1.0]) for k in knowns])

    def differences(self, unknowns: list, knowns: list) -> np.ndarray:
        """Central differences through fmi2SetContinuousStates / fmi2SetReal, Richardson-extrapolated
        (truncation error of fourth order: this reference is far more accurate than the tolerance)."""
        x0 = self.get_x()
        u0 = dict(zip(self.inputs, self.model.getReal(self.inputs))) if self.inputs else {}

        def at(vr: int, offset: float) -> np.ndarray:
            if vr in self.states:
                x = x0.copy()
                x[self.states.index(vr)] += offset
                self.set_x(x)
            else:
                self.model.setReal([vr], [u0[vr] + offset])
            values = self.unknown_values(unknowns)
            self.set_x(x0)
            if vr in u0:
                self.model.setReal([vr], [u0[vr]])
            return values

        columns = []
        for vr in knowns:
            value = x0[self.states.index(vr)] if vr in self.states else u0[vr]
            h = 1e-4 * max(abs(value), self.nominal.get(vr, 1.0))
            d1 = (at(vr, h) - at(vr, -h)) / (2 * h)
            d2 = (at(vr, h / 2) - at(vr, -h / 2)) / h
            columns.append((4 * d2 - d1) / 3)
        return np.column_stack(columns)

    def close(self) -> None:
        self.model.terminate()
        self.model.freeInstance()


def _assert_close(importer: _Importer, exact: np.ndarray, reference: np.ndarray, unknowns: list, knowns: list,
                  rtol: float) -> None:
    """Entry by entry, relative to the largest entry of its row (rows mix N, m and rad)."""
    scale = np.max(np.abs(reference), axis=1, keepdims=True)
    error = np.abs(exact - reference) / np.where(scale > 0, scale, 1.0)
    i, j = np.unravel_index(np.argmax(error), error.shape)
    assert error.max() <= rtol, (f"d {importer.names[unknowns[i]]} / d {importer.names[knowns[j]]}: "
                                 f"{exact[i, j]!r} against {reference[i, j]!r} (row scale {scale[i, 0]:.3g})")


@pytest.mark.parametrize("source", SOURCES)
def test_directional_derivatives_equal_central_differences(build_fmu_from_src, tmp_path, source):
    """Derivatives and continuous outputs by states and inputs, in continuous-time mode, at a point
    off the start (every state moved by 1 % of its scale: velocities, and for the robots a
    distance from the closed loops at which the residual norm |h| is smooth), to 1e-6 relative to
    the largest entry of each row."""
    fmu = build_fmu_from_src(source)
    assert validate_fmu(str(fmu)) == []
    importer = _Importer(fmu, tmp_path / "fmu", START.get(source, {}))
    md = importer.md
    assert md.modelExchange.providesDirectionalDerivative and md.coSimulation.providesDirectionalDerivative
    try:
        importer.model.enterContinuousTimeMode()
        if importer.nx:
            x = importer.get_x()
            scale = np.maximum(np.abs(x), [importer.nominal.get(vr, 1.0) for vr in importer.states])
            importer.set_x(x + 1e-2 * scale * np.random.default_rng(7).standard_normal(importer.nx))
        unknowns = importer.derivatives + importer.outputs
        knowns = importer.states + importer.inputs
        if not knowns or not unknowns:
            # nothing to differentiate (Trajectory: no states, no Real inputs): the call still works
            assert importer.model.getDirectionalDerivative(unknowns or importer.discrete_outputs, [], []) == \
                [0.0] * len(unknowns or importer.discrete_outputs)
            return
        exact = importer.directional(unknowns, knowns)
        _assert_close(importer, exact, importer.differences(unknowns, knowns), unknowns, knowns, 1e-6)
    finally:
        importer.close()


def test_discrete_outputs_in_event_mode(build_fmu_from_src, tmp_path):
    """FMI 2.0 adds the discrete Real outputs to the unknowns in event mode: the controller's torques
    change only at its samples, so by its inputs between samples they do not move (0 both ways)."""
    importer = _Importer(build_fmu_from_src("delta_controller.py"), tmp_path / "fmu")
    try:
        unknowns, knowns = importer.discrete_outputs, importer.inputs
        exact = importer.directional(unknowns, knowns)
        assert exact.shape == (len(unknowns), len(knowns)) and not exact.any()
        assert not importer.differences(unknowns, knowns).any()
    finally:
        importer.close()


def test_a_parameter_is_no_known(build_fmu_from_src, tmp_path):
    """FMI 2.0 knowns are states and inputs: a parameter is refused with fmi2Error."""
    importer = _Importer(build_fmu_from_src("oscillator.py"), tmp_path / "fmu")
    try:
        importer.model.enterContinuousTimeMode()
        parameter = next(v.valueReference for v in importer.md.modelVariables if v.name == "k")
        with pytest.raises(fmpy.fmi1.FMICallException):
            importer.model.getDirectionalDerivative(importer.derivatives, [parameter], [1.0])
    finally:
        importer.model.freeInstance()


@pytest.mark.parametrize("case", ["rest", "moving"])
def test_robot_jacobian_is_exact(case):
    """plant_jacobian against the library's own evaluation, Richardson-extrapolated central
    differences (fourth order): agreement to rounding, far below any difference formula's error."""
    p = d.DeltaParams(payload=1.0, damping=0.3)
    rng = np.random.default_rng(5)
    q = d.inverse_kinematics(p, (0.15, -0.2, -0.95))
    v = np.zeros(9) if case == "rest" else rng.normal(0.0, 1.0, 9)
    q = q + (0.0 if case == "rest" else rng.normal(0.0, 1e-3, 9))
    u, f, pole = np.array([20.0, -5.0, 13.0]), np.array([3.0, -7.0, 11.0]), 5.0

    def outputs(w):
        vdot, lam = d.accelerations(p, w[:9], w[9:18], w[18:21], w[21:], pole)
        ev = d.evaluate_plant(p, w[:9], w[9:18], w[18:21], w[21:], pole)
        return np.concatenate([w[9:18], vdot, lam, ev.z, ev.zd, [ev.energy]])

    w0 = np.concatenate([q, v, u, f])
    columns = []
    for j in range(24):
        h = 1e-3 * max(1.0, abs(w0[j]))
        e = np.zeros(24)
        e[j] = 1.0
        d1 = (outputs(w0 + h * e) - outputs(w0 - h * e)) / (2 * h)
        d2 = (outputs(w0 + h / 2 * e) - outputs(w0 - h / 2 * e)) / h
        columns.append((4 * d2 - d1) / 3)
    reference = np.column_stack(columns)
    pj = plant_jacobian(p, q, v, u, f, pole)
    exact = np.vstack([pj.dx, pj.dlam, pj.dz, pj.dzd, pj.denergy[None]])
    scale = np.max(np.abs(reference), axis=1, keepdims=True)
    assert np.max(np.abs(exact - reference) / scale) < 1e-9
    np.testing.assert_allclose(pj.vdot, d.accelerations(p, q, v, u, f, pole)[0], rtol=0, atol=0)


def test_master_cvode_takes_the_exact_jacobian(build_fmu_from_src, tmp_path):
    """The DeltaRobot FMU says its derivatives are exact (vendor annotation), the oscillator's are
    its own differences; the master's CVODE then takes the robot's: a free fall at rtol 1e-6 with
    and without lands on the same trajectory within the tolerance's reach of a tight reference."""
    from deltafmi.master.stepping.jacobians import computes_exact_derivatives
    from deltafmi.master.stepping.master import Master
    from deltafmi import resolve_system
    from deltafmi.master.results.csv_file import columns
    from deltafmi.master.scenario.spec import load_scenario

    robot = build_fmu_from_src("delta_robot.py")
    assert computes_exact_derivatives(fmpy.extract(str(robot), str(tmp_path / "robot")))
    assert not computes_exact_derivatives(fmpy.extract(str(build_fmu_from_src("oscillator.py")),
                                                       str(tmp_path / "osc")))
    runs = {}
    for name, solver in (("exact", "{rtol: 1.0e-6, jacobian: true}"), ("quotients", "{rtol: 1.0e-6, jacobian: false}"),
                         ("reference", "{rtol: 1.0e-11}")):
        path = tmp_path / f"{name}.yaml"
        path.write_text(f"""experiment: {{start: 0.0, stop: 0.5, step: 1.0e-2}}
components:
  plant: {{fmu: {robot}, interface: ME, parameters: {{z0: [0.1, -0.1, -0.9]}}, solver: {solver}}}
outputs: ['plant.z[*]']
""")
        Master(resolve_system(load_scenario(path)), result=tmp_path / f"{name}.csv").run()
        runs[name] = np.column_stack([columns(tmp_path / f"{name}.csv")[f"plant.z[{i}]"] for i in (1, 2, 3)])
    error = {k: np.max(np.abs(runs[k] - runs["reference"])) for k in ("exact", "quotients")}
    assert error["exact"] < 1e-4 and error["quotients"] < 1e-4
    assert np.max(np.abs(runs["exact"] - runs["quotients"])) > 0  # a different Newton matrix was used


def test_fmi3_build_gives_the_master_the_same_newton_matrix(build_fmu_from_src, tmp_path):
    """The robot built as FMI 3.0 (q, v as arrays): the master's CVODE takes its Newton matrix
    from fmi3GetDirectionalDerivative, one seed per array element, and follows the FMI 2.0 build's
    run bit for bit; with CVODE's own difference quotients it does not."""
    from deltafmi.builder import build_fmu
    from deltafmi.master.stepping.master import Master
    from deltafmi import resolve_system
    from deltafmi.master.results.csv_file import columns
    from deltafmi.master.scenario.spec import load_scenario

    robots = {2: build_fmu_from_src("delta_robot.py"),
              3: build_fmu(FMU_SRC / "delta_robot.py", tmp_path / "robot3.fmu", fmi_version=3)}
    runs = {}
    for version, jacobian in ((2, "true"), (3, "true"), (3, "false")):
        path = tmp_path / f"{version}{jacobian}.yaml"
        path.write_text(f"""experiment: {{start: 0.0, stop: 0.3, step: 1.0e-2}}
components:
  plant: {{fmu: {robots[version]}, interface: ME, parameters: {{z0: [0.1, -0.1, -0.9]}},
           solver: {{rtol: 1.0e-6, jacobian: {jacobian}}}}}
outputs: ['plant.z', 'plant.q']
""")
        Master(resolve_system(load_scenario(path)), result=tmp_path / f"{version}{jacobian}.csv").run()
        found = columns(tmp_path / f"{version}{jacobian}.csv")
        runs[version, jacobian] = np.column_stack([found[n] for n in sorted(found)])
    assert np.array_equal(runs[3, "true"], runs[2, "true"])
    assert not np.array_equal(runs[3, "false"], runs[3, "true"])
