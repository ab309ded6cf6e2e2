"""Issue 26: the delta controller's whole sample (deltafmi.physics.delta.sampling.sample: the
tactile shift, the integral frozen while saturated, the control law, the held torque on a
singular sample, the zero-order-hold lead, the warm start and the warning latch) translated to C
by deltafmi.builder.codegen from its unchanged source, against the Python DeltaController.

Each sample goes through the Python controller and through the generated ``dfk_sample``, the
state the C returned handed back to it (C -> Python -> C) for the next sample; the whole state
(torques, status, cond, shift, integral, warm start, warning latch) must agree to the bit. The
flagship's controller samples are replayed over its whole run, and the Python torques checked
against the hand C transcription of the controller (benchmarks/native/flagship.c) as well; the
other cases reach the singular branch, torque saturation, the tactile loop, the impedance mode
and the warning latch.
"""
from __future__ import annotations

import importlib
import math
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from deltafmi.builder.codegen import Entry, Vec, named
from deltafmi.builder.codegen.build import compile_unit
from deltafmi.builder.codegen.kernel_types import D
from deltafmi.toolchain import NoCompilerError
from deltafmi.physics import delta as d
from deltafmi.physics.delta import control
from deltafmi.physics.delta.sampling import SampleSettings, SampleState, initial_state

ROOT = Path(__file__).resolve().parents[2]
P = d.RL5
TS = 1e-3
ARGS = [named(control.ControlLaw), named(SampleSettings), named(SampleState), Vec(3), Vec(3), Vec(3), Vec(3),
        Vec(3), Vec(3), D]
ZERO3 = (0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    try:
        # _f3 converts a numpy array or sequence to 3 floats: the identity on C's fixed arrays
        return compile_unit([Entry("dfk_sample", control.sample, ARGS)], tmp_path_factory.mktemp("sample"),
                            identities={"_f3"}, name="sample")
    except NoCompilerError as exc:
        pytest.skip(f"no C compiler for the generated sample: {exc}")


def flat(value) -> list:
    """Every number of a (nested) value as its IEEE-754 bits (ints as themselves, None kept)."""
    if value is None:
        return [None]
    if isinstance(value, (tuple, list, np.ndarray)):
        return [b for v in value for b in flat(v)]
    if isinstance(value, float):
        return [struct.unpack("<q", struct.pack("<d", value))[0]]
    return [int(value)]


def both(lib, ctl: control.DeltaController, state: SampleState, sample) -> SampleState:
    """One sample (y, yd, r, rd, rdd, force, tactile) through ``ctl`` and through the generated
    sample from ``state`` (the state C returned last time); asserts they agree bit for bit."""
    y, yd, r, rd, rdd, force, tactile = sample
    u = ctl.step(y, yd, r, rd, rdd, force, tactile)
    state = lib.call("dfk_sample", ctl.law, ctl.settings, state, y, yd, r, rd, rdd, force, tactile)
    assert type(state) is SampleState
    assert flat(u) == flat(state.u) and state.status == ctl.status
    assert flat((state.cond, state.shift)) == flat((ctl.cond, ctl.shift))
    assert flat(state) == flat(ctl.state), f"{state} != {ctl.state}"
    return state


def replay(lib, ctl: control.DeltaController, samples) -> list[SampleState]:
    """``samples`` through ``ctl`` and the generated sample (see :func:`both`): the states."""
    state, states = initial_state(), []
    for k, sample in enumerate(samples):
        try:
            state = both(lib, ctl, state, sample)
        except AssertionError as exc:
            raise AssertionError(f"sample {k}: {exc}") from None
        states.append(state)
    return states


def test_flagship_samples_bit_for_bit(lib, tmp_path):
    """The flagship's controller samples over its whole run (3.5 s at 1 kHz)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    native = importlib.import_module("native")
    system = native.load_flagship()
    try:
        baseline = native.Baseline(native.compile_baseline(tmp_path))
    except NoCompilerError as exc:
        pytest.skip(f"no C compiler: {exc}")
    spec = native.flagship_spec(system)
    experiment = system.scenario.experiment
    steps = int(round((experiment.stop - experiment.start) / experiment.step))
    rows, states, _ = baseline.run(spec, steps)
    inputs = native.controller_inputs(baseline, spec, rows, states)
    ctl = native.flagship_models(system).controller
    samples = [(i[0:3], i[3:6], i[6:9], i[9:12], i[12:15], ZERO3, 0.0) for i in inputs.tolist()]
    got = replay(lib, ctl, samples)
    u = np.array([s.u for s in got])
    # the Python controller is still the one the hand C transcription was written from
    u_hand, _ = baseline.replay_controller(spec, inputs)
    assert flat(u) == flat(u_hand)
    assert len(got) == steps and np.ptp(u[:, 0]) > 1.0 and max(s.iterations for s in got) >= 1


def _servo(z):
    return control.inverse_kinematics_servo(P, z)[0].tolist()


def _circle(n: int, seed: int, radius: float = 0.1, err: float = 2e-3, force: float = 0.0, tactile: float = 0.0):
    """Samples along a circle about (0, 0, -1) m: the servo state a little off the reference."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        w, t = 2.0 * math.pi, k * TS
        r = (radius * math.cos(w * t), radius * math.sin(w * t), -1.0)
        rd = (-w * r[1], w * r[0], 0.0)
        rdd = (-w * w * r[0], -w * w * r[1], 0.0)
        y = _servo(np.array(r) + rng.normal(0.0, err, 3))
        yd = rng.normal(0.0, 0.5, 3).tolist()
        f = rng.normal(0.0, force, 3).tolist() if force else ZERO3
        out.append((y, yd, r, rd, rdd, f, float(rng.normal(0.0, tactile)) if tactile else 0.0))
    return out


def test_singular_samples_hold_the_torque_and_warn_once(lib):
    """Near the stretched singularity (ill-conditioned, saturated), then measurements with no
    assembly (singular: the torque held, the warm start dropped), then back on the circle."""
    zs = d.stretched_height(P)
    near = _servo((0.0, 0.0, zs + 1e-6))
    bad = [math.nan, 0.0, 0.0]
    target = (0.0, 0.0, zs + 0.01)
    samples = (_circle(20, 1) + [(near, ZERO3, target, ZERO3, ZERO3, ZERO3, 0.0)] * 3
               + [(bad, ZERO3, target, ZERO3, ZERO3, ZERO3, 0.0)] * 2 + _circle(20, 2)
               + [(bad, ZERO3, target, ZERO3, ZERO3, ZERO3, 0.0)] + _circle(5, 3))
    ctl = control.DeltaController(P, torque_limit=250.0)
    warnings, states, state = [], [], initial_state()
    for sample in samples:  # one by one, to read pending_warning after each
        state = both(lib, ctl, state, sample)
        states.append(state)
        warnings.append(ctl.pending_warning())
    statuses = [s.status for s in states]
    assert statuses[20] & control.STATUS_ILL_CONDITIONED and statuses[20] & control.STATUS_TORQUE_SATURATED
    assert statuses[23] == statuses[24] == control.STATUS_SINGULAR == statuses[45]
    # a singular sample holds the previous torque and drops the warm start and the lead
    assert states[23].u == states[22].u and states[23].x_next is None and states[23].u_law is None
    assert states[23].z == states[22].z and states[23].integral == states[22].integral
    assert states[25].iterations == -1 and states[26].iterations >= 0   # cold start, then Newton again
    # the latch: each bit warns once, at the sample that first raised it
    assert [k for k, s in enumerate(states) if s.new_warnings] == [20, 23]
    assert states[20].new_warnings == control.STATUS_ILL_CONDITIONED
    assert states[23].new_warnings == control.STATUS_SINGULAR
    assert states[-1].warned == control.STATUS_ILL_CONDITIONED | control.STATUS_SINGULAR
    assert [k for k, w in enumerate(warnings) if w] == [20, 23]
    assert "ill-conditioned" in warnings[20] and "singular" in warnings[23] and "+-250 N m" in warnings[23]


def test_torque_saturation_freezes_the_integral(lib):
    """A torque limit the circle exceeds: the law's clipping and the lead's, the integral frozen."""
    ctl = control.DeltaController(P, torque_limit=100.0)
    states = replay(lib, ctl, _circle(300, 4, radius=0.2, err=5e-3))
    saturated = [k for k, s in enumerate(states) if s.status & control.STATUS_TORQUE_SATURATED]
    assert 10 < len(saturated) < len(states)
    assert all(max(abs(u) for u in s.u) <= 100.0 for s in states)
    # clipped by the law, and by the lead alone (the law's torque within the limit)
    by_lead = [k for k in saturated if max(abs(u) for u in states[k].u_law) < 100.0]
    assert 0 < len(by_lead) < len(saturated)
    # after a saturated sample the next one integrates nothing (conditional integration)
    frozen = [k + 1 for k in saturated if k + 1 < len(states)]
    assert all(states[k].integral == states[k - 1].integral for k in frozen)
    assert any(states[k].integral != states[k - 1].integral for k in range(1, len(states)) if k not in frozen)


def test_tactile_loop_shifts_the_reference(lib):
    """tactile_gain != 0 on a diagonal axis: the shift integrates gain * tactile over the samples."""
    ctl = control.DeltaController(P, tactile_gain=2e-3, tactile_axis=(1.0, 1.0, 0.0))
    samples = _circle(200, 5, tactile=3.0)
    states = replay(lib, ctl, samples)
    expected = math.fsum(2e-3 * s[6] * TS for s in samples)
    assert states[-1].shift == pytest.approx(expected, rel=1e-12, abs=1e-15) and abs(expected) > 1e-6
    assert ctl.settings.tactile_axis == pytest.approx((math.sqrt(0.5), math.sqrt(0.5), 0.0))


def test_impedance_mode_with_a_commanded_force(lib):
    ctl = control.DeltaController(P, impedance=True, stiffness=(4000.0, 3000.0, 900.0),
                                  task_damping=(300.0, 200.0, 150.0))
    states = replay(lib, ctl, _circle(150, 6, force=20.0))
    assert all(s.integral == ZERO3 for s in states)  # the impedance mode has no integral
    plain = control.DeltaController(P, impedance=True, stiffness=(4000.0, 3000.0, 900.0),
                                    task_damping=(300.0, 200.0, 150.0))
    unforced = [plain.step(*s[:5]).tolist() for s in _circle(150, 6)]
    assert max(abs(a - b) for s, v in zip(states, unforced) for a, b in zip(s.u, v)) > 1.0  # the force acts


def test_without_lead_closed_form_and_ill_conditioning(lib):
    """No zero-order-hold lead, closed-form kinematics, a low cond_limit and a clamped integral."""
    ctl = control.DeltaController(P, zoh_lead=False, fk="closed", cond_limit=1.5, integral_limit=1e-3)
    states = replay(lib, ctl, _circle(100, 7))
    assert all(s.iterations == -1 for s in states)
    assert all(s.status & control.STATUS_ILL_CONDITIONED for s in states)
    assert any(s.status & control.STATUS_INTEGRAL_CLAMPED for s in states)
    assert [k for k, s in enumerate(states) if s.new_warnings] == [0]
