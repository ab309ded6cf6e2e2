"""The exact Jacobians of equation models (the implicit function theorem on the compiled system)
through fmi2GetDirectionalDerivative, against central differences and against the hand-written
robot's exact Jacobian."""
import ctypes

import fmpy
import numpy as np
from fmpy.fmi2 import FMU2Model

from deltafmi.builder.packager import build_cached


def _instance(name, directory):
    fmu = build_cached(name)
    md = fmpy.read_model_description(str(fmu))
    m = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu), str(directory)),
                  modelIdentifier=md.modelExchange.modelIdentifier)
    m.instantiate()
    m.setupExperiment(startTime=0.0)
    m.enterInitializationMode()
    m.exitInitializationMode()
    m.enterContinuousTimeMode()
    return m, md


def _jacobian(m, unknowns, knowns):
    return np.column_stack([m.getDirectionalDerivative(unknowns, [k], [1.0]) for k in knowns])


def _differences(m, md, unknowns, knowns):
    nx = md.numberOfContinuousStates
    states = [u.variable.derivative.valueReference for u in md.derivatives]
    ders = [u.variable.valueReference for u in md.derivatives]
    x0 = (ctypes.c_double * nx)()
    m.getContinuousStates(x0, nx)
    x0 = np.array(x0[:])

    def values(x):
        m.setContinuousStates((ctypes.c_double * nx)(*x), nx)
        d = (ctypes.c_double * nx)()
        m.getDerivatives(d, nx)
        others = dict(zip(unknowns, m.getReal(unknowns)))
        return np.array([d[ders.index(u)] if u in ders else others[u] for u in unknowns])

    columns = []
    for k in knowns:
        h = 1e-5 * max(1.0, abs(x0[states.index(k)]))
        plus, minus = x0.copy(), x0.copy()
        plus[states.index(k)] += h
        minus[states.index(k)] -= h
        columns.append((values(plus) - values(minus)) / (2 * h))
    m.setContinuousStates((ctypes.c_double * nx)(*x0), nx)
    return np.column_stack(columns)


def test_pendulum_jacobian_equals_differences(tmp_path):
    m, md = _instance("CartesianPendulum", tmp_path)
    ders = [u.variable.valueReference for u in md.derivatives]
    states = [u.variable.derivative.valueReference for u in md.derivatives]
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    exact = _jacobian(m, ders + outputs, states)
    assert np.allclose(exact, _differences(m, md, ders + outputs, states), rtol=1e-6, atol=1e-6)


def test_delta_robot_jacobian_equals_the_hand_written_exact_one(tmp_path):
    E, emd = _instance("DeltaRobotEquations", tmp_path / "eq")
    H, hmd = _instance("DeltaRobot", tmp_path / "hand")
    evr = {v.name: v.valueReference for v in emd.modelVariables}
    hvr = {v.name: v.valueReference for v in hmd.modelVariables}
    enames = [u.variable.derivative.name for u in emd.derivatives]
    hnames = [u.variable.derivative.name for u in hmd.derivatives]
    to_hand = {n: f"{n[5]}[{3 * (int(n[3]) - 1) + int(n[7])}]" for n in enames}
    outputs = [f"z[{k}]" for k in (1, 2, 3)] + [f"zd[{k}]" for k in (1, 2, 3)] + \
              [f"lambda[{k}]" for k in range(1, 7)] + ["energy"]
    e_unknowns = [evr[f"der({n})"] for n in enames] + [evr[o] for o in outputs]
    h_unknowns = [hvr[f"der({to_hand[n]})"] for n in enames] + [hvr[o] for o in outputs]
    e_knowns = [evr[n] for n in enames] + [evr[f"{i}[{k}]"] for i in "uf" for k in (1, 2, 3)]
    h_knowns = [hvr[to_hand[n]] for n in enames] + [hvr[f"{i}[{k}]"] for i in "uf" for k in (1, 2, 3)]
    exact = _jacobian(E, e_unknowns, e_knowns)
    reference = _jacobian(H, h_unknowns, h_knowns)
    assert np.max(np.abs(exact - reference)) < 1e-12 * np.max(np.abs(reference))
    assert hnames  # the hand-written plant names its states q[k], v[k]
