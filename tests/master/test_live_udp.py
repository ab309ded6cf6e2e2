"""UDP live inputs and outputs (deltafmi.master.live.udp) over real sockets on 127.0.0.1.

The senders and receivers on the other side are plain sockets, and what they send or expect is
written out with struct and json, field by field, as docs/realtime.md documents it."""
from __future__ import annotations

import json
import math
import socket
import struct
import time

import numpy as np
import pytest

from deltafmi.master.live.udp import UdpSink, UdpSource, parse_host_port
from deltafmi.errors import BadInput


def dfmi(values: dict, t: float, seq: int = 0) -> bytes:
    """A DFMI v1 binary datagram, by the byte table."""
    out = struct.pack("<4sBBHId", b"DFMI", 1, 1, len(values), seq, t)
    for name, value in values.items():
        raw = name.encode()
        out += struct.pack(f"<B{len(raw)}sd", len(raw), raw, value)
    return out


def dfmi_json(values: dict, t: float) -> bytes:
    return json.dumps({"format": "dfmi", "version": 1, "t": t, "signals": values}).encode()


def bound() -> socket.socket:
    """A plain UDP socket on 127.0.0.1, on a free port."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    return sock


@pytest.fixture
def sender():
    with bound() as sock:
        yield sock


@pytest.fixture
def receiver():
    with bound() as sock:
        sock.settimeout(60.0)  # a hang guard
        yield sock


def opened(source: UdpSource, warnings: list) -> UdpSource:
    source.open(warnings.append)
    assert source.port > 0
    return source


def drain(source: UdpSource, received: int) -> dict:
    """Polls until ``received`` datagrams arrived (or 60 s passed: a hang guard); every update merged, newest
    last."""
    merged: dict = {}
    deadline = time.monotonic() + 60.0
    while source.counters()["received"] < received and time.monotonic() < deadline:
        merged.update(source.poll(0.0) or {})
    merged.update(source.poll(0.0) or {})
    return merged


def test_loopback_keeps_the_newest_value_and_counts_the_rest(sender):
    warnings: list = []
    source = opened(UdpSource("cmd", ["x", "y", "θ"]), warnings)
    to = ("127.0.0.1", source.port)
    sent = [dfmi({"x": 1.0, "θ": 0.5}, 1.0, 1),
            b"DFMI\x02" + bytes(16),                            # malformed: version 2
            dfmi({"y": 2.0, "w": 9.0}, 2.0, 2),                 # w: unknown, y used
            dfmi({"x": 99.0}, 1.5, 3),                          # stale: 1.5 < 2.0 already received
            dfmi({"x": 3.0}, 2.0, 4),                           # same time, later arrival: wins
            dfmi({"x": 1.0, "y": math.nan}, 3.0, 5),            # malformed: NaN
            dfmi({"w": 8.0}, 2.5, 6),                           # unknown again: counted, warned once
            dfmi_json({"y": 4.0, "θ": -0.25}, 3.0)]
    for data in sent:
        sender.sendto(data, to)
    assert drain(source, len(sent)) == {"x": 3.0, "y": 4.0, "θ": -0.25}
    assert source.counters() == {"received": 8, "accepted": 5, "malformed": 2, "stale": 1, "restarts": 0,
                                 "unknown": 2, "foreign": 0, "overflow": 0}
    assert source.poll(0.0) is None  # nothing new
    text = "\n".join(warnings)
    assert len(warnings) == 4, text
    assert f"dropped a malformed datagram from 127.0.0.1:{sender.getsockname()[1]}: version 2 (this deltafmi reads 1)" in text
    assert "signal 'y' is nan" in text and "ignoring signal 'w'" in text and text.count("'w'") == 1
    assert "stale datagram" in text and "1.5 s is before 2 s" in text
    source.close()
    source.close()  # idempotent
    with pytest.raises(RuntimeError, match="poll before open"):
        source.poll(0.0)


def test_a_restarted_sender_is_heard_again_a_reordered_datagram_is_stale(sender):
    """A device that reboots keeps its port but starts its clock and its sequence numbers again:
    its data is taken again (one warning); a datagram the network delayed is a few numbers behind
    and stays stale."""
    warnings: list = []
    source = opened(UdpSource("cmd", ["x"]), warnings)
    to = ("127.0.0.1", source.port)
    for n in range(100):
        sender.sendto(dfmi({"x": float(n)}, n * 0.01, n), to)
    assert drain(source, 100) == {"x": 99.0}
    sender.sendto(dfmi({"x": -1.0}, 0.95, 95), to)        # late by 5 numbers: stale
    assert drain(source, 101) == {} and source.counters()["stale"] == 1
    for n in range(3):                                     # rebooted: time and sequence from 0
        sender.sendto(dfmi({"x": 1000.0 + n}, n * 0.01, n), to)
    assert drain(source, 104) == {"x": 1002.0}
    counts = source.counters()
    assert counts["restarts"] == 1 and counts["stale"] == 1 and counts["accepted"] == 103
    assert sum("restarted" in w for w in warnings) == 1
    source.close()


def test_timestamps_are_compared_per_sender(sender):
    """A second program (another port) has its own clock: its earlier times are not stale."""
    source = opened(UdpSource("cmd", ["x", "y"]), [])
    other = bound()
    try:
        sender.sendto(dfmi({"x": 1.0}, 100.0), ("127.0.0.1", source.port))
        assert drain(source, 1) == {"x": 1.0}
        other.sendto(dfmi({"x": 2.0, "y": 5.0}, 0.1), ("127.0.0.1", source.port))
        assert drain(source, 2) == {"x": 2.0, "y": 5.0}
        sender.sendto(dfmi({"y": 7.0}, 99.0), ("127.0.0.1", source.port))  # stale for its own sender
        assert drain(source, 3) == {}
        assert source.counters()["stale"] == 1 and source.counters()["accepted"] == 2
    finally:
        other.close()
        source.close()


def test_malformed_warnings_stop_after_five(sender):
    warnings: list = []
    source = opened(UdpSource("cmd", ["x"]), warnings)
    for k in range(8):
        sender.sendto(b"garbage %d" % k, ("127.0.0.1", source.port))
    sender.sendto(dfmi({"x": -4.5}, 0.0), ("127.0.0.1", source.port))
    assert drain(source, 9) == {"x": -4.5}
    assert source.counters()["malformed"] == 8 and source.counters()["accepted"] == 1
    assert len(warnings) == 5 and all("bad magic b'garb'" in w for w in warnings)
    assert warnings[-1].endswith("; further malformed datagrams are counted only")
    source.close()


def test_packed_doubles_in_declared_order(sender):
    """What a Simulink UDP Send block sends: big-endian float32 values, no header."""
    source = opened(UdpSource("sim", ["a", "b", "c"], format="doubles", dtype="float32", byte_order="big"), [])
    to = ("127.0.0.1", source.port)
    sender.sendto(struct.pack(">3f", 0.1, -2.0, 3e5), to)
    sender.sendto(struct.pack(">4f", 1, 2, 3, 4), to)  # malformed: wrong length
    assert drain(source, 2) == {"a": float(np.float32(0.1)), "b": -2.0, "c": 3e5}
    assert source.counters()["malformed"] == 1
    sender.sendto(struct.pack(">3f", 7, 8, 9), to)
    assert drain(source, 3) == {"a": 7.0, "b": 8.0, "c": 9.0}
    source.close()


def test_sender_filter_counts_other_hosts_as_foreign(sender):
    accepting = opened(UdpSource("a", ["x"], sender="127.0.0.1"), [])
    refusing = opened(UdpSource("b", ["x"], sender="127.0.0.2"), [])
    for source in (accepting, refusing):
        sender.sendto(dfmi({"x": 1.25}, 0.0), ("127.0.0.1", source.port))
    assert drain(accepting, 1) == {"x": 1.25}
    assert drain(refusing, 1) == {}
    assert refusing.counters()["foreign"] == 1 and refusing.counters()["accepted"] == 0
    accepting.close()
    refusing.close()


def test_a_flood_is_read_a_bounded_number_per_poll(sender):
    """50 000 datagrams: one poll reads max_per_poll of them, oldest first; every datagram is
    either read or counted as dropped by the OS (its receive buffer full)."""
    warnings: list = []
    source = opened(UdpSource("cmd", ["x"], max_per_poll=100), warnings)
    to = ("127.0.0.1", source.port)
    for k in range(50000):
        sender.sendto(dfmi({"x": float(k)}, float(k)), to)
    assert source.poll(0.0) == {"x": 99.0}
    assert source.counters()["received"] == 100
    assert len(warnings) == 1 and "100 or more datagrams waiting" in warnings[0]
    polls = 1
    while source.poll(0.0) is not None:
        polls += 1
    received = source.counters()["received"]
    assert polls == math.ceil(received / 100) and received < 50000
    sender.sendto(dfmi({"x": -1.0}, 1e6), to)  # carries the OS's count of the datagrams it dropped
    assert drain(source, received + 1) == {"x": -1.0}
    counts = source.counters()
    assert counts["received"] + counts["overflow"] == 50001
    assert counts["accepted"] == counts["received"] and counts["stale"] == 0
    source.close()


def test_sink_sends_what_the_documented_formats_say(receiver):
    host, port = receiver.getsockname()
    warnings: list = []
    sink = UdpSink(["plant.z[1]", "φ"], host, port)
    sink.open(warnings.append)
    assert sink.send(0.5, [0.1, -1.0 / 3.0]) and sink.send(1.0, {"φ": 2.0, "plant.z[1]": -0.0})
    for seq, t, values in [(0, 0.5, (0.1, -1.0 / 3.0)), (1, 1.0, (-0.0, 2.0))]:
        data = receiver.recv(65536)
        assert data == dfmi(dict(zip(["plant.z[1]", "φ"], values)), t, seq)
    sink.close()

    sink = UdpSink(["x"], host, port, format="dfmi-json")
    sink.open(warnings.append)
    sink.send(0.25, [0.1])
    assert json.loads(receiver.recv(65536)) == {"format": "dfmi", "version": 1, "t": 0.25, "seq": 0, "signals": {"x": 0.1}}
    sink.close()

    sink = UdpSink(["a", "b"], host, port, format="doubles", dtype="float32", byte_order="big")
    sink.open(warnings.append)
    sink.send(0.0, [1.0, -2.0])
    assert receiver.recv(65536) == b"\x3f\x80\x00\x00\xc0\x00\x00\x00"
    assert sink.counters() == {"sent": 1, "failed": 0} and warnings == []
    sink.close()


def test_sink_to_source_round_trip_is_bit_exact():
    values = [0.1, 5e-324, -1.7976931348623157e308]
    source = opened(UdpSource("in", ["a", "b", "c"]), [])
    sink = UdpSink(["a", "b", "c"], "127.0.0.1", source.port)
    sink.open([].append)
    sink.send(0.001, values)
    got = drain(source, 1)
    assert [struct.pack("<d", got[n]) for n in "abc"] == [struct.pack("<d", v) for v in values]
    sink.close()
    source.close()


def test_sink_without_listener_counts_failures_and_never_raises():
    with bound() as probe:
        port = probe.getsockname()[1]
    # nobody listens on this port now
    warnings: list = []
    sink = UdpSink(["x"], "127.0.0.1", port)
    sink.open(warnings.append)
    results = [sink.send(k * 0.01, [float(k)]) for k in range(20)]
    assert sink.send(1.0, [math.nan]) is False  # cannot be encoded: counted too
    counts = sink.counters()
    assert counts["sent"] + counts["failed"] == 21 and counts["failed"] >= 2
    assert results.count(False) == counts["failed"] - 1
    assert len(warnings) == 1 and "Connection refused (nobody listening?)" in warnings[0]
    assert f"UDP stream to 127.0.0.1:{port}" in warnings[0]
    sink.close()
    sink.close()


def test_bind_errors_name_host_and_port():
    with bound() as taken:
        port = taken.getsockname()[1]
        with pytest.raises(BadInput, match=rf"^live input 'cmd': cannot listen on UDP 127\.0\.0\.1:{port}: Address already in use$"):
            UdpSource("cmd", ["x"], port=port).open(print)
    with pytest.raises(BadInput, match=r"^live input 'cmd': cannot listen on UDP 192\.0\.2\.1:0: Cannot assign requested address$"):
        UdpSource("cmd", ["x"], host="192.0.2.1").open(print)  # TEST-NET: not an address of this machine


@pytest.mark.parametrize("make, message", [
    (lambda: UdpSource("cmd", ["x"], port=70000), "live input 'cmd' udp: port 70000 is not in 0..65535"),
    (lambda: UdpSource("cmd", ["x"], format="xml"), "live input 'cmd': format 'xml': expected one of dfmi, doubles"),
    (lambda: UdpSource("cmd", ["x"], format="doubles", dtype="int8"), "live input 'cmd': dtype 'int8'"),
    (lambda: UdpSource("cmd", []), "live input 'cmd': no signals"),
    (lambda: UdpSink(["x"], "127.0.0.1", 0), "UDP stream to 127.0.0.1:0: port 0 is not in 1..65535"),
    (lambda: UdpSink(["x"], "127.0.0.1", 9, format="csv"), "format 'csv': expected one of dfmi, dfmi-json, doubles"),
    (lambda: UdpSink(["x", "x"], "127.0.0.1", 9), "signal 'x' is named twice"),
    (lambda: parse_host_port("localhost", "stream"), "stream 'localhost': expected host:port, e.g. 127.0.0.1:25000"),
    (lambda: parse_host_port("127.0.0.1:port", "stream"), "stream '127.0.0.1:port': expected host:port"),
    (lambda: parse_host_port(":25000", "stream"), "stream ':25000': expected host:port"),
    (lambda: parse_host_port("127.0.0.1:65536", "stream"), "stream '127.0.0.1:65536': port 65536 is not in 1..65535"),
])
def test_configuration_errors_are_one_line(make, message):
    with pytest.raises(BadInput) as error:
        make()
    assert message in error.value.format_message() and "\n" not in error.value.format_message()


def test_parse_host_port():
    assert parse_host_port("127.0.0.1:25001") == ("127.0.0.1", 25001)
    assert parse_host_port("[::1]:9") == ("::1", 9)
    assert parse_host_port("localhost:0", allow_port_0=True) == ("localhost", 0)
