"""The DeltaWristPeg FMU (the 6-DOF plant with its peg in a chamfered hole) through fmpy's CVODE.

The robot is held by its closed-form holding torques (delta_wrist.holding_torques) and pushed
down by a constant force on the tool tip; no controller. References: the DeltaWrist plant's Python
kernels without any contact integrated by scipy (a centred peg must not touch the hole), and the
contact kernel in Python (deltafmi.physics.peg) re-evaluated on the FMU's own states.
"""
from __future__ import annotations

import math

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu
from scipy.integrate import solve_ivp

from deltafmi.builder import build_cached
from deltafmi.physics import delta_wrist as dw
from deltafmi.physics.delta.params import RL5
from deltafmi.physics.peg import Hole, Peg, PegContact, contact, plant
from deltafmi.physics.wrist.kernels import wrist_constants

PUSH = 20.0  #: N, down on the tool tip
HOLE = Hole()  #: the FMU's default (true) hole: top centre (0, 0, -1.2), bore 10.1 mm, chamfer 2 mm x 45 deg
PEG, LAW = Peg(), PegContact()  #: the FMU's default tool (r 10 mm, L 100 mm) and contact law
STATES = [f"q[{i}]" for i in range(1, 10)] + [f"q_w[{i}]" for i in range(1, 4)] + \
    [f"v[{i}]" for i in range(1, 10)] + [f"v_w[{i}]" for i in range(1, 4)]
PEG_OUT = ["depth", "success", "lateral_misalignment", "angular_misalignment", "max_normal_force", "active_contacts"] \
    + [f"contact_force[{i}]" for i in range(1, 4)] + [f"contact_moment[{i}]" for i in range(1, 4)] \
    + [f"ft_sensor[{i}]" for i in range(1, 7)] + [f"R[{i}]" for i in range(1, 10)]


@pytest.fixture(scope="module")
def fmu():
    return build_cached("DeltaWristPeg")


@pytest.fixture(scope="module")
def robot():
    """(delta, wrist constants, mount) as the FMU builds them from its default parameters."""
    tool = dw.peg_tool(0.25, PEG.length, PEG.radius, 0.13)
    return RL5, wrist_constants(dw.wrist_params((3.0e-4, 2.0e-4, 1.0e-4), tool, 9.81, 0.0)), dw.MOUNT


def _start(robot, tip0):
    """The start state at tip0 (tool down) and the inputs holding it, plus the push."""
    p, w, m = robot
    x0 = dw.dynamics.start_state(p, w, m, tip0, (0.0, 0.0, 0.0))
    u, tau = dw.dynamics.holding_torques(p, w, x0)
    values = {f"tip0[{i + 1}]": tip0[i] for i in range(3)}
    values.update({f"u[{i + 1}]": u[i] for i in range(3)})
    values.update({f"tau[{i + 1}]": tau[i] for i in range(3)})
    values["f[3]"] = -PUSH
    return x0, u, tau, values


def _simulate(fmu, values, T):
    return fmpy.simulate_fmu(str(fmu), fmi_type="ModelExchange", start_values=values, stop_time=T,
                             output_interval=1e-3, relative_tolerance=1e-8, output=PEG_OUT + STATES)


def test_validates(fmu):
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    assert md.numberOfContinuousStates == 24 and md.numberOfEventIndicators == 1
    names = {v.name for v in md.modelVariables}
    assert {"hole_position[3]", "hole_tilt[2]", "mu", "target_depth", "ft_sensor[6]", "success"} <= names


def test_centred_peg_goes_in_untouched_as_the_free_plant(fmu, robot):
    """Tip 5 mm above the hole's centre, pushed down: the peg enters the 0.1 mm clearance without a
    single contact (force exactly 0) and its depth follows DeltaWrist's kernels with no contact,
    integrated by scipy DOP853 (rtol 1e-11). Tolerance: CVODE at rtol 1e-8 on a 25 mm travel,
    2e-8 m (measured 3.5e-9 m); success latches at the reference's crossing of target_depth
    (20 mm), located by CVODE's root finding, to 1e-6 s (measured 4e-9 s)."""
    p, w, m = robot
    x0, u, tau, values = _start(robot, (0.0, 0.0, -1.195))
    T = 0.25
    r = _simulate(fmu, values, T)
    zero = (0.0, 0.0, 0.0)
    ref = solve_ivp(lambda t, x: dw.dynamics.state_derivative(p, w, m, x, u, tau, (0.0, 0.0, -PUSH), zero, 5.0),
                    (0.0, T), x0, method="DOP853", rtol=1e-11, atol=1e-13, dense_output=True)

    def depth(t):
        return HOLE.z - plant.tool_pose(p, w, m, ref.sol(t))[0][2]
    assert depth(T) > 0.024  # well past the target
    for name in ("contact_force[1]", "contact_force[2]", "contact_force[3]", "max_normal_force", "active_contacts"):
        assert np.all(r[name] == 0.0), name
    np.testing.assert_allclose(r["depth"], [depth(t) for t in r["time"]], atol=2e-8)
    lo, hi = 0.0, T  # the reference's crossing of the target depth, by bisection
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if depth(mid) < 0.02 else (lo, mid)
    latched = r["time"][np.argmax(r["success"] == 1)]
    assert abs(latched - lo) < 1e-6
    assert np.all(r["success"][r["time"] > latched] == 1) and np.all(r["success"][r["time"] < latched - 1e-9] == 0)


def test_offset_peg_slides_off_the_chamfer_and_centres(fmu, robot):
    """Tip off the axis by the clearance plus 60 % of the chamfer width: it lands on the chamfer
    (contact with the tip in the chamfer's depth), is pushed to the axis and goes in; the free
    wrist lets the peg tilt. At the end the tip is within the clearance (+ the rim polygon's
    48 um + the contacts' deflection) of the axis and success has latched. On the FMU's own states
    the Python contact kernel gives the FMU's contact force and moment (same kernel, generated C:
    1e-9 relative), and the F/T sensor reads R^T of them (tool frame)."""
    p, w, m = robot
    off = HOLE.bore_radius - PEG.radius + 0.6 * HOLE.chamfer_width
    x0, u, tau, values = _start(robot, (off, 0.0, -1.195))
    T = 0.25
    r = _simulate(fmu, values, T)
    chamfer = HOLE.chamfer_width * math.tan(HOLE.chamfer_angle)
    touching = (r["max_normal_force"] > 0.0) & (r["depth"] < chamfer)
    assert touching.any() and r["lateral_misalignment"][0] == pytest.approx(off, abs=1e-9)
    end = r[-1]
    polygon = PEG.radius * (1.0 - math.cos(math.pi / contact.RIM_POINTS))
    assert end["success"] == 1 and end["depth"] > 0.02
    deflection = end["max_normal_force"] / LAW.stiffness
    assert end["lateral_misalignment"] <= HOLE.bore_radius - PEG.radius + polygon + deflection
    checked = 0
    for row in r[::10]:
        x = [float(row[s]) for s in STATES]
        c = plant.plant_wrench(p, w, m, x, HOLE, PEG, LAW)
        scale = 1e-9 * max(1.0, c.max_normal)
        np.testing.assert_allclose([row[f"contact_force[{i}]"] for i in (1, 2, 3)], c.force, atol=scale)
        np.testing.assert_allclose([row[f"contact_moment[{i}]"] for i in (1, 2, 3)], c.moment, atol=scale)
        R = np.array([row[f"R[{i}]"] for i in range(1, 10)]).reshape(3, 3)
        ft = [row[f"ft_sensor[{i}]"] for i in range(1, 7)]
        np.testing.assert_allclose(ft[:3], R.T @ np.array(c.force), atol=scale)
        np.testing.assert_allclose(ft[3:], R.T @ np.array(c.moment), atol=scale)
        checked += c.active > 0
    assert checked >= 3


def test_co_simulation_agrees_with_model_exchange(fmu, robot):
    """The FMU's own CVODE (Co-Simulation, 1 ms steps) through the same chamfer landing: final depth
    and misalignments as fmpy's ME run to 1e-7 (both at rtol 1e-8 over a 26 mm travel)."""
    off = HOLE.bore_radius - PEG.radius + 0.6 * HOLE.chamfer_width
    values = _start(robot, (off, 0.0, -1.195))[3]
    me = _simulate(fmu, values, 0.25)[-1]
    cs = fmpy.simulate_fmu(str(fmu), fmi_type="CoSimulation", start_values=values, stop_time=0.25,
                           output_interval=1e-3, output=PEG_OUT)[-1]
    for name in ("depth", "lateral_misalignment", "angular_misalignment"):
        assert cs[name] == pytest.approx(me[name], abs=1e-7), name
    assert cs["success"] == 1


def test_peg_wider_than_the_bore_is_an_initialization_error(fmu, capfd):
    with pytest.raises(Exception):
        fmpy.simulate_fmu(str(fmu), start_values={"bore_radius": 0.009}, stop_time=0.01)
    assert "bore_radius 0.009 m must exceed the peg radius 0.01 m" in "".join(capfd.readouterr())
