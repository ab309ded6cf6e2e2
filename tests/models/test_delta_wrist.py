"""The DeltaWrist FMU (delta + spherical wrist, 24 states) through fmpy: ME with CVODE, CS, FMI 2.0 and 3.0.

References: the plant's Python kernels (deltafmi.physics.delta_wrist, themselves checked against
a dense KKT solve in test_delta_wrist_mechanics.py) integrated by scipy's DOP853 at rtol 1e-11, and
the closed-form holding torques. Tolerances are stated where they are asserted.
"""
from __future__ import annotations

import ctypes
import json
import zipfile

import fmpy
import numpy as np
import pytest
from fmpy.fmi2 import FMU2Model
from fmpy.validation import validate_fmu
from scipy.integrate import solve_ivp

from conftest import start_model_exchange
from deltafmi.builder import build_cached
from deltafmi.physics import delta_wrist as dw
from deltafmi.physics.delta.params import RL5
from deltafmi.physics.wrist.kernels import wrist_constants

#: a start away from rest's symmetry: tip off the axis, the tool tilted 1.1 rad (it swings down)
START = {"tip0[1]": 0.1, "tip0[2]": -0.05, "tip0[3]": -1.15, "qw0[1]": 0.3, "qw0[2]": 1.1, "qw0[3]": -0.4}
TIP0, QW0 = [0.1, -0.05, -1.15], [0.3, 1.1, -0.4]
T_END = 2.0
OUTPUTS = ["energy", "residual", "gimbal", "tip[1]", "tip[2]", "tip[3]", "qw[2]"]
ZERO = (0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def fmu():
    return build_cached("DeltaWrist")


@pytest.fixture(scope="module")
def plant():
    """(delta, wrist constants, mount) as the FMU builds them from its default parameters."""
    from deltafmi.models.delta_wrist import DeltaWrist

    def start(name: str):
        value = getattr(DeltaWrist, name).start
        return value[0] if len(value) == 1 else tuple(value)
    tool = dw.peg_tool(start("tool_mass"), start("tool_length"), start("tool_radius"), start("tool_tip"))
    wrist = dw.wrist_params(start("rotor_inertia"), tool, start("g"), start("wrist_damping"))
    return RL5, wrist_constants(wrist), dw.MOUNT


@pytest.fixture(scope="module")
def reference(plant):
    """The free swing from START by the Python kernels and DOP853 (rtol 1e-11: its global error
    on the tip stays below ~1e-9 m over 2 s, measured against rtol 1e-12)."""
    p, c, m = plant
    x0 = dw.start_state(p, c, m, TIP0, QW0)
    return solve_ivp(lambda t, x: dw.state_derivative(p, c, m, x.tolist(), ZERO, ZERO, ZERO, ZERO, 5.0),
                     (0.0, T_END), x0, method="DOP853", rtol=1e-11, atol=1e-12, dense_output=True)


def _simulate(fmu, fmi_type: str, stop: float = T_END, **start):
    return fmpy.simulate_fmu(str(fmu), fmi_type=fmi_type, start_values={**START, **start}, stop_time=stop,
                             output_interval=0.01, relative_tolerance=1e-8, output=OUTPUTS)


def test_validates_and_carries_compiled_kernels(fmu):
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    assert md.numberOfContinuousStates == 24 and md.modelExchange and md.coSimulation
    names = {v.name for v in md.modelVariables}
    assert {"q_w[3]", "v_w[3]", "der(v_w[3])", "tau[3]", "moment[3]", "R[9]", "omega[3]", "lambda[6]", "gimbal",
            "mount[3]", "rotor_inertia[3]", "tip0[3]", "qw0[3]"} <= names
    with zipfile.ZipFile(fmu) as archive:
        description = json.loads(archive.read("resources/native_kernels.json"))
        assert description["library"] in archive.namelist()
    assert description["kernels"] == ["derivatives", "outputs", "project"]


def test_fmu_derivatives_are_the_python_kernels(fmu, plant, tmp_path):
    """Through fmi2GetDerivatives the FMU's C kernels give the Python kernel's numbers (the same
    float operations in the same order: asserted to 1e-13 of the largest derivative)."""
    p, c, m = plant
    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    instance = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu), str(tmp_path / "fmu")),
                         modelIdentifier="DeltaWrist")
    start_model_exchange(instance)
    rng = np.random.default_rng(8)
    inputs = {name: rng.normal(0.0, scale, 3) for name, scale in (("u", 30.0), ("tau", 1.0), ("f", 10.0),
                                                                  ("moment", 1.0))}
    for name, values in inputs.items():
        instance.setReal([vr[f"{name}[{i}]"] for i in (1, 2, 3)], list(values))
    for tip, qw in (([0.1, -0.2, -1.1], [0.2, 0.4, -0.3]), ([0.0, 0.25, -1.3], [-1.0, -0.5, 0.8])):
        x = dw.start_state(p, c, m, tip, qw, zd=rng.normal(0, 0.3, 3), qwd=rng.normal(0, 2, 3))
        dx = np.zeros(24)
        instance.setContinuousStates(x.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 24)
        instance.getDerivatives(dx.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 24)
        expected = np.array(dw.state_derivative(p, c, m, x.tolist(), *(tuple(v) for v in inputs.values()), 5.0))
        np.testing.assert_allclose(dx, expected, rtol=0.0, atol=1e-13 * np.max(np.abs(expected)))
    instance.terminate()
    instance.freeInstance()


# Loop drift: CS projects after every step of its own CVODE; in ME fmpy's CVODE integrates the 24
# states and the loops drift by its local errors (the delta alone: ~5e-8 m at rtol 1e-8).
RESIDUAL = {"CoSimulation": 1e-9, "ModelExchange": 1e-7}


@pytest.mark.parametrize("fmi_type", ["ModelExchange", "CoSimulation"])
def test_free_swing_conserves_energy_and_follows_the_kernels(fmu, plant, reference, fmi_type):
    """2 s of free motion at rtol 1e-8 (the tool swings through gimbal lock's neighbourhood, the
    delta falls to its lowest pose and back). Over the first second the tip follows the DOP853
    reference to 1e-5 m: CVODE's local errors (rtol 1e-8 on states of order 1, ~10^3 steps)
    summed without cancellation, times a lever of ~1 m/rad (measured: 5e-7 m). Later the swing
    passes within 1.5 degrees of gimbal lock, where the motion is chaotic (two DOP853 runs at rtol
    1e-11 and 1e-12 part by 3e-7 m at 2 s), so only the invariants are compared there: the
    energy, kept to 1e-6 of the motion's energy scale (the same error budget), and the loops,
    within RESIDUAL."""
    r = _simulate(fmu, fmi_type)
    p, c, m = plant
    ref = reference.sol(r["time"])
    first = r["time"] <= 1.0
    tip_ref = np.array([dw.plant_outputs(p, c, m, x.tolist(), ZERO, ZERO, ZERO, ZERO, 5.0)[6] for x in ref.T[first]])
    tip = np.column_stack([r["tip[1]"], r["tip[2]"], r["tip[3]"]])[first]
    assert np.max(np.linalg.norm(tip - tip_ref, axis=1)) < 1e-5
    potential = [dw.energy(p, c, m, np.concatenate([x[:12], np.zeros(12)])) for x in ref.T]
    scale = np.ptp(potential)  # potential turned into kinetic energy and back
    print(f"\n{fmi_type}: tip {np.max(np.linalg.norm(tip - tip_ref, axis=1)):.1e} m from the reference, energy drift "
          f"{np.max(np.abs(r['energy'] - r['energy'][0])) / scale:.1e} of {scale:.0f} J, loop residual "
          f"{np.max(np.abs(r['residual'])):.1e} m")
    assert scale > 10.0
    assert np.max(np.abs(r["energy"] - r["energy"][0])) < 1e-6 * scale
    assert np.max(np.abs(r["residual"])) < RESIDUAL[fmi_type]
    assert np.ptp(r["qw[2]"]) > 1.0


def test_model_exchange_step_events_close_the_loops(fmu):
    """With loop_tolerance the FMU asks for a step event whenever |h| exceeds it after an
    integrator step and projects there (the mass-weighted projection of the plant): every row
    after an event closes the loops, and the projections together move the energy by less than
    the ME run's own budget, 1e-6 of its 45 J scale (measured: 3e-8)."""
    r = _simulate(fmu, "ModelExchange", stop=1.0, loop_tolerance=1e-10)
    before_event = np.append(np.diff(r["time"]) == 0, False)  # fmpy records a row before and after an event
    assert before_event.sum() >= 10
    assert np.max(np.abs(r["residual"][~before_event])) < 1e-9
    jumps = np.diff(r["energy"])[before_event[:-1]]
    assert np.sum(np.abs(jumps)) < 1e-6 * 45.0


def test_holding_torques_keep_it_still(fmu, plant):
    """The static solve's torques (servo: [B H^T][u; lam] = G with the wrist's weight as payload;
    wrist: its gravity torques) as constant inputs: the accelerations vanish to rounding
    (~1e-14), so in 1 s the tip moves by less than 1e-9 m and nothing turns."""
    p, c, m = plant
    x0 = dw.start_state(p, c, m, TIP0, QW0)
    u, tau = dw.holding_torques(p, c, x0)
    start = {**{f"u[{i + 1}]": u[i] for i in range(3)}, **{f"tau[{i + 1}]": tau[i] for i in range(3)}}
    for fmi_type in ("ModelExchange", "CoSimulation"):
        r = _simulate(fmu, fmi_type, stop=1.0, **start)
        tip = np.column_stack([r["tip[1]"], r["tip[2]"], r["tip[3]"]])
        assert np.max(np.linalg.norm(tip - TIP0, axis=1)) < 1e-9, fmi_type
        assert np.ptp(r["qw[2]"]) < 1e-9


def test_fmi3_build_runs_as_the_fmi2_one(fmu):
    fmu3 = build_cached("DeltaWrist", fmi_version=3)
    assert validate_fmu(str(fmu3)) == []
    md = fmpy.read_model_description(str(fmu3))
    assert md.fmiVersion == "3.0" and md.numberOfContinuousStates == 24
    r2 = _simulate(fmu, "CoSimulation", stop=0.3)
    r3 = fmpy.simulate_fmu(str(fmu3), fmi_type="CoSimulation", start_values={"tip0": TIP0, "qw0": QW0}, stop_time=0.3,
                           output_interval=0.01, relative_tolerance=1e-8, output=["energy", "tip"])
    # the same kernels and solver: the same numbers
    np.testing.assert_allclose(r3["energy"], r2["energy"], rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(r3["tip"], np.column_stack([r2["tip[1]"], r2["tip[2]"], r2["tip[3]"]]), rtol=0.0,
                               atol=1e-12)


def test_unreachable_tip_is_a_clear_initialization_error(fmu, capfd):
    with pytest.raises(Exception):
        _simulate(fmu, "CoSimulation", stop=0.1, **{"tip0[3]": -1.7})
    log = "".join(capfd.readouterr())
    assert "tool tip" in log and "out of reach" in log and "-1.7" in log
