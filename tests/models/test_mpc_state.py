"""The MPC FMUs (MpcController, InsertionMpc with DAQP and with OSQP) continue bit-identically after
an FMU state is restored: fmi2SetFMUstate into the same instance, and fmi2DeSerializeFMUstate into
another one (FMI 2.0, 2.1.8: a restored state continues as from the moment it was taken). The QP
solvers' warm start (OSQP's adapted rho, DAQP's active set) is part of that state."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi2 import FMU2Slave

from deltafmi.builder.packager import build_cached

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
#: model, its shipped linear model, string parameters, communication step (its sample period)
CASES = {
    "MpcController": ("MpcController", "mpc_press_model.npz", {"linear_model": "mpc_press_model.npz"}, 4e-3),
    "InsertionMpc-daqp": ("InsertionMpc", "peg_in_hole_mpc_model.npz", {}, 1e-2),
    "InsertionMpc-osqp": ("InsertionMpc", "peg_in_hole_mpc_model.npz", {"qp_solver": "osqp"}, 1e-2),
}
STEPS, SAVED = 60, 15  # steps run; the step after which the state is taken


def _inputs(model: str, k: int, h: float, outputs: dict) -> dict:
    """The inputs before step k: the MPC's own plan fed back as an ideal plant would follow it
    (InsertionMpc), or a reference sweeping across the workspace (MpcController); the same in every run."""
    t = k * h
    if model == "InsertionMpc":  # the tip follows the reference; the peg pushed back from 0.4 s on
        return {"tip": outputs["r"], "tip_velocity": outputs["rd"], "ft": [0.0, 0.0, -5.0 if t > 0.4 else 0.0,
                                                                            0.0, 0.0, 0.0]}
    return {"y": [0.05 * math.sin(9 * t), -0.04 * math.sin(7 * t), 0.03 * math.cos(5 * t)], "yd": [0.0] * 3,
            "r": [0.02 * math.sin(6 * t), 0.02 * math.cos(6 * t), -1.049 - 0.03 * t], "rd": [0.0] * 3,
            "force": [20.0]}


class _Run:
    """One instance of the FMU in Co-Simulation, stepped by h with the inputs of :func:`_inputs`."""

    def __init__(self, case: str, fmu: Path, name: str) -> None:
        self.model, _, self.strings, self.h = CASES[case]
        self.md = fmpy.read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.real_outputs = [v.name for v in self.md.modelVariables
                             if v.causality == "output" and v.type == "Real" and v.name != "solve_time"]
        self.int_outputs = [v.name for v in self.md.modelVariables if v.causality == "output" and v.type == "Integer"]
        self.names = self.real_outputs + self.int_outputs  # a row's columns (a vector's elements are adjacent)
        self.slave = FMU2Slave(guid=self.md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                               modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.slave.instantiate()

    def start(self) -> None:
        if self.strings:
            self.slave.setString([self.vr[k] for k in self.strings], list(self.strings.values()))
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def outputs(self) -> dict:
        """Every output (vectors by their base name) but the wall-clock solve_time."""
        reals = self.slave.getReal([self.vr[n] for n in self.real_outputs])
        ints = self.slave.getInteger([self.vr[n] for n in self.int_outputs])
        grouped: dict = {}
        for name, value in [*zip(self.real_outputs, reals), *zip(self.int_outputs, ints)]:
            grouped.setdefault(name.split("[")[0], []).append(value)
        return grouped

    def steps(self, first: int, last: int) -> list:
        """Steps first .. last - 1; the outputs after each one (flat)."""
        rows = []
        for k in range(first, last):
            for name, values in _inputs(self.model, k, self.h, self.outputs()).items():
                self.slave.setReal([self.vr[f"{name}[{i + 1}]"] for i in range(len(values))] if len(values) > 1
                                   else [self.vr[name]], values)
            self.slave.doStep(k * self.h, self.h)
            rows.append([v for values in self.outputs().values() for v in values])
        return rows

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()
        shutil.rmtree(self.slave.unzipDirectory, ignore_errors=True)


@pytest.mark.parametrize("case", list(CASES))
def test_a_restored_state_continues_bit_identically(case):
    """Uninterrupted run to STEPS; the state taken after SAVED steps set back into the instance and
    the rest run again; the serialized state loaded into a fresh instance and the rest run there:
    all three continuations are the same bits (float equality of every output at every step)."""
    model, resource, _, _ = CASES[case]
    fmu = build_cached(model, resources=[SCENARIOS / resource])
    run = _Run(case, fmu, "first")
    other = _Run(case, fmu, "second")
    try:
        run.start()
        run.steps(0, SAVED)
        state = run.slave.getFMUstate()
        data = run.slave.serializeFMUstate(state)
        uninterrupted = run.steps(SAVED, STEPS)
        run.slave.setFMUstate(state)
        restored = run.steps(SAVED, STEPS)
        run.slave.freeFMUstate(state)
        other.start()
        loaded = other.slave.deSerializeFMUstate(data)
        other.slave.setFMUstate(loaded)
        other.slave.freeFMUstate(loaded)
        deserialized = other.steps(SAVED, STEPS)
    finally:
        run.close()
        other.close()
    a = np.array(uninterrupted)
    assert np.ptp(a, axis=0).max() > 0.0  # the plan moves: the continuation has something to differ in
    for what, b in (("set back", np.array(restored)), ("deserialized", np.array(deserialized))):
        differ = np.argwhere(a != b)
        assert differ.size == 0, (f"{what}: first difference at step {SAVED + differ[0][0]} in "
                                  f"{run.names[differ[0][1]]}, max |diff| {np.abs(a - b).max(axis=0)}")
