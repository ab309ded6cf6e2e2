"""The C loop's reader of live UDP inputs (deltafmi/master/live/native/udp_reader.c) against the
Python reader (deltafmi.master.live.udp.UdpSource), over real sockets on 127.0.0.1.

The same datagrams go to two sources: one read by Python at every point, the other by the C reader
(called as the C loop calls it after each point's release), which hands a point to Python where
it meets a datagram it leaves to Python. At every point both units must hold the same values,
and at the end both sources must have counted and warned alike: the Python reader is the
independent formulation of the rules (docs/realtime.md), the C reader a second implementation of
their common path."""
from __future__ import annotations

import ctypes
import json
import socket
import struct
import time
from types import SimpleNamespace

import numpy as np
import pytest

from deltafmi.master.live.input_units import LiveInputUnit
from deltafmi.master.live.native_udp import NativeReaders
from deltafmi.master.live.udp import UdpSource


def dfmi(values: dict, t: float, seq: int = 0) -> bytes:
    """A DFMI v1 binary datagram, by the byte table."""
    out = struct.pack("<4sBBHId", b"DFMI", 1, 1, len(values), seq, t)
    for name, value in values.items():
        raw = name.encode()
        out += struct.pack(f"<B{len(raw)}sd", len(raw), raw, value)
    return out


def dfmi_json(values: dict, t: float, seq: int = 0) -> bytes:
    return json.dumps({"format": "dfmi", "version": 1, "t": t, "seq": seq, "signals": values}).encode()


class Pair:
    """Two sources of the same signals, their units (values on a bus of their own), one read by C."""

    def __init__(self, signals, timeout=None, **options) -> None:
        self.warnings = {"python": [], "c": []}
        self.units, self.buses = {}, {}
        for who in ("python", "c"):
            source = UdpSource("cmd", signals, **options)
            unit = LiveInputUnit(SimpleNamespace(name="cmd"), source, [0.0] * len(signals), timeout,
                                 self.warnings[who].append)
            unit.instantiate(0.0, 1.0)
            bus = np.full(len(signals) + 2, -1.0)
            unit.wire_outputs("Real", list(range(len(signals))), bus, 1)
            unit.fetch()  # the start values on the bus, as initialization puts them
            self.units[who], self.buses[who] = unit, bus
        self.readers = NativeReaders([(self.units["c"], self.units["c"].source)])
        self.sample = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double)(self.readers.function)
        self.handed = 0

    def send(self, sock: socket.socket, data: bytes) -> None:
        for unit in self.units.values():
            sock.sendto(data, ("127.0.0.1", unit.source.port))

    def point(self, t: float) -> None:
        """Both sources sampled at point t (the C one as the C loop does); their values must agree."""
        time.sleep(0.01)  # loopback delivers within sendto; a margin on a loaded machine
        self.units["python"].sample(t)
        if self.sample(self.readers.context, t):
            self.handed += 1
            self.units["c"].sample(t)
            self.readers.before_c()
        python, c = self.units["python"], self.units["c"]
        assert c.values.tolist() == python.values.tolist(), t
        assert self.buses["c"].tolist() == self.buses["python"].tolist(), t

    def close(self) -> dict:
        self.readers.close()
        counts = {who: unit.source.counters() for who, unit in self.units.items()}
        for unit in self.units.values():
            unit.close()
        return counts


@pytest.fixture
def senders():
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2)]
    for sock in socks:
        sock.bind(("127.0.0.1", 0))
    yield socks
    for sock in socks:
        sock.close()


def test_the_c_reader_takes_what_python_would(senders):
    """Two senders, binary and JSON DFMI, the newest winning per point, a malformed datagram, a
    stale one, a restarted sender, an undeclared name, a name twice, NaN: the same values at every
    point, the same counters and warnings; the common datagrams taken in C without Python."""
    a, b = senders
    pair = Pair(["x", "y", "z"])
    script = [
        [(a, dfmi({"x": 1.0}, 0.1, 1))],                                  # a new sender: C
        [(a, dfmi({"x": 2.0, "y": 3.0}, 0.2, 2)), (a, dfmi({"y": 4.0}, 0.3, 3))],   # newest wins, in C
        [(a, dfmi({"z": 5.0}, 0.4, 4))],                                  # C
        [(a, dfmi({"x": 6.0}, 0.35, 5)), (a, dfmi({"x": 7.0}, 0.5, 6))],  # stale (Python), and after it
        [(b, dfmi({"x": 8.0}, 100.0, 1)), (a, dfmi({"y": 9.0}, 0.6, 7))],  # a second sender, its own clock
        [(b, dfmi({"x": 10.0}, 100.1, 2)), (a, dfmi({"y": 11.0}, 0.7, 8))],  # both known: C
        [(a, b"DFMI\x02\x01" + bytes(14)), (a, dfmi({"y": 12.0}, 0.8, 9))],  # malformed, then a good one
        [(a, dfmi({"x": 13.0, "nope": 1.0}, 0.9, 10))],                    # an undeclared name
        [(a, dfmi_json({"z": 14.0}, 1.0, 11))],                            # JSON
        [(a, dfmi({"x": float("nan")}, 1.1, 12)), (a, dfmi({"x": 15.0, "x ": 1.0}, 1.1, 13))],  # NaN; undeclared
        [(a, dfmi({"x": 16.0}, 0.05, 200))],                               # time back, seq on: stale
        [(a, dfmi({"x": 17.0}, 0.01, 0))],                                 # seq back by 13 only: stale
        [(a, dfmi({"z": 18.0}, 2.0, 20)), (a, dfmi({"z": 19.0}, 2.1, 21)), (a, dfmi({"z": 20.0}, 2.2, 22))],  # C
        [],                                                                # nothing new
        [(a, dfmi({"x": 21.0}, 0.0, 2 ** 32 - 100))],                      # time and seq back by 122: a restart
        [(a, dfmi({"x": 22.0}, 0.1, 2 ** 32 - 99))],                       # C again
    ]
    for k, datagrams in enumerate(script, 1):
        for sock, data in datagrams:
            pair.send(sock, data)
        pair.point(k * 1e-3)
    counts = pair.close()
    assert counts["c"] == counts["python"], counts
    assert pair.warnings["c"] == pair.warnings["python"]
    assert counts["c"]["malformed"] == 2 and counts["c"]["stale"] >= 2 and counts["c"]["restarts"] == 1
    assert pair.units["c"].values.tolist() == [22.0, 12.0, 20.0]
    # Python had to look at: the stale, malformed, undeclared, JSON, NaN datagrams, the restart
    assert 6 <= pair.handed <= 10
    taken_in_c = pair.readers.readers[0].counters()["accepted"]
    assert taken_in_c >= 10


def test_packed_doubles_and_a_sender_filter_in_c(senders):
    """format: doubles, float32 big-endian, one host allowed: the C reader takes the packed values
    itself (exactly what float32 holds), hands a datagram of the wrong length to Python and counts
    the others' datagrams as foreign, as Python does."""
    a, _ = senders
    pair = Pair(["p", "q"], format="doubles", dtype="float32", byte_order="big", sender="127.0.0.1")
    pair.send(a, struct.pack(">ff", 1.5, -2.25))
    pair.point(1e-3)
    assert pair.handed == 0 and pair.units["c"].values.tolist() == [1.5, -2.25]
    pair.send(a, struct.pack(">f", 7.0))
    pair.send(a, struct.pack(">ff", 0.1, 3.0))
    pair.point(2e-3)
    assert pair.handed == 1 and pair.units["c"].values.tolist() == [float(np.float32(0.1)), 3.0]
    counts = pair.close()
    assert counts["c"] == counts["python"] and counts["c"]["malformed"] == 1 and counts["c"]["accepted"] == 2


def test_silence_and_news_after_it_are_handed_to_python(senders):
    """timeout 0.05 s: no news for longer hands the point to Python, which reports the silence
    once; news after it hands the point over again ("data again"); in between C reads alone."""
    a, _ = senders
    pair = Pair(["x"], timeout=0.05)
    pair.send(a, dfmi({"x": 1.0}, 0.1, 1))
    pair.point(1e-3)
    handed = pair.handed
    time.sleep(0.08)
    pair.point(2e-3)  # silent now
    assert pair.handed == handed + 1
    assert any("nothing received" in w for w in pair.warnings["c"])
    pair.point(3e-3)  # still silent: C alone
    assert pair.handed == handed + 1
    pair.send(a, dfmi({"x": 2.0}, 0.2, 2))
    pair.point(4e-3)
    assert pair.handed == handed + 2 and any("data again" in w for w in pair.warnings["c"])
    assert pair.units["c"].silences == pair.units["python"].silences == [2e-3]
    pair.close()
