"""The DeltaRobot's exact Jacobian as a compiled kernel (``NativeKernels(jacobian=...)``): the C
generated from ``jacobian_values`` gives the Python's bits, the matrices built from them are
plant_jacobian's, and through FMI the directional derivatives (the kernel's floats, and the
central differences of the residual over the compiled outputs kernel) and a Co-Simulation run
(CVODE's Newton matrix) are the same bits with the compiled kernels as with the Python methods
(``DELTAFMI_NATIVE=0``)."""
from __future__ import annotations

import ctypes
import json
import struct
import zipfile

import fmpy
import numpy as np
import pytest
from fmpy.fmi2 import FMU2Model

from deltafmi.component import Kernel, NativeKernels
from deltafmi.builder import build_cached
from deltafmi.builder.codegen.build import compile_unit
from deltafmi.builder.codegen.kernel_types import D, Entry, Obj, Vec
from deltafmi.toolchain import NoCompilerError
from deltafmi.physics import delta as d
from deltafmi.physics.delta.jacobian import (N_VALUES, jacobian_from_values, jacobian_values, plant_jacobian,
                                             state_jacobian)
from deltafmi.physics.delta.params import DeltaParams


def bits(values) -> list[int]:
    return [struct.unpack("<q", struct.pack("<d", float(v)))[0] for v in values]


def points(seed: int, n: int = 4):
    """(q, v, u, f) on the closed loops, at rest and moving, with torques and a wrist force."""
    rng = np.random.default_rng(seed)
    for k in range(n):
        z = [0.1 * rng.normal(), 0.1 * rng.normal(), -1.0 + 0.1 * rng.normal()]
        q = d.inverse_kinematics(d.RL5, z)
        v = rng.normal(0.0, 1.0, 9) if k else np.zeros(9)
        yield q.tolist(), v.tolist(), rng.normal(0.0, 30.0, 3).tolist(), rng.normal(0.0, 20.0, 3).tolist()


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    entry = Entry("jacobian_values", jacobian_values, [Obj(DeltaParams), Vec(9), Vec(9), Vec(3), Vec(3), D])
    state = Entry("state_jacobian", state_jacobian, [Obj(DeltaParams), Vec(18), Vec(3), Vec(3), D])
    try:
        return compile_unit([entry, state], tmp_path_factory.mktemp("jacobian_kernel"), identities=("_as_list",))
    except NoCompilerError as exc:
        pytest.skip(f"no C compiler: {exc}")


def test_generated_c_gives_the_python_bits(compiled):
    for q, v, u, f in points(1):
        python = jacobian_values(d.RL5, q, v, u, f, 5.0)
        assert len(python) == N_VALUES
        assert bits(compiled.call("jacobian_values", d.RL5, q, v, u, f, 5.0)) == bits(python)
        state = state_jacobian(d.RL5, q + v, u, f, 5.0)
        assert bits(compiled.call("state_jacobian", d.RL5, q + v, u, f, 5.0)) == bits(state)


def test_the_state_jacobian_is_the_state_block_column_by_column():
    """state_jacobian (CVODE's Newton matrix, column-major) is plant_jacobian's d x'/d x bit for bit."""
    for q, v, u, f in points(3, n=3):
        pj = plant_jacobian(d.RL5, np.array(q), np.array(v), np.array(u), np.array(f), 5.0)
        matrix = np.array(state_jacobian(d.RL5, q + v, u, f, 5.0)).reshape(18, 18).T
        assert bits(matrix.ravel()) == bits(pj.dx[:, :18].ravel())


def test_every_column_is_the_derivative_of_the_dynamics():
    """All 24 columns of d[a; lam] (states, torques, wrist force) against central differences of
    the dynamics (an independent formulation: no KKT system), to 1e-6 relative."""
    for q, v, u, f in points(4, n=2):
        pj = plant_jacobian(d.RL5, np.array(q), np.array(v), np.array(u), np.array(f), 5.0)
        known = np.array(q + v + u + f)
        h = 1e-6

        def evaluate(z):
            a, lam = d.accelerations(d.RL5, z[:9], z[9:18], z[18:21], z[21:])
            return np.concatenate([a, lam])

        for j in range(24):
            plus, minus = known.copy(), known.copy()
            plus[j] += h
            minus[j] -= h
            column = (evaluate(plus) - evaluate(minus)) / (2 * h)
            exact = np.concatenate([pj.dx[9:, j], pj.dlam[:, j]])
            np.testing.assert_allclose(exact, column, rtol=1e-6, atol=1e-6 * max(1.0, np.max(np.abs(column))))


def test_the_matrices_from_the_values_are_plant_jacobians():
    """jacobian_from_values(jacobian_values(...)) is plant_jacobian, and its state block is the
    derivative of the accelerations (central differences of the library, to 1e-6 relative)."""
    for q, v, u, f in points(2, n=2):
        pj = plant_jacobian(d.RL5, np.array(q), np.array(v), np.array(u), np.array(f), 5.0)
        again = jacobian_from_values(np.array(jacobian_values(d.RL5, q, v, u, f, 5.0)))
        for name in pj._fields:
            np.testing.assert_array_equal(getattr(again, name), getattr(pj, name))
        x = np.array(q + v)
        h = 1e-6
        for j in (0, 4, 13):
            plus, minus = x.copy(), x.copy()
            plus[j] += h
            minus[j] -= h
            column = (np.array(d.state_derivative(d.RL5, plus, u, f)) - np.array(d.state_derivative(d.RL5, minus, u, f))) / (2 * h)
            np.testing.assert_allclose(pj.dx[:, j], column, rtol=1e-6, atol=1e-6 * np.max(np.abs(column)))


def test_a_jacobian_kernel_needs_then():
    with pytest.raises(ValueError, match="needs then="):
        NativeKernels(jacobian=Kernel(jacobian_values, "_plant", "q", "v", "u", "f", "pole"))


def _directional(fmu: str, directory, monkeypatch, native: bool) -> np.ndarray:
    """Every state's column of d[der, outputs] by fmi2GetDirectionalDerivative at a moving state
    (``fmu`` unzipped into ``directory``, unless that holds it already)."""
    if native:
        monkeypatch.delenv("DELTAFMI_NATIVE", raising=False)
    else:
        monkeypatch.setenv("DELTAFMI_NATIVE", "0")
    if not (directory / "modelDescription.xml").exists():
        fmpy.extract(fmu, str(directory))
    md = fmpy.read_model_description(str(directory))
    model = FMU2Model(guid=md.guid, unzipDirectory=str(directory), modelIdentifier="DeltaRobot")
    model.instantiate()
    model.setupExperiment(startTime=0.0)
    model.enterInitializationMode()
    model.exitInitializationMode()
    while model.newDiscreteStates()[0]:
        pass
    model.enterContinuousTimeMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    model.setReal([vr[f"u[{i}]"] for i in (1, 2, 3)], [30.0, -20.0, 5.0])
    model.setReal([vr[f"f[{i}]"] for i in (1, 2, 3)], [2.0, 0.0, -8.0])
    x = np.zeros(18)
    model.getContinuousStates(x.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 18)
    x[9:] = np.linspace(-1.0, 1.0, 9)
    model.setContinuousStates(x.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 18)
    states = [u.variable.derivative.valueReference for u in md.derivatives]
    unknowns = [u.variable.valueReference for u in md.derivatives] + [
        v.valueReference for v in md.modelVariables
        if v.causality == "output" and v.type == "Real" and v.variability == "continuous"]
    columns = np.column_stack([model.getDirectionalDerivative(unknowns, [s], [1.0]) for s in states])
    model.terminate()
    model.freeInstance()
    return columns


def test_through_fmi_the_compiled_jacobian_gives_the_python_bits(tmp_path, monkeypatch):
    fmu = str(build_cached("DeltaRobot"))
    with zipfile.ZipFile(fmu) as archive:
        description = json.loads(archive.read("resources/native_kernels.json"))
    assert "jacobian" in description["kernels"] and description["jacobian_size"] == N_VALUES
    compiled = _directional(fmu, tmp_path / "native", monkeypatch, True)
    python = _directional(fmu, tmp_path / "python", monkeypatch, False)
    assert np.all(np.isfinite(compiled)) and np.any(compiled != 0.0)
    assert bits(compiled.ravel()) == bits(python.ravel())


def test_the_compiled_kernel_is_what_runs(tmp_path, monkeypatch):
    """With the FMU's Python jacobian() edited (its floats shifted), the compiled path still gives
    the library's derivatives and the Python path the edit's: the directional derivatives come
    from the kernel, not from the method."""
    fmu = str(build_cached("DeltaRobot"))
    reference = _directional(fmu, tmp_path / "reference", monkeypatch, True)
    edited = tmp_path / "edited"
    fmpy.extract(fmu, str(edited))
    model = edited / "resources" / "model" / "delta_robot.py"
    text = model.read_text()
    call = "return _jacobian_blocks(np.array(jacobian_values("
    assert text.count(call) == 1
    model.write_text(text.replace(call, "return _jacobian_blocks(0.5 + np.array(jacobian_values("))
    assert bits(_directional(fmu, edited, monkeypatch, True).ravel()) == bits(reference.ravel())
    assert np.max(np.abs(_directional(fmu, edited, monkeypatch, False) - reference)) > 1e-3


def test_a_co_simulation_run_gives_the_python_bits(monkeypatch):
    """CVODE's Newton matrix from the kernel: the trajectory is the Python Jacobian's."""
    fmu = str(build_cached("DeltaRobot"))
    results = []
    for native in (True, False):
        if native:
            monkeypatch.delenv("DELTAFMI_NATIVE", raising=False)
        else:
            monkeypatch.setenv("DELTAFMI_NATIVE", "0")
        results.append(fmpy.simulate_fmu(fmu, fmi_type="CoSimulation", stop_time=0.3, output_interval=1e-3,
                                         start_values={"u[1]": 20.0, "f[3]": -5.0}, output=["q[1]", "v[9]", "z[3]"]))
    for name in ("q[1]", "v[9]", "z[3]"):
        assert bits(results[0][name]) == bits(results[1][name])
    # it moved: the wrist fell and the servo torque turned arm 1
    assert results[0]["z[3]"][-1] < results[0]["z[3]"][0] - 0.01


def test_the_co_simulation_newton_matrix_calls_no_python(tmp_path, monkeypatch):
    """With the FMU's Python jacobian() made to raise, a Co-Simulation run on the compiled kernels
    still runs (CVODE's Newton matrix is the state_jacobian kernel's), and on the Python methods it fails."""
    fmu = str(build_cached("DeltaRobot"))
    edited = tmp_path / "edited"
    fmpy.extract(fmu, str(edited))
    assert "state_jacobian" in json.loads((edited / "resources/native_kernels.json").read_text())["kernels"]
    model = edited / "resources" / "model" / "delta_robot.py"
    call = "return _jacobian_blocks(np.array(jacobian_values("
    model.write_text(model.read_text().replace(call, "raise RuntimeError('no Python here')\n        " + call))

    def run():
        return fmpy.simulate_fmu(str(edited), fmi_type="CoSimulation", stop_time=0.3, output_interval=1e-3,
                                 start_values={"u[1]": 20.0, "f[3]": -5.0}, output=["z[3]"])

    monkeypatch.delenv("DELTAFMI_NATIVE", raising=False)
    assert run()["z[3]"][-1] < -1.01  # it fell
    monkeypatch.setenv("DELTAFMI_NATIVE", "0")
    with pytest.raises(Exception, match="fmi2DoStep"):
        run()
