"""Write scenarios/joystick_session.jsonl: a synthesized 20 s gamepad session.

A person moves the left stick (ABS_X, ABS_Y) and the right stick's vertical axis (ABS_RY):
minimum-jerk excursions, holds with a little hand tremor, a circle, releases that spring back to
the centre. The pad is modelled on a wired XInput pad: 16-bit axes (-32768..32767, flat 128)
whose values come from a 10-bit converter (steps of 64 counts) with a little electrical noise,
sent in reports every 8 ms (125 Hz) with USB jitter; evdev emits an event only for an axis whose
value changed. Each event is stamped with the simulation time of the 1 ms communication point
that would first see it (``k * 0.001``, as the master computes its points). Deterministic (seed 28).

    python tools/make_joystick_session.py [OUT]
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from deltafmi.master.live.joystick import AxisRange, session_event, session_header

OUT = Path(__file__).resolve().parents[1] / "scenarios" / "joystick_session.jsonl"
AXES = ("ABS_X", "ABS_Y", "ABS_RY")
RANGE = AxisRange(-32768, 32767, 128)
REPORT, JITTER, POLL, DURATION = 8e-3, 0.25e-3, 1e-3, 20.0
DEVICE = ("synthesized by tools/make_joystick_session.py (seed 28): a wired XInput-style gamepad, "
          "left stick x/y and right stick vertical; not a recording of a real device")

#: (start s, duration s, (x, y, ry) normalized at the end; None: spring back to centre when let go)
MOVES = [
    (1.0, 0.6, (0.8, 0.0, 0.0)),
    (2.5, 0.7, (0.6, 0.7, 0.0)),
    (4.0, 0.9, (-0.5, 0.6, 0.0)),
    (5.5, 0.8, (-0.7, -0.5, 0.0)),
    (7.0, None, (0.0, 0.0, 0.0)),
    (8.0, 0.7, (0.0, 0.0, 0.9)),
    (9.0, 0.9, (0.0, 0.0, -0.8)),
    (10.2, None, (0.0, 0.0, 0.0)),
    (13.2, 0.8, (0.4, -0.6, 0.5)),
    (17.0, None, (0.0, 0.0, 0.0)),
]
CIRCLE = (10.5, 13.0, 0.6)   # start, end, radius of a counter-clockwise circle of the left stick


def minimum_jerk(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return s ** 3 * (10 - 15 * s + 6 * s ** 2)


def hand(t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The sticks' deflections (n, 3), normalized, at times ``t``."""
    pos = np.zeros((len(t), 3))
    held = np.zeros(3)
    released = np.ones(len(t), dtype=bool)
    for start, duration, end in MOVES:
        end = np.asarray(end, float)
        if duration is None:  # let go: the spring returns the stick in ~0.12 s, slightly underdamped
            tau = np.maximum(t - start, 0.0)
            shape = np.exp(-tau / 0.03) * np.cos(2 * math.pi * tau / 0.25)
            after = t >= start
            pos[after] = held * shape[after, None]
            released[after] = True
        else:
            after = t >= start
            pos[after] = held + (end - held) * minimum_jerk((t[after] - start) / duration)[:, None]
            released[after] = False
        held = end
    c0, c1, radius = CIRCLE
    on = (t >= c0) & (t < c1)
    ramp = minimum_jerk((t[on] - c0) / 0.4) * minimum_jerk((c1 - t[on]) / 0.4)
    angle = 2 * math.pi * (t[on] - c0) / (c1 - c0)
    pos[on, 0] += radius * ramp * np.sin(angle)
    pos[on, 1] += radius * ramp * (1 - np.cos(angle)) * 0.5
    released[on] = False
    # hand tremor (8-12 Hz, ~0.4 %) while a thumb is on a stick
    tremor = sum(0.0015 * np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi))
                 for f in (8.3, 9.7, 11.9))
    pos += np.where(released[:, None], 0.0, tremor[:, None] * np.array([1.0, 0.8, 0.6]))
    return np.clip(pos, -1.0, 1.0)


def counts(x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """16-bit axis values of normalized deflections through a 10-bit converter with noise."""
    code = np.rint((x + 1.0) / 2.0 * 1023 + rng.normal(0.0, 0.35, x.shape))
    code = np.clip(code, 0, 1023)
    return np.clip(np.rint(code * 64.06 - 32768), RANGE.min, RANGE.max).astype(int)


def main(out: Path = OUT) -> int:
    rng = np.random.default_rng(28)
    reports = np.arange(int(DURATION / REPORT)) * REPORT + rng.uniform(-JITTER, JITTER, int(DURATION / REPORT))
    reports = np.clip(reports, 0.0, DURATION)
    values = counts(hand(reports, rng), rng)
    centre = counts(np.zeros(3), rng)
    lines = [session_header(DEVICE, {a: RANGE._replace(value=int(v)) for a, v in zip(AXES, centre)})]
    last = centre.copy()
    for tr, row in zip(reports, values):
        k = math.ceil(tr / POLL - 1e-9)
        stamp = 0.0 + k * POLL   # the master's point start + k h
        for i, axis in enumerate(AXES):
            if row[i] != last[i]:
                lines.append(session_event(stamp, axis, int(row[i])))
                last[i] = row[i]
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"{out}: {len(lines) - 1} events over {DURATION:g} s, {out.stat().st_size / 1000:.0f} kB")
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1]) if len(sys.argv) > 1 else OUT))
