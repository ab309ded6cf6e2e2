"""The live datagram formats (deltafmi.master.live.datagram) against the byte table of docs/realtime.md,
written out here by hand with struct, field by field."""
from __future__ import annotations

import json
import math
import random
import struct

import numpy as np
import pytest

from deltafmi.master.live.datagram import (MAX_DATAGRAM, Datagram, Encoder, MalformedDatagram, PackedDoubles,
                                          decode, encode, encode_json)

#: values whose bits a decimal or float32 detour would change
TRICKY = {"x": 0.1, "θ₁": -1.0 / 3.0, "関節[2]": 5e-324, "Geschwindigkeit_ü": -0.0, "big": 1.7976931348623157e308}


def by_hand(values: dict, t: float, seq: int, version: int = 1, kind: int = 1, count: int | None = None) -> bytes:
    """A DFMI v1 datagram assembled field by field from the documented byte table."""
    out = b"DFMI" + bytes([version, kind]) + struct.pack("<H", len(values) if count is None else count)
    out += struct.pack("<I", seq) + struct.pack("<d", t)
    for name, value in values.items():
        raw = name.encode("utf-8")
        out += bytes([len(raw)]) + raw + struct.pack("<d", value)
    return out


def bits(values) -> list:
    return [struct.pack("<d", v) for v in values]


def test_binary_layout_is_the_documented_byte_table():
    data = encode(TRICKY, 12.5, 7)
    assert data == by_hand(TRICKY, 12.5, 7)
    assert len(data) == 20 + sum(1 + len(n.encode()) + 8 for n in TRICKY)
    assert data[:20] == b"DFMI\x01\x01\x05\x00\x07\x00\x00\x00" + struct.pack("<d", 12.5)


def test_binary_round_trip_is_bit_exact():
    got = decode(encode(TRICKY, -3.25e-7, 2 ** 32 + 5))
    assert got.t == -3.25e-7 and got.seq == 5  # the sequence number wraps at 2**32
    assert list(got.values) == list(TRICKY)
    assert bits(got.values.values()) == bits(TRICKY.values())  # -0.0 and the subnormal too
    assert decode(by_hand({"a": 1.0}, 0.0, 2 ** 32 - 1)) == Datagram(0.0, 2 ** 32 - 1, {"a": 1.0})


def test_encoder_for_fixed_names_equals_encode():
    encoder = Encoder(list(TRICKY))
    assert encoder.encode(list(TRICKY.values()), 1.0, 3) == encode(TRICKY, 1.0, 3)


def test_json_round_trip_is_bit_exact_and_hand_written_json_reads():
    got = decode(encode_json(TRICKY, 0.75, 9))
    assert (got.t, got.seq, list(got.values)) == (0.75, 9, list(TRICKY))
    assert bits(got.values.values()) == bits(TRICKY.values())
    text = '{"format": "dfmi", "version": 1, "t": 2, "signals": {"x": 0.1, "y": -2}, "from": "a script"}'
    assert decode(text.encode()) == Datagram(2.0, 0, {"x": 0.1, "y": -2.0})  # seq optional, extra keys ignored
    assert json.loads(encode_json({"ü": 1.5}, 0.0, 1))["signals"] == {"ü": 1.5}


@pytest.mark.parametrize("dtype, byte_order, fmt", [("float64", "little", "<3d"), ("float64", "big", ">3d"),
                                                    ("float32", "little", "<3f"), ("float32", "big", ">3f")])
def test_packed_doubles_layout_and_round_trip(dtype, byte_order, fmt):
    packed = PackedDoubles(3, dtype, byte_order)
    values = (0.1, -2.5, 1e-3)
    data = packed.encode(values)
    assert data == struct.pack(fmt, *values) and packed.size == struct.calcsize(fmt)
    expected = tuple(float(np.float32(v)) for v in values) if dtype == "float32" else values
    assert packed.decode(data) == expected
    assert packed.decode(struct.pack(fmt, *values)) == expected


def test_float32_rounds_to_nearest_float32():
    packed = PackedDoubles(2, "float32", "big")
    assert packed.encode([1.0, -2.0]) == b"\x3f\x80\x00\x00\xc0\x00\x00\x00"
    (x, y) = packed.decode(packed.encode([0.1, 1.0 + 2 ** -30]))
    assert x == float(np.float32(0.1)) and x != 0.1 and abs(x - 0.1) <= 0.1 * 2 ** -24
    assert y == 1.0


GOOD = by_hand({"x": 1.0, "y": 2.0}, 0.5, 1)


@pytest.mark.parametrize("data, reason", [
    (b"", "empty datagram"),
    (b"DFM", "truncated header: 3 bytes (a DFMI v1 header has 20)"),
    (b"XXXX" + GOOD[4:], "bad magic b'XXXX'"),
    (b"hello", "bad magic b'hell'"),
    (by_hand({"x": 1.0}, 0.0, 0, version=2), "version 2 (this deltafmi reads 1)"),
    (by_hand({"x": 1.0}, 0.0, 0, kind=7), "kind 7 (this deltafmi reads kind 1 = signals)"),
    (by_hand({}, 0.0, 0), "count 0: no signals"),
    (by_hand({"x": 1.0}, math.nan, 0), "timestamp is nan"),
    (by_hand({"x": 1.0}, -math.inf, 0), "timestamp is -inf"),
    (GOOD[:-3], "truncated at entry 2 of 2 (ends after 37 bytes)"),
    (GOOD[:30], "truncated at entry 2 of 2 (ends after 30 bytes)"),
    (GOOD[:25], "truncated at entry 1 of 2 (ends after 25 bytes)"),
    (by_hand({"x": 1.0, "y": 2.0}, 0.0, 0, count=3), "truncated at entry 3 of 3"),
    (GOOD + b"\x00", "1 byte after the last of 2 entries"),
    (by_hand({"x": 1.0, "y": 2.0}, 0.0, 0, count=1), "10 bytes after the last of 1 entries"),
    (by_hand({"x": 1.0, "": 2.0}, 0.0, 0), "entry 2: empty name"),
    (by_hand({"x": 1.0}, 0.0, 0).replace(b"\x01x", b"\x01\xff"), "entry 1: name is not UTF-8 (b'\\xff')"),
    (by_hand({"x": 1.0, "y": math.nan}, 0.0, 0), "signal 'y' is nan"),
    (by_hand({"x": math.inf}, 0.0, 0), "signal 'x' is inf"),
    (b"DFMI\x01\x01\x02\x00" + bytes(12) + b"\x01x" + bytes(8) + b"\x01x" + bytes(8), "signal 'x' twice"),
    (b'{"format": "dfmi", "version": 2, "t": 0, "signals": {"x": 1}}', "version 2 (this deltafmi reads 1)"),
    (b'{"format": "dfmi", "t": 0, "signals": {"x": 1}}', "version None (this deltafmi reads 1)"),
    (b'{"format": "csv", "version": 1, "t": 0, "signals": {"x": 1}}', '"format" is \'csv\' (expected "dfmi")'),
    (b'{"format": "dfmi", "version": 1, "signals": {"x": 1}}', '"t" is None (expected a finite number)'),
    (b'{"format": "dfmi", "version": 1, "t": 1e999, "signals": {"x": 1}}', '"t" is inf'),
    (b'{"format": "dfmi", "version": 1, "t": 0, "seq": -1, "signals": {"x": 1}}', '"seq" is -1'),
    (b'{"format": "dfmi", "version": 1, "t": 0, "signals": {}}', '"signals" must be a non-empty object'),
    (b'{"format": "dfmi", "version": 1, "t": 0, "signals": {"x": NaN}}', "signal 'x' is nan (expected a finite number)"),
    (b'{"format": "dfmi", "version": 1, "t": 0, "signals": {"x": "1"}}', "signal 'x' is '1'"),
    (b'{"format": "dfmi", "version": 1, "t": 0, "signals": {"x": true}}', "signal 'x' is True"),
    (b'{"format": "dfmi", "version": 1, "t": 0, "signals": {"x": 10' + b"0" * 400 + b"}}", "signal 'x' is 1" + "0" * 39 + "... (expected a finite number)"),
    (b'{"format": "dfmi", "version": 1, "t": 0, "signals": {"x": 1, "x": 2}}', "key 'x' twice"),
    (b'{"format": "dfmi", "version": 1, "t": 0, "signals": {"": 1}}', "empty signal name"),
    (b'{"format": "dfmi", "version": 1, "t": 0', "not JSON: "),
    (b"{" + b"\xff" * 4, "JSON datagram is not UTF-8"),
])
def test_each_malformed_datagram_has_its_reason(data, reason):
    with pytest.raises(MalformedDatagram) as error:
        decode(data)
    assert reason in error.value.reason and error.value.reason == str(error.value)
    assert "\n" not in error.value.reason


def test_deep_json_nesting_is_malformed_not_a_recursion_crash():
    with pytest.raises(MalformedDatagram, match="not JSON"):
        decode(b'{"a": ' + b"[" * 60000 + b"]" * 60000 + b"}")


def test_packed_doubles_malformed():
    packed = PackedDoubles(2)
    with pytest.raises(MalformedDatagram, match=r"^24 bytes, expected 16 \(2 float64 values\)$"):
        packed.decode(struct.pack("<3d", 1, 2, 3))
    with pytest.raises(MalformedDatagram, match=r"^value 2 is nan$"):
        packed.decode(struct.pack("<2d", 1, math.nan))
    with pytest.raises(MalformedDatagram, match=r"^8 bytes, expected 4 \(1 float32 values\)$"):
        PackedDoubles(1, "float32", "big").decode(bytes(8))


def test_random_corruptions_only_ever_raise_malformed():
    """Truncations, flipped bytes and random bytes: decode returns a Datagram or raises
    MalformedDatagram, nothing else (a live source must not crash on what it receives)."""
    rng = random.Random(28)
    samples = [encode(TRICKY, 1.0, 1), encode_json(TRICKY, 1.0, 1)]
    outcomes = {"ok": 0, "malformed": 0}
    for _ in range(20000):
        data = bytearray(rng.choice(samples))
        action = rng.randrange(3)
        if action == 0:
            data = data[:rng.randrange(len(data))]
        elif action == 1:
            for _ in range(rng.randint(1, 3)):
                data[rng.randrange(len(data))] = rng.randrange(256)
        else:
            data = bytearray(b"DFMI\x01\x01") + bytearray(rng.randbytes(rng.randrange(40)))
        try:
            got = decode(bytes(data))
        except MalformedDatagram:
            outcomes["malformed"] += 1
        else:
            assert all(math.isfinite(v) for v in got.values.values()) and math.isfinite(got.t)
            outcomes["ok"] += 1
    assert outcomes["ok"] > 100 and outcomes["malformed"] > 10000


def test_encode_refuses_what_a_receiver_would_drop():
    with pytest.raises(ValueError, match="'y' is nan: DFMI v1 carries finite values only"):
        encode({"x": 1.0, "y": math.nan}, 0.0, 0)
    with pytest.raises(ValueError, match="timestamp is inf"):
        encode({"x": 1.0}, math.inf, 0)
    with pytest.raises(ValueError, match="is 256 bytes of UTF-8; DFMI v1 allows 255"):
        encode({"ü" * 128: 1.0}, 0.0, 0)
    assert decode(encode({"ü" * 127 + "a": 1.0}, 0.0, 0)).values == {"ü" * 127 + "a": 1.0}
    with pytest.raises(ValueError, match="at least one signal"):
        encode({}, 0.0, 0)
    with pytest.raises(ValueError, match="at least one value"):
        PackedDoubles(0)
    with pytest.raises(ValueError, match="cannot pack as float32"):
        PackedDoubles(1, "float32").encode([1e39])
    with pytest.raises(ValueError, match="dtype 'int16'"):
        PackedDoubles(1, "int16")
    with pytest.raises(ValueError, match="byte_order 'network'"):
        PackedDoubles(1, byte_order="network")


def test_encode_refuses_datagrams_larger_than_udp_carries():
    names = [f"{k:03d}" + "n" * 246 for k in range(254)]  # names of 249 bytes: entries of 258
    assert len(encode(dict.fromkeys(names[:253], 1.0), 0.0, 0)) == 20 + 253 * 258 == 65294 <= MAX_DATAGRAM
    with pytest.raises(ValueError, match=r"^254 signals make a datagram of 65552 bytes; a UDP datagram carries at most 65507"):
        encode(dict.fromkeys(names, 1.0), 0.0, 0)
    with pytest.raises(ValueError, match="carries at most 65507"):
        PackedDoubles(8189)
    assert PackedDoubles(8188).size == 65504
