"""The contact FMUs through fmpy, Model Exchange and Co-Simulation, against the reference driver
and against physics."""
from __future__ import annotations

import math

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from bouncing_ball_figures import bounce_figures
from hybrid_sim import simulate
from deltafmi.physics.contact_problems.newtons_cradle import make_cradle

G = 9.81
BOTH = ["ModelExchange", "CoSimulation"]


def after_events(result):
    """fmpy records event instants twice (before/after): keep the value after the event."""
    t = result["time"]
    return result[np.r_[t[1:] != t[:-1], True]]


def on_grid(result, step=1e-3):
    r = after_events(result)
    k = np.round(r["time"] / step)
    return r[np.abs(r["time"] - k * step) < 1e-9]


def sim(fmu, fmi_type, **kw):
    kw.setdefault("relative_tolerance", 1e-9)
    return fmpy.simulate_fmu(str(fmu), fmi_type=fmi_type, **kw)


@pytest.fixture(scope="module")
def fmus(build_fmu_from_src):
    names = ["bouncing_ball", "bouncing_ball_restitution", "newtons_cradle", "box_on_table"]
    return {name: build_fmu_from_src(f"{name}.py") for name in names}


def test_all_validate(fmus):
    for name, fmu in fmus.items():
        assert validate_fmu(str(fmu)) == [], name
        md = fmpy.read_model_description(str(fmu))
        assert md.modelExchange and md.coSimulation
    md = fmpy.read_model_description(str(fmus["newtons_cradle"]))
    assert md.numberOfContinuousStates == 14 and md.numberOfEventIndicators == 12


def test_modelica_ball_events_match_reference(fmus):
    ref = bounce_figures(a1=20.0, t_end=3.0).transitions
    r = sim(fmus["bouncing_ball"], "ModelExchange", output=["q", "contact"])
    c = r["contact"]
    i = np.flatnonzero(np.diff(c) != 0)
    got = [(r["time"][k + 1], int(c[k]), int(c[k + 1])) for k in i]
    assert [(a, b) for _, a, b in got] == [(a, b) for _, a, b in ref]
    np.testing.assert_allclose([t for t, _, _ in got], [t for t, _, _ in ref], atol=1e-6)
    assert got[0][0] == pytest.approx(math.sqrt(2 / G), abs=1e-8)


def test_modelica_ball_me_and_cs_agree(fmus):
    me, cs = (on_grid(sim(fmus["bouncing_ball"], t, output_interval=1e-3, output=["q", "v"])) for t in BOTH)
    assert len(me) == len(cs) == 3001
    assert np.max(np.abs(me["q"] - cs["q"])) < 1e-6
    assert np.max(np.abs(me["v"] - cs["v"])) < 1e-5


def test_modelica_ball_gains_energy_without_damping(fmus):
    r = after_events(sim(fmus["bouncing_ball"], "ModelExchange", stop_time=1.3,
                         start_values={"a1": 0.0}, output=["energy", "contact"]))
    flight = (r["contact"] == 2) & (r["time"] > 0.6)
    np.testing.assert_allclose(r["energy"][flight], G + 0.1362139476, rtol=1e-6)


@pytest.mark.parametrize("fmi_type", BOTH)
def test_restitution_ball(fmus, fmi_type):
    r = after_events(sim(fmus["bouncing_ball_restitution"], fmi_type, output_interval=1e-3,
                         output=["q", "mode", "lam", "energy"]))
    first_flight = (r["time"] > 0.5) & (r["time"] < 1.1)
    assert np.max(r["q"][first_flight]) == pytest.approx(0.8 ** 2, rel=1e-3)
    assert r["mode"][-1] == 2 and r["lam"][-1] == pytest.approx(G, rel=1e-3)
    assert r["energy"][-1] < 1e-3 * r["energy"][0]


@pytest.fixture(scope="module")
def cradle_runs(fmus):
    out = ["q[1]", "q[2]", "q[3]", "energy", "momentum"] + [f"vx[{i}]" for i in range(1, 8)]
    return {t: on_grid(sim(fmus["newtons_cradle"], t, stop_time=0.5, output=out)) for t in BOTH}


@pytest.mark.parametrize("fmi_type", BOTH)
def test_cradle_pendulums_hand_over(cradle_runs, fmi_type):
    r = cradle_runs[fmi_type]
    v_strike = math.sqrt(2 * G * 0.3 * (1 - math.cos(0.3)))
    k = np.searchsorted(r["time"], 0.28)   # just after the first strike (t = 0.2762 s)
    assert r["vx[3]"][k] >= 0.97 * v_strike
    assert abs(r["vx[1]"][k]) < 0.08 * v_strike and abs(r["vx[2]"][k]) < 0.08 * v_strike
    assert np.all(r["vx[4]"] == 0.0)       # unused balls are frozen
    assert np.max(np.abs(r["energy"] / r["energy"][0] - 1)) < 1e-5


def test_cradle_me_and_cs_agree(cradle_runs):
    me, cs = cradle_runs["ModelExchange"], cradle_runs["CoSimulation"]
    for name in ["q[1]", "q[2]", "q[3]", "vx[1]", "vx[2]", "vx[3]"]:
        assert np.max(np.abs(me[name] - cs[name])) < 1e-5, name


def test_cradle_free_chain_matches_reference(fmus):
    system, x0 = make_cradle(5, striker_speed=1.0, radius=0.0125, mass=0.1)
    ref = simulate(system, (0.0, 0.01), x0, rtol=1e-10, atol=1e-13)
    r = sim(fmus["newtons_cradle"], "CoSimulation", stop_time=0.01, output_interval=1e-4,
            start_values={"n": 5, "pendulum": False}, output=[f"vx[{i}]" for i in range(1, 6)] + ["momentum"])
    got = np.array([r[f"vx[{i}]"][-1] for i in range(1, 6)])
    np.testing.assert_allclose(got, system.model.ball_velocities(ref.x[-1])[:5], atol=1e-6)
    assert abs(r["momentum"][-1] - 0.1) < 1e-9


@pytest.mark.parametrize("fmi_type", BOTH)
def test_box_rests_on_two_corners(fmus, fmi_type):
    out = [f"lam[{i}]" for i in range(1, 5)] + [f"mode[{i}]" for i in range(1, 5)] + ["total_force", "theta"]
    r = sim(fmus["box_on_table"], fmi_type, relative_tolerance=1e-8, output=out,
            start_values={"com_offset[1]": 0.04})
    assert [int(r[f"mode[{i}]"][-1]) for i in range(1, 5)] == [2, 2, 0, 0]
    assert r["total_force"][-1] == pytest.approx(G, rel=1e-6)
    np.testing.assert_allclose([r["lam[1]"][-1], r["lam[2]"][-1]], [G * 0.16 / 0.4, G * 0.24 / 0.4], rtol=1e-6)
    assert abs(r["theta"][-1]) < 1e-6
