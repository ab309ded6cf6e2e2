"""Issue 28: the joystick source (deltafmi/master/live/joystick.py) and its recorded sessions.

The axis mapping is checked against its formula written out here (normalize over the device's
range, dead band rescaled to stay continuous, offset + scale * value, the rate limit's ramp);
sessions are written here as plain JSON lines, so a parse error must name file:line, playback
must release events by stamp, and a recording of a playback must give the input back.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from deltafmi.master.live.joystick import AxisMap, AxisRange, JoystickSource, read_session
from deltafmi.errors import BadInput

SHIPPED = Path(__file__).resolve().parents[2] / "scenarios" / "joystick_session.jsonl"
HEADER = {"format": "deltafmi-joystick-session", "version": 1, "device": "test pad",
          "axes": {"ABS_X": {"min": -32768, "max": 32767, "flat": 0}, "ABS_RY": {"min": 0, "max": 1023, "flat": 0}}}


def write_session(path: Path, events, header=HEADER) -> Path:
    lines = [json.dumps(header)] + [json.dumps({"t": t, "code": c, "value": v}) for t, c, v in events]
    path.write_text("\n".join(lines) + "\n")
    return path


def play(source: JoystickSource, times) -> list:
    """The value of every signal after each poll at ``times`` (the source opened and closed here)."""
    warnings = []
    source.open(warnings.append)
    current, rows = {}, []
    try:
        for t in times:
            current.update(source.poll(t) or {})
            rows.append(dict(current))
    finally:
        source.close()
    return rows


# --- the axis mapping -------------------------------------------------------------------------------

def test_the_range_maps_onto_minus_one_to_one():
    r = AxisRange(0, 1023, 0)
    assert r.normalized(0) == -1.0 and r.normalized(1023) == 1.0 and r.normalized(2000) == 1.0
    assert r.normalized(767.25) == pytest.approx(0.5, abs=1e-15)


@pytest.mark.parametrize("band", [0.0, 0.1, 0.35])
@pytest.mark.parametrize("invert", [False, True])
def test_dead_band_scale_offset_and_invert_follow_the_formula(band, invert):
    m = AxisMap("ABS_X", scale=0.15, offset=-0.02, dead_band=band, invert=invert)
    x = np.linspace(-1.0, 1.0, 2001)
    s = -x if invert else x
    expected = -0.02 + 0.15 * np.where(np.abs(s) <= band, 0.0, np.sign(s) * (np.abs(s) - band) / (1 - band))
    got = np.array([m.value(v) for v in x])
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-15)
    assert m.value(1.0) == pytest.approx(-0.02 + (-0.15 if invert else 0.15), abs=1e-15)
    # continuous at the band's edge: a step eps past it moves the output by scale * eps / (1 - band)
    eps = 1e-9
    assert abs(m.value(band + eps) - m.value(band)) <= 0.15 * eps / (1 - band) * (1 + 1e-6)


def test_the_default_dead_band_is_the_device_flat(tmp_path):
    header = json.loads(json.dumps(HEADER))
    header["axes"]["ABS_X"]["flat"] = 3277            # 10 % of the half-range
    path = write_session(tmp_path / "s.jsonl", [(0.0, "ABS_X", 3000), (0.01, "ABS_X", 16384)], header)
    source = JoystickSource("pad", {"x": AxisMap("ABS_X")}, device=None, session=path)
    first, second = play(source, [0.0, 0.01])
    band = 2 * 3277 / 65535
    assert first["x"] == 0.0
    n = 2 * (16384 + 32768) / 65535 - 1
    assert second["x"] == pytest.approx((n - band) / (1 - band), abs=1e-15)
    off = JoystickSource("pad", {"x": AxisMap("ABS_X", dead_band=0.0)}, device=None, session=path)
    assert play(off, [0.0])[0]["x"] == pytest.approx(2 * (3000 + 32768) / 65535 - 1, abs=1e-15)


def test_the_rate_limit_ramps_at_its_rate_in_simulation_time(tmp_path):
    path = write_session(tmp_path / "s.jsonl", [(0.1, "ABS_RY", 1023), (0.3, "ABS_RY", 0)])
    h, rate, scale = 1e-3, 0.5, 0.15
    times = np.arange(1001) * h
    source = JoystickSource("pad", {"z": AxisMap("ABS_RY", scale=scale, rate_limit=rate)}, device=None, session=path)
    z = np.array([row["z"] for row in play(source, times)])
    centre = scale * (2 * 511.5 / 1023 - 1)          # no "value" in the header: the stick starts centred
    # a discrete rate limiter (as Simulink's): each poll moves by at most rate * (t - t_before)
    # towards the value read at that poll, so the ramp's first move is at the event's poll
    up = np.minimum(centre + rate * np.maximum(times - 0.1 + h, 0.0), scale)
    peak = rate * 0.2                                  # where the ramp up is when the stick reverses
    expected = np.where(times < 0.3 - 1e-12, up, np.maximum(peak - rate * (times - 0.3 + h), -scale))
    np.testing.assert_allclose(z, expected, rtol=0, atol=1e-12)
    assert z[-1] == -scale and z.max() == pytest.approx(peak, abs=1e-12)


# --- sessions ---------------------------------------------------------------------------------------

BAD = [
    ("{not json", 1, "not JSON"),
    (json.dumps({"format": "something else", "version": 1, "axes": {}}), 1, "not a joystick session"),
    (json.dumps({**HEADER, "version": 7}), 1, "version 7"),
    (json.dumps({**HEADER, "axes": {"ABS_X": {"min": 5, "max": 5}}}), 1, "min < max"),
    (json.dumps(HEADER) + "\n" + '{"t": 0.0, "code": "ABS_X", "value": 3}\n{"t": 0.1, "code"', 3, "not JSON"),
    (json.dumps(HEADER) + "\n" + '{"t": 0.0, "code": "ABS_Z", "value": 3}', 2, "'ABS_Z' is not in the header"),
    (json.dumps(HEADER) + "\n" + '{"t": 0.2, "code": "ABS_X", "value": 3}\n{"t": 0.1, "code": "ABS_X", "value": 3}',
     3, "goes back in time"),
    (json.dumps(HEADER) + "\n" + '{"t": 0.2, "code": "ABS_X", "value": 3.5}', 2, "not an integer"),
    (json.dumps(HEADER) + "\n" + '{"t": "soon", "code": "ABS_X", "value": 3}', 2, "not a finite number"),
]


@pytest.mark.parametrize("text, line, what", BAD)
def test_a_bad_session_names_its_file_and_line(tmp_path, text, line, what):
    path = tmp_path / "bad.jsonl"
    path.write_text(text)
    with pytest.raises(BadInput) as info:
        read_session(path)
    message = info.value.message
    assert message.startswith(f"{path}:{line}: ") and what in message and "\n" not in message


def test_a_missing_session_or_axis_is_a_one_line_error(tmp_path):
    source = JoystickSource("pad", {"x": AxisMap("ABS_X")}, device=None, session=tmp_path / "none.jsonl")
    with pytest.raises(BadInput, match=r"none.jsonl: cannot read it"):
        source.open(print)
    path = write_session(tmp_path / "s.jsonl", [])
    source = JoystickSource("pad", {"y": AxisMap("ABS_Y")}, device=None, session=path)
    with pytest.raises(BadInput, match=r"the session .*s.jsonl has no ABS_Y \(its axes: ABS_X, ABS_RY\)"):
        source.open(print)


def test_playback_releases_every_event_stamped_up_to_the_poll_in_order(tmp_path):
    events = [(0.0, "ABS_RY", 100), (0.0025, "ABS_RY", 200), (0.005, "ABS_RY", 300), (0.005, "ABS_RY", 400),
              (0.005, "ABS_X", 32767)]
    path = write_session(tmp_path / "s.jsonl", events)
    source = JoystickSource("pad", {"z": AxisMap("ABS_RY", scale=1023.0 / 2, offset=1023.0 / 2, dead_band=0.0),
                                    "x": AxisMap("ABS_X", dead_band=0.0)}, device=None, session=path)
    rows = play(source, [0.0, 0.001, 0.002, 0.003, 0.004, 0.005, 0.006])
    assert [round(r["z"], 9) for r in rows] == [100, 100, 100, 200, 200, 400, 400]
    assert [r["x"] for r in rows] == [0.0] * 5 + [1.0, 1.0]   # centred until its event
    assert source.counters()["events"] == 5


def test_a_recording_of_a_playback_is_the_session_again(tmp_path):
    out = tmp_path / "again.jsonl"
    maps = {"x": AxisMap("ABS_X", scale=0.15), "y": AxisMap("ABS_Y", scale=0.15, invert=True),
            "z": AxisMap("ABS_RY", scale=0.1, offset=-1.0, rate_limit=0.5)}
    source = JoystickSource("stick", maps, device=None, session=SHIPPED, record_to=out)
    times = np.arange(20001) * 1e-3
    first = play(source, times)
    assert out.read_bytes() == SHIPPED.read_bytes()
    # and playing the recording repeats the run, bit for bit
    again = play(JoystickSource("stick", maps, device=None, session=out), times)
    assert again == first


def test_the_shipped_session_is_a_plausible_pad(tmp_path):
    session = read_session(SHIPPED)
    assert session.device.startswith("synthesized") and set(session.axes) == {"ABS_X", "ABS_Y", "ABS_RY"}
    assert 15.0 <= session.events[-1][0] <= 20.0 and SHIPPED.stat().st_size < 300_000
    t = np.array([e[0] for e in session.events])
    per_second = len(set(t)) / 20.0
    assert 60 <= per_second <= 250                               # reports seen per second (125 Hz pad)
    maps = {"x": AxisMap("ABS_X", scale=0.15), "y": AxisMap("ABS_Y", scale=0.15), "z": AxisMap("ABS_RY", scale=0.1)}
    rows = play(JoystickSource("stick", maps, device=None, session=SHIPPED), np.arange(20001) * 1e-3)
    x = np.array([r["x"] for r in rows])
    assert x.max() > 0.1 and x.min() < -0.08                     # excursions both ways
    assert rows[0] == {"x": 0.0, "y": 0.0, "z": 0.0} == rows[-1]  # at rest, inside the flat, at both ends


# --- devices ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("device", ["auto", None, "/dev/input/event0"])
def test_without_python_evdev_the_error_says_what_to_install(monkeypatch, device):
    monkeypatch.setitem(sys.modules, "evdev", None)   # what `import evdev` meets when it is not installed
    source = JoystickSource("stick", {"x": AxisMap("ABS_X")}, device=device)
    with pytest.raises(BadInput) as info:
        source.open(print)
    assert info.value.message == ("joystick source 'stick': python-evdev is not installed: pip install "
                                  "'deltafmi[joystick]' (or pip install evdev), or give a recorded session")


def test_without_python_evdev_auto_plays_the_session_and_says_so(monkeypatch):
    monkeypatch.setitem(sys.modules, "evdev", None)
    source = JoystickSource("stick", {"x": AxisMap("ABS_X", scale=0.15)}, device="auto", session=SHIPPED)
    warnings = []
    source.open(warnings.append)
    source.close()
    assert source.playing is not None and len(warnings) == 1
    assert warnings[0] == ("joystick source 'stick': python-evdev is not installed: playing the recorded session "
                           f"{SHIPPED}")


def test_with_python_evdev_a_missing_device_is_a_one_line_error():
    evdev = pytest.importorskip("evdev")
    devices = evdev.list_devices()
    if any(evdev.ecodes.EV_ABS in evdev.InputDevice(p).capabilities() for p in devices):
        pytest.skip("this machine has an input device with absolute axes")
    with pytest.raises(BadInput) as info:
        JoystickSource("stick", {"x": AxisMap("ABS_X"), "z": AxisMap("ABS_RY")}, device="auto").open(print)
    message = info.value.message
    assert message.startswith("joystick source 'stick': no input device has axes ABS_X, ABS_RY (found: ")
    assert "\n" not in message and ("no input devices in /dev/input" in message) == (not devices)
    with pytest.raises(BadInput, match=r"^joystick source 'stick': cannot open /dev/input/event999: "):
        JoystickSource("stick", {"x": AxisMap("ABS_X")}, device="/dev/input/event999").open(print)


def test_bad_axis_settings_are_one_line_errors():
    with pytest.raises(BadInput, match="dead_band = 1.0 must be in"):
        AxisMap("ABS_X", dead_band=1.0)
    with pytest.raises(BadInput, match="rate_limit = 0 must be > 0"):
        AxisMap("ABS_X", rate_limit=0)
    with pytest.raises(BadInput, match="expected an evdev absolute axis"):
        AxisMap("BTN_A")


# --- through the master -----------------------------------------------------------------------------

def follower_scenario(directory: Path, session: Path, record: Path = None) -> Path:
    joystick = {"session": str(session)}
    if record is not None:
        joystick["record"] = str(record)
    text = json.dumps({
        "experiment": {"start": 0.0, "stop": 6.0, "step": 1e-3},
        "live": {"stick": {"joystick": joystick, "signals": {
            "x": {"axis": "ABS_X", "scale": 0.2, "unit": "m"},
            "y": {"axis": "ABS_Y", "scale": -0.2, "rate_limit": 0.5, "unit": "m"},
            "z": {"axis": "ABS_RY", "scale": -0.15, "offset": -1.0, "dead_band": 0.05, "unit": "m"}}}},
        "components": {"follower": {"source": "deltafmi.models:TargetFollower", "interface": "CS"}},
        "connections": [{"from": f"stick.{s}", "to": f"follower.target[{i}]"} for i, s in enumerate("xyz", 1)],
        "outputs": ["stick.*", "follower.r[*]", "follower.rd[*]"]})
    path = directory / f"follow_{len(list(directory.glob('follow_*')))}.yaml"
    path.write_text(text)   # JSON is YAML
    return path


def test_a_run_from_its_recording_repeats_the_run_bit_for_bit(tmp_path):
    import deltafmi
    recording = tmp_path / "recorded.jsonl"
    first = deltafmi.simulate(follower_scenario(tmp_path, SHIPPED, recording), output=tmp_path / "first.csv")
    again = deltafmi.simulate(follower_scenario(tmp_path, recording), output=tmp_path / "again.csv")
    shipped = read_session(SHIPPED)
    assert read_session(recording).events == [e for e in shipped.events if e[0] <= 6.0]
    assert first.names == again.names and len(first["time"]) == 6001
    for name in first.names:
        assert np.array_equal(first[name], again[name]), name
    assert np.ptp(first["follower.r[1]"]) > 0.1          # the stick moved the follower
