"""Issue 28: the TargetFollower (the joystick experiment's reference) against closed forms.

Each sample advances the follower exactly for the target held over it (mechanics/delta/follower.py),
so for a target that does not move the sampled values have no discretization error: the closed
forms below, written out independently of the law's code, hold at the sample instants to
round-off (1e-12 m over thousands of samples). Far target: the speed command is v_max along a
fixed direction, the acceleration a_max until the gap to it is a_max / (2 wn), then the gap decays
at rate 2 wn (the cruise). Small step: the critically damped 1 - (1 + wn t) exp(-wn t).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy import simulate_fmu

from deltafmi.builder import build_cached
from deltafmi.physics.delta.follower import (STATUS_CLAMPED, FollowerSettings, follower_outputs, follower_step,
                                               initial_state, sample)

WN, V_MAX, A_MAX, H = 10.0, 0.5, 5.0, 1e-3
SETTINGS = FollowerSettings(WN, V_MAX, A_MAX, H, 0.5, -1.2, -0.75)
R0 = (0.0, 0.0, -1.0)


def run(target, n: int, settings: FollowerSettings = SETTINGS, r0=R0) -> dict:
    """The follower's outputs at instants 0..n for a target held from the start."""
    state = initial_state(settings, r0, target)
    rows = [follower_outputs(settings, state)]
    for _ in range(n):
        state = sample(settings, state, target)
        rows.append(follower_outputs(settings, state))
    return {"t": np.arange(n + 1) * settings.sample_period, "r": np.array([x[0] for x in rows]),
            "rd": np.array([x[1] for x in rows]), "rdd": np.array([x[2] for x in rows]),
            "status": np.array([x[3] for x in rows])}


def cruise(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance and speed from rest towards a far target: a_max, then the gap to v_max closing at 2 wn."""
    gap = A_MAX / (2 * WN)
    t1 = (V_MAX - gap) / A_MAX
    s1 = 0.5 * A_MAX * t1 ** 2
    tau = np.maximum(t - t1, 0.0)
    decay = np.exp(-2 * WN * tau)
    s = np.where(t <= t1, 0.5 * A_MAX * t ** 2, s1 + V_MAX * tau - gap * (1 - decay) / (2 * WN))
    v = np.where(t <= t1, A_MAX * t, V_MAX - gap * decay)
    return s, v


def test_a_far_target_is_reached_at_the_speed_and_acceleration_limits():
    target = (0.3, 0.3, -0.8)
    out = run(target, 4000)
    delta = np.subtract(target, R0)
    L = np.linalg.norm(delta)
    u = delta / L
    # the cruise holds while the speed command is limited: |e| > 2 v_max / wn and > v_max^2 / a_max
    window = out["t"] <= 0.7
    assert L - cruise(out["t"][window])[0][-1] > max(2 * V_MAX / WN, V_MAX ** 2 / A_MAX)
    s, v = cruise(out["t"][window])
    np.testing.assert_allclose(out["r"][window], np.asarray(R0) + np.outer(s, u), rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["rd"][window], np.outer(v, u), rtol=0, atol=1e-12)
    assert np.linalg.norm(out["rd"][window][-1]) > V_MAX * (1 - 1e-5)      # saturated
    speed, accel = np.linalg.norm(out["rd"], axis=1), np.linalg.norm(out["rdd"], axis=1)
    assert speed.max() <= V_MAX * (1 + 1e-12) and accel.max() <= A_MAX * (1 + 1e-12)
    assert accel[1] == pytest.approx(A_MAX, rel=1e-12)                       # it starts at the limit
    assert np.abs(out["r"][-1] - target).max() <= 1e-9
    assert ((out["r"] - np.asarray(R0)) @ u).max() <= L + 1e-12                    # no overshoot


def test_a_small_step_is_the_critically_damped_closed_form():
    A = np.array([0.006, -0.004, 0.005])   # wn^2 |A| <= a_max, (wn / 2) |A| <= v_max: no limit acts
    target = tuple(np.asarray(R0) + A)
    out = run(target, 1500)
    t = out["t"][:, None]
    assert (out["status"] == 0).all()
    np.testing.assert_allclose(out["r"], target - A * (1 + WN * t) * np.exp(-WN * t), rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["rd"], A * WN ** 2 * t * np.exp(-WN * t), rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["rdd"], A * WN ** 2 * (1 - WN * t) * np.exp(-WN * t), rtol=0, atol=1e-10)


def test_the_target_is_clamped_to_the_nominal_workspace():
    out = run((1.2, -0.9, -2.0), 5000)    # radius 1.5 m, below z_min
    clamped = (0.5 * 0.8, -0.5 * 0.6, -1.2)
    assert (out["status"] & STATUS_CLAMPED).all()
    assert np.abs(out["r"][-1] - clamped).max() <= 1e-9
    rho = np.hypot(out["r"][:, 0], out["r"][:, 1])
    assert rho.max() <= 0.5 + 1e-12 and out["r"][:, 2].min() >= -1.2 - 1e-12
    assert np.linalg.norm(out["rd"], axis=1).max() <= V_MAX * (1 + 1e-12)


def test_a_slow_follower_obeys_the_braking_limit_without_overshoot():
    """With a_max small for its bandwidth the speed command near the target is sqrt(a_max |e|)."""
    s = SETTINGS._replace(a_max=0.4)
    target = (0.0, 0.4, -1.0)
    out = run(target, 8000, settings=s)
    assert np.linalg.norm(out["rdd"], axis=1).max() <= 0.4 * (1 + 1e-12)
    assert out["r"][:, 1].max() <= 0.4 + 1e-12
    assert abs(out["r"][-1, 1] - 0.4) <= 1e-9


def moving_target(n: int) -> np.ndarray:
    """A target that jumps, sweeps out of the workspace and back: every branch of the law."""
    t = np.arange(n + 1) * H
    x = np.where(t < 0.6, 0.1, 0.2 * np.sin(3 * t))
    y = np.where(t < 1.2, 0.004, 0.8 * np.cos(2 * t))
    z = np.where(t < 0.8, -1.0, -1.0 + 0.15 * np.sin(1.5 * (t - 0.8)))
    rows = np.zeros(n + 1, dtype=[("time", float), ("target[1]", float), ("target[2]", float), ("target[3]", float)])
    rows["time"], rows["target[1]"], rows["target[2]"], rows["target[3]"] = t, x, y, z
    return rows


OUTPUTS = [f"{v}[{i}]" for v in ("r", "rd", "rdd") for i in (1, 2, 3)] + ["status"]


@pytest.mark.parametrize("interface", ["CoSimulation", "ModelExchange"])
def test_the_fmu_equals_the_mechanics_and_its_compiled_kernels_equal_python(interface, monkeypatch):
    fmu = str(build_cached("TargetFollower"))
    signal = moving_target(2000)
    results = {}
    for native in ("1", "0"):
        monkeypatch.setenv("DELTAFMI_NATIVE", native)
        results[native] = simulate_fmu(fmu, fmi_type=interface, stop_time=2.0, output_interval=H, step_size=H,
                                       input=signal, output=OUTPUTS)
    for name in ("time", *OUTPUTS):
        assert np.array_equal(results["1"][name], results["0"][name]), name
    res = results["1"]
    assert set(res["status"]) >= {0, 2, 4, 6} and (res["status"] & STATUS_CLAMPED).any()   # every branch
    if interface == "CoSimulation":
        # doStep(t, h) is follower_step with the target at t, from the state after initialization
        state, k = initial_state(SETTINGS, R0, tuple(signal[0])[1:]), 0
        for i in range(1, len(res)):
            state, k, r, rd, rdd, status = follower_step(SETTINGS, state, 0.0, k, (i - 1) * H, H,
                                                         tuple(signal[i - 1])[1:])
            assert tuple(res[i])[1:] == (*r, *rd, *rdd, status), i


@pytest.mark.parametrize("start, message", [
    ({"r0[3]": -0.5}, "r0 = (0.0, 0.0, -0.5) has z -0.5 m outside [-1.2, -0.75] m: the follower must start inside "
                      "the nominal workspace"),
    ({"a_max": 0.0}, "a_max must be > 0, got 0.0"),
])
def test_bad_parameters_fail_initialization_with_a_clear_message(start, message, capfd):
    # fmpy's default logger prints: a logger passed to simulate_fmu would stay registered in
    # fmpy's native logging proxy after the call, freed, and crash the next FMU that logs
    with pytest.raises(Exception, match="fmi2ExitInitializationMode failed"):
        simulate_fmu(str(build_cached("TargetFollower")), fmi_type="CoSimulation", start_values=start)
    messages = "".join(capfd.readouterr()).splitlines()
    assert any(message in m for m in messages), messages
