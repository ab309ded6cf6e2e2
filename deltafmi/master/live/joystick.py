"""A joystick or gamepad as a live source: Linux evdev axes, or a recorded session played back.

:class:`JoystickSource` reads the absolute axes (``EV_ABS``) of an input device through
python-evdev (``pip install 'deltafmi[joystick]'``), without blocking, at each communication
point, and maps each configured axis to a signal (:class:`AxisMap`): normalized to -1..1 from the
device's range, inverted if asked, a dead band around the centre, ``offset + scale * value``, then
a rate limit in signal units per simulated second.

Sessions (JSON Lines): a header line
``{"format": "deltafmi-joystick-session", "version": 1, "device": NAME, "axes": {"ABS_X": {"min": .., "max": ..,
"flat": .., "value": ..}, ...}}`` (``value``, the axis' position when the device was opened, is
optional: centre), then one line per axis event ``{"t": T, "code": "ABS_X", "value": V}``, in
order, where ``T`` is the simulation time of the poll that saw the event. Playback releases at
``poll(t)`` every event stamped ``<= t``; since a run polls at the same times, a run from a
recording repeats the live run's values bit for bit. ``record_to`` writes a session: of a device
(stamps: the polls' times), or of a playback (its events with their own stamps: the input's
events again).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Callable, Dict, List, Mapping, NamedTuple, Optional, Sequence, Tuple, Union

from deltafmi.errors import BadInput

__all__ = ["AxisMap", "AxisRange", "JoystickSource", "NoJoystick", "SESSION_FORMAT", "Session", "read_session",
           "session_header", "session_event"]

SESSION_FORMAT = "deltafmi-joystick-session"
SESSION_VERSION = 1
#: the most device events one poll reads (a flood waits for the next poll)
MAX_EVENTS_PER_POLL = 4096

Warn = Callable[[str], None]


class AxisRange(NamedTuple):
    """An absolute axis' range as its device reports it (evdev's absinfo)."""

    min: int
    max: int
    flat: int = 0
    value: Optional[int] = None     #: the position when the device was opened (None: centre)

    def normalized(self, raw: float) -> float:
        """``raw`` mapped linearly onto -1..1 (min -> -1, max -> 1), clipped there."""
        x = 2.0 * (raw - self.min) / (self.max - self.min) - 1.0
        return min(1.0, max(-1.0, x))

    def flat_fraction(self) -> float:
        """The device's flat (its centre noise band) as a fraction of the half-range."""
        return min(0.99, max(0.0, 2.0 * self.flat / (self.max - self.min)))


@dataclass(frozen=True)
class AxisMap:
    """How one axis becomes one signal.

    ``axis``: the evdev code name (ABS_X, ABS_RY, ...). The axis normalized to -1..1 (``invert``:
    negated) passes a dead band: deflections up to ``dead_band`` (a fraction of the half-range)
    read 0, larger ones are rescaled so the value is continuous at the band's edge and reaches
    +-1 at the ends; the signal is ``offset + scale * value``. ``dead_band`` None (the default):
    the device's own ``flat`` (what the kernel driver reports as the centre's noise band, and
    what joydev applies), 0 with a device that reports none; 0.0 turns it off. ``rate_limit``:
    the largest change of the signal per second of simulation time (None: none)."""

    axis: str
    scale: float = 1.0
    offset: float = 0.0
    dead_band: Optional[float] = None
    rate_limit: Optional[float] = None
    invert: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.axis, str) or not self.axis.startswith("ABS_"):
            raise BadInput(f"joystick axis {self.axis!r}: expected an evdev absolute axis (ABS_X, ABS_RY, ...)")
        for name in ("scale", "offset"):
            if not _finite(getattr(self, name)):
                raise BadInput(f"joystick axis {self.axis}: {name} = {getattr(self, name)!r} is not a finite number")
        if self.dead_band is not None and not (_finite(self.dead_band) and 0.0 <= self.dead_band < 1.0):
            raise BadInput(f"joystick axis {self.axis}: dead_band = {self.dead_band!r} must be in [0, 1)")
        if self.rate_limit is not None and not (_finite(self.rate_limit) and self.rate_limit > 0.0):
            raise BadInput(f"joystick axis {self.axis}: rate_limit = {self.rate_limit!r} must be > 0")

    def value(self, normalized: float, device_flat: float = 0.0) -> float:
        """The signal for an axis at ``normalized`` (-1..1), before the rate limit; ``device_flat``:
        the dead band when none is set."""
        x = -normalized if self.invert else normalized
        band = device_flat if self.dead_band is None else self.dead_band
        if abs(x) <= band:
            x = 0.0
        else:
            x = math.copysign((abs(x) - band) / (1.0 - band), x)
        return self.offset + self.scale * x


def _finite(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


# --- sessions ------------------------------------------------------------------------------------

class Session(NamedTuple):
    """A recorded session: the device's name, its axes' ranges, the events (t, code, value)."""

    device: str
    axes: Dict[str, AxisRange]
    events: List[Tuple[float, str, int]]


def session_header(device: str, axes: Mapping[str, AxisRange]) -> str:
    """The header line of a session (no newline)."""
    info = {}
    for code, a in axes.items():
        info[code] = {"min": a.min, "max": a.max, "flat": a.flat}
        if a.value is not None:
            info[code]["value"] = a.value
    return json.dumps({"format": SESSION_FORMAT, "version": SESSION_VERSION, "device": device, "axes": info})


def session_event(t: float, code: str, value: int) -> str:
    """One event line of a session (no newline)."""
    return json.dumps({"t": t, "code": code, "value": value}, separators=(",", ":"))


def _integer(x: Any) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _header(path: Path, line: str) -> Tuple[str, Dict[str, AxisRange]]:
    where = f"{path}:1"
    try:
        head = json.loads(line)
    except ValueError as exc:
        raise BadInput(f"{where}: the session header is not JSON ({exc.msg})") from None
    if not isinstance(head, dict) or head.get("format") != SESSION_FORMAT:
        raise BadInput(f"{where}: not a joystick session (the header needs \"format\": \"{SESSION_FORMAT}\")")
    if head.get("version") != SESSION_VERSION:
        raise BadInput(f"{where}: session version {head.get('version')!r} is not supported (this reads "
                       f"version {SESSION_VERSION})")
    axes = head.get("axes")
    if not isinstance(axes, dict) or not axes:
        raise BadInput(f"{where}: the header needs \"axes\": {{\"ABS_X\": {{\"min\": .., \"max\": ..}}, ...}}")
    ranges = {}
    for code, info in axes.items():
        if not isinstance(info, dict) or not _integer(info.get("min")) or not _integer(info.get("max")):
            raise BadInput(f"{where}: axis {code}: needs integer \"min\" and \"max\"")
        flat, value = info.get("flat", 0), info.get("value")
        if info["min"] >= info["max"] or not _integer(flat) or flat < 0:
            raise BadInput(f"{where}: axis {code}: needs min < max and an integer flat >= 0")
        if value is not None and not _integer(value):
            raise BadInput(f"{where}: axis {code}: value {value!r} is not an integer")
        ranges[code] = AxisRange(info["min"], info["max"], flat, value)
    return str(head.get("device", "")), ranges


def read_session(path: Union[str, Path]) -> Session:
    """Parse a session file; :class:`BadInput` naming ``file:line`` for what is wrong in it."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInput(f"joystick session {path}: cannot read it ({getattr(exc, 'strerror', None) or exc})") from None
    if not lines:
        raise BadInput(f"{path}:1: the session is empty (it needs a header line)")
    device, axes = _header(path, lines[0])
    events = []
    last = -math.inf
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        try:
            item = json.loads(line)
        except ValueError as exc:
            raise BadInput(f"{path}:{number}: not JSON ({exc.msg})") from None
        if not isinstance(item, dict):
            raise BadInput(f"{path}:{number}: expected {{\"t\": .., \"code\": .., \"value\": ..}}")
        t, code, value = item.get("t"), item.get("code"), item.get("value")
        if not _finite(t):
            raise BadInput(f"{path}:{number}: \"t\" = {t!r} is not a finite number")
        if t < last:
            raise BadInput(f"{path}:{number}: t = {t} goes back in time (the line before has t = {last})")
        if code not in axes:
            raise BadInput(f"{path}:{number}: axis {code!r} is not in the header's axes ({', '.join(axes)})")
        if not _integer(value):
            raise BadInput(f"{path}:{number}: \"value\" = {value!r} is not an integer")
        events.append((float(t), code, value))
        last = t
    return Session(device, axes, events)


# --- devices -------------------------------------------------------------------------------------

class NoJoystick(BadInput):
    """No device to read: python-evdev missing, or no (matching) device. ``reason`` says which."""

    def __init__(self, name: str, reason: str, advice: str) -> None:
        super().__init__(f"joystick source '{name}': {reason}{advice}")
        self.reason = reason


def _evdev(name: str) -> Any:
    try:
        import evdev
    except ImportError:
        raise NoJoystick(name, "python-evdev is not installed", ": pip install 'deltafmi[joystick]' (or pip install "
                         "evdev), or give a recorded session") from None
    return evdev


def _abs_axes(evdev: Any, device: Any) -> Dict[str, Tuple[int, AxisRange]]:
    """The absolute axes a device has, by code name: their codes and ranges."""
    axes = {}
    for code, info in device.capabilities(absinfo=True).get(evdev.ecodes.EV_ABS, []):
        names = evdev.ecodes.ABS.get(code, f"ABS_{code}")
        for name in names if isinstance(names, (list, tuple)) else (names,):
            axes[name] = (code, AxisRange(info.min, info.max, info.flat, info.value))
    return axes


def open_device(name: str, device: str, wanted: Sequence[str]) -> Tuple[Any, Dict[str, Tuple[int, AxisRange]]]:
    """The evdev device ``device`` (a path, or "auto": the first /dev/input/event* that has every
    axis in ``wanted``) and its axes (name -> code, range); :class:`BadInput` saying what to
    install, which devices exist or which axes are missing."""
    evdev = _evdev(name)
    need = f"axes {', '.join(wanted)}"
    if device != "auto":
        try:
            dev = evdev.InputDevice(device)
        except OSError as exc:
            raise BadInput(f"joystick source '{name}': cannot open {device}: {exc.strerror or exc}") from None
        axes = _abs_axes(evdev, dev)
        missing = [a for a in wanted if a not in axes]
        if missing:
            dev.close()
            raise BadInput(f"joystick source '{name}': {device} ({dev.name}) has no {', '.join(missing)} "
                           f"(its axes: {', '.join(axes) or 'none'})")
        return dev, axes
    seen = []
    for path in sorted(evdev.list_devices(), key=_event_number):
        try:
            dev = evdev.InputDevice(path)
        except OSError as exc:
            seen.append(f"{path} (not readable: {exc.strerror or exc})")
            continue
        axes = _abs_axes(evdev, dev)
        if all(a in axes for a in wanted):
            return dev, axes
        seen.append(f"{path} '{dev.name}'")
        dev.close()
    found = "; ".join(seen) if seen else "no input devices in /dev/input"
    raise NoJoystick(name, f"no input device has {need} (found: {found})",
                     "; give device: /dev/input/eventN, or a recorded session")


def _event_number(path: str) -> Tuple[int, str]:
    tail = path.rsplit("event", 1)[-1]
    return (int(tail), path) if tail.isdigit() else (1 << 30, path)


# --- the source ----------------------------------------------------------------------------------

class JoystickSource:
    """A live source whose ``signals`` (name -> :class:`AxisMap`) come from a joystick's axes.

    ``device``: "auto" (the first input device with every configured axis), a path
    (/dev/input/eventN) or None (with no session: "auto"). ``session``: a recorded session played
    instead of a device when ``device`` is None, or when ``device`` is "auto" and no device (or no
    python-evdev) is found.
    ``record_to``: write the events read to this session file. The first poll reports every
    signal (the axes' positions when opened, centred for a session without them); later polls
    report the signals whose value changed, a rate-limited one also while it ramps. A device
    that disappears mid-run warns once and holds the last values."""

    def __init__(self, name: str, signals: Mapping[str, AxisMap], device: Optional[str] = "auto",
                 session: Optional[Union[str, Path]] = None, record_to: Optional[Union[str, Path]] = None) -> None:
        self.name = name
        self.maps = {s: m if isinstance(m, AxisMap) else AxisMap(**m) for s, m in signals.items()}
        self.signals: Tuple[str, ...] = tuple(self.maps)
        self.session = None if session is None else Path(session)
        self.device = "auto" if device is None and session is None else device
        self.record_to = None if record_to is None else Path(record_to)
        self.wanted = tuple(dict.fromkeys(m.axis for m in self.maps.values()))
        self.playing: Optional[Session] = None
        self._dev: Any = None
        self._codes: Dict[int, str] = {}
        self._ranges: Dict[str, AxisRange] = {}
        self._raw: Dict[str, float] = {}
        self._out: Dict[str, float] = {}
        self._target: Dict[str, float] = {}
        self._next = 0
        self._dropping = False
        self._t: Optional[float] = None
        self._record: Optional[IO[str]] = None
        self._warn: Warn = lambda text: None
        self._counts = {"events": 0, "dropped": 0, "lost": 0}

    # --- opening ----------------------------------------------------------------------------------
    def open(self, warn: Warn) -> None:
        """Open the device (or read the session) and the recording."""
        self._warn = warn
        if self.device is not None and (self.session is None or self.device != "auto"):
            self._open_device()
        elif self.device == "auto":
            try:
                self._open_device()
            except NoJoystick as exc:
                warn(f"joystick source '{self.name}': {exc.reason}: playing the recorded session {self.session}")
                self._open_session()
        else:
            self._open_session()
        if self.record_to is not None:
            try:
                self._record = open(self.record_to, "w", encoding="utf-8")
            except OSError as exc:
                self.close()
                raise BadInput(f"joystick source '{self.name}': cannot write the session {self.record_to}: "
                               f"{exc.strerror or exc}") from None
            device = self.playing.device if self.playing is not None else self._dev.name
            self._record.write(session_header(device, {a: self._ranges[a] for a in self.wanted}) + "\n")

    def _open_device(self) -> None:
        self._dev, axes = open_device(self.name, self.device, self.wanted)
        self._codes = {axes[a][0]: a for a in self.wanted}
        self._ranges = {a: axes[a][1] for a in self.wanted}
        self._start()

    def _open_session(self) -> None:
        self.playing = read_session(self.session)
        missing = [a for a in self.wanted if a not in self.playing.axes]
        if missing:
            raise BadInput(f"joystick source '{self.name}': the session {self.session} has no {', '.join(missing)} "
                           f"(its axes: {', '.join(self.playing.axes)})")
        self._ranges = self.playing.axes
        self._start()

    def _start(self) -> None:
        for axis in self.wanted:
            r = self._ranges[axis]
            self._raw[axis] = 0.5 * (r.min + r.max) if r.value is None else r.value
        for signal in self.signals:
            self._target[signal] = self._mapped(signal)

    def _mapped(self, signal: str) -> float:
        m = self.maps[signal]
        r = self._ranges[m.axis]
        return m.value(r.normalized(self._raw[m.axis]), r.flat_fraction())

    # --- polling ----------------------------------------------------------------------------------
    def poll(self, t: float) -> Optional[Dict[str, float]]:
        """The signals changed since the last poll, None when none did (see the class)."""
        changed_axes = self._read_playback(t) if self.playing is not None else self._read_device(t)
        if changed_axes and self._record is not None:
            self._record.flush()  # a run killed later keeps what was recorded
        for signal, m in self.maps.items():
            if m.axis in changed_axes:
                self._target[signal] = self._mapped(signal)
        first = self._t is None
        dt = 0.0 if first else max(0.0, t - self._t)
        self._t = t
        news = {}
        for signal, target in self._target.items():
            old = self._out.get(signal)
            limit = self.maps[signal].rate_limit
            if old is None:
                new = target
            elif limit is not None:
                step = limit * dt
                new = min(max(target, old - step), old + step)
            else:
                new = target
            if first or new != old:
                self._out[signal] = news[signal] = new
        return news or None

    def _read_playback(self, t: float) -> set:
        events = self.playing.events
        changed = set()
        i = self._next
        while i < len(events) and events[i][0] <= t:
            stamp, code, value = events[i]
            if code in self._raw:
                self._raw[code] = value
                changed.add(code)
                self._counts["events"] += 1
                self._write(stamp, code, value)
            i += 1
        self._next = i
        return changed

    def _read_device(self, t: float) -> set:
        changed: set = set()
        if self._dev is None:
            return changed
        batch: list = []
        lost = None
        try:
            while len(batch) < MAX_EVENTS_PER_POLL:  # each read() takes at most 64 events
                batch.extend(self._dev.read())
        except BlockingIOError:
            pass
        except OSError as exc:
            lost = exc
        ecodes = _evdev(self.name).ecodes
        for event in batch:
            if event.type == ecodes.EV_SYN and event.code == ecodes.SYN_DROPPED:
                self._dropping = True
            elif self._dropping:  # the kernel's rule: skip up to the next report, then read the state
                if event.type == ecodes.EV_SYN and event.code == ecodes.SYN_REPORT:
                    self._dropping = False
                    changed |= self._resync(t)
            elif event.type == ecodes.EV_ABS and event.code in self._codes:
                axis = self._codes[event.code]
                self._raw[axis] = event.value
                changed.add(axis)
                self._counts["events"] += 1
                self._write(t, axis, event.value)
        if lost is not None:
            self._lose(t, lost)
        return changed

    def _resync(self, t: float) -> set:
        """After the kernel dropped events (SYN_DROPPED): the axes' current positions, read again."""
        self._counts["dropped"] += 1
        if self._counts["dropped"] == 1:
            self._warn(f"joystick source '{self.name}': the device's event buffer overflowed at t = {t:.6g} s; "
                       "positions read again")
        changed = set()
        for code, axis in self._codes.items():
            try:
                value = self._dev.absinfo(code).value
            except OSError:
                continue
            if value != self._raw[axis]:
                self._raw[axis] = value
                changed.add(axis)
                self._write(t, axis, value)
        return changed

    def _lose(self, t: float, exc: OSError) -> None:
        self._counts["lost"] = 1
        self._warn(f"joystick source '{self.name}': the device is gone at t = {t:.6g} s "
                   f"({exc.strerror or exc}); holding the last values")
        self._close_device()

    def _write(self, stamp: float, axis: str, value: int) -> None:
        if self._record is not None:
            self._record.write(session_event(stamp, axis, value) + "\n")

    # --- the rest ---------------------------------------------------------------------------------
    def counters(self) -> Dict[str, int]:
        """events: axis events applied; dropped: kernel buffer overflows; lost: 1 when the device went."""
        return dict(self._counts)

    def _close_device(self) -> None:
        dev, self._dev = self._dev, None
        if dev is not None:
            try:
                dev.close()
            except OSError:
                pass

    def close(self) -> None:
        """Close the device and the recording (twice is fine)."""
        self._close_device()
        record, self._record = self._record, None
        if record is not None:
            record.close()
