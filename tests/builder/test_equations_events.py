"""Equation models with events, built into FMUs and run by fmpy: the talk's ball (an if-equation
and an algorithm with edge()) against the hand-written BouncingBall, the when/reinit ball against
its closed-form impact times."""
import numpy as np
import pytest
from fmpy import simulate_fmu

from deltafmi.builder.packager import build_cached


def _switches(name, interface, column, before, after, **options):
    result = simulate_fmu(build_cached(name), fmi_type=interface, stop_time=3.0, output=[column, "f" if
                          "Reinit" not in name else "height"], output_interval=1e-3, **options)
    values = result[column]
    k = np.where((values[:-1] == before) & (values[1:] == after))[0]
    return result["time"][k + 1], result


def test_talk_ball_impacts_equal_the_hand_written_ball():
    hand, _ = _switches("BouncingBall", "ModelExchange", "contact", 0, 1, relative_tolerance=1e-10)
    eq, _ = _switches("BouncingBallEquations", "ModelExchange", "contact", 0, 1, relative_tolerance=1e-10)
    assert len(hand) == 3 and len(eq) == len(hand)
    assert np.max(np.abs(eq - hand)) < 1e-9
    # the floor force while in contact agrees too (Co-Simulation, each FMU's own CVODE)
    _, a = _switches("BouncingBall", "CoSimulation", "contact", 0, 1)
    _, b = _switches("BouncingBallEquations", "CoSimulation", "contact", 0, 1)
    assert np.array_equal(a["contact"], b["contact"])
    assert np.max(np.abs(a["f"] - b["f"])) < 1e-5 * np.max(np.abs(a["f"]))


@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
def test_reinit_ball_impact_times_are_the_closed_form(interface):
    g, e, h0 = 9.81, 0.8, 1.0
    v1 = np.sqrt(2.0 * g * h0)
    exact = [np.sqrt(2.0 * h0 / g)]
    for k in range(1, 8):
        exact.append(exact[-1] + 2.0 * e ** k * v1 / g)
    result = simulate_fmu(build_cached("BouncingBallReinit"), fmi_type=interface, stop_time=3.0,
                          output=["impacts", "height"], output_interval=1e-4,
                          relative_tolerance=1e-12 if interface == "ModelExchange" else None)
    t, n = result["time"], result["impacts"]
    found = t[1:][np.diff(n) == 1]
    expected = [x for x in exact if x < 3.0]
    assert len(found) == len(expected)
    if interface == "ModelExchange":  # the event rows are at the impacts themselves
        assert np.max(np.abs(found - expected)) < 1e-9
    else:  # Co-Simulation shows an impact at the end of the step that contains it
        assert all(0.0 <= f - x < 1e-4 + 1e-12 for f, x in zip(found, expected))
    assert np.min(result["height"]) > -1e-9


@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
def test_ball_comes_to_rest_on_the_table_and_is_lifted_off(interface):
    """FREE / CONTACT: impacts with restitution, capture into the constraint h = 0, release."""
    g, m, e, capture, t_lift, F, h0 = 9.81, 0.5, 0.5, 0.1, 3.0, 10.0, 0.5
    v0 = np.sqrt(2.0 * g * h0)
    impacts, speed = [np.sqrt(2.0 * h0 / g)], v0
    while speed >= capture:  # each impact slower than capture ends in contact
        speed *= e
        impacts.append(impacts[-1] + 2.0 * speed / g)
    rest = impacts[-1]
    r = simulate_fmu(build_cached("BallOnTableEquations"), fmi_type=interface, stop_time=3.5,
                     output=["mode", "height", "lam"], output_interval=1e-4,
                     relative_tolerance=1e-12 if interface == "ModelExchange" else None)
    t, mode, h, lam = r["time"], r["mode"], r["height"], r["lam"]
    starts = t[1:][(mode[:-1] == 0) & (mode[1:] == 1)]
    assert len(starts) == 1
    resting = (t > starts[0] + 1e-9) & (t < t_lift - 1e-9)
    assert np.all(mode[resting] == 1) and np.all(h[resting] == 0.0)
    assert np.allclose(lam[resting], m * g, rtol=1e-14)
    if interface == "ModelExchange":
        assert abs(starts[0] - rest) < 1e-9
    else:
        assert 0.0 <= starts[0] - rest < 1e-4 + 1e-12
    lifted = t > t_lift + 1e-3
    assert np.all(mode[lifted] == 0)
    assert np.max(np.abs(h[lifted] - 0.5 * (F / m - g) * (t[lifted] - t_lift) ** 2)) < 1e-7
