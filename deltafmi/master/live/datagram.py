"""The datagram formats of live inputs and outputs: DFMI v1 (binary and JSON) and packed doubles.

**DFMI v1, binary** (all little-endian; a header of 20 bytes, then ``count`` entries)::

    offset  size  type      field
    0       4     bytes     magic b"DFMI"
    4       1     uint8     version, 1
    5       1     uint8     kind, 1 = signals (other kinds are reserved)
    6       2     uint16    count, number of entries, >= 1
    8       4     uint32    sequence, the sender's counter (wraps at 2**32)
    12      8     float64   timestamp [s], the sender's time (deltafmi sends simulation time)
    20      ...   entries:  uint8 name length n (1..255), n bytes UTF-8 name, float64 value

**DFMI v1, JSON** (one UTF-8 JSON object per datagram, told apart by its first byte ``{``)::

    {"format": "dfmi", "version": 1, "t": 0.25, "seq": 7, "signals": {"x": 0.1, "y": -0.2}}

``seq`` may be left out (0); other keys are ignored.

**Packed doubles** (what Simulink's UDP Send and Packet Output blocks send): ``n`` values, float64
or float32, little- or big-endian, no header; the values are in the order the receiver declares its
signals, and a datagram of any other length is malformed.

Decided for live inputs: a value or timestamp that is NaN or infinite makes the datagram malformed
(a live input must not poison a run), as do an empty datagram (count 0), a name given twice,
an empty name, a name that is not UTF-8 and bytes after the last entry. :func:`decode` raises
:class:`MalformedDatagram` for every such case and nothing else, whatever the bytes.
"""
from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from typing import Dict, Iterable, Mapping, Optional, Sequence, Tuple

from deltafmi.errors import DeltaFmiError

__all__ = ["Datagram", "Encoder", "MAX_DATAGRAM", "MalformedDatagram", "PackedDoubles", "decode", "encode",
           "encode_json", "sequence_went_back"]

MAGIC = b"DFMI"
VERSION = 1
KIND_SIGNALS = 1
#: the largest UDP payload over IPv4 (65535 - 8 bytes UDP header - 20 bytes IP header)
MAX_DATAGRAM = 65507
#: the longest signal name, in bytes of UTF-8 (its length is one byte)
MAX_NAME = 255

_HEADER = struct.Struct("<4sBBHId")
_VALUE = struct.Struct("<d")
_HEADER_SIZE = _HEADER.size  # 20
_ENTRY_OVERHEAD = 1 + _VALUE.size  # the length byte and the value
_isfinite = math.isfinite


class MalformedDatagram(DeltaFmiError, ValueError):
    """A datagram that cannot be read; ``reason`` says precisely why (one line)."""

    exit_code = 2  # bad input

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass(frozen=True)
class Datagram:
    """One decoded DFMI datagram: the sender's time ``t`` [s], its sequence number ``seq`` and the
    signal ``values`` by name, in the order they came."""

    t: float
    seq: int
    values: Dict[str, float]


def _name_bytes(name: str) -> bytes:
    raw = name.encode("utf-8")
    if not raw:
        raise ValueError("a signal name must not be empty")
    if len(raw) > MAX_NAME:
        raise ValueError(f"signal name {name[:40]!r}... is {len(raw)} bytes of UTF-8; DFMI v1 allows {MAX_NAME}")
    return raw


def _check_finite(name: str, value: float) -> None:
    if not _isfinite(value):
        raise ValueError(f"signal {name!r} is {value}: DFMI v1 carries finite values only")


def _too_large(size: int, count: int) -> ValueError:
    return ValueError(f"{count} signals make a datagram of {size} bytes; a UDP datagram carries at most "
                      f"{MAX_DATAGRAM} (split the signals over several streams)")


class Encoder:
    """Encodes datagrams of a fixed list of signal ``names`` fast (one precompiled :class:`struct.Struct`):
    what a sender that sends the same signals again and again uses."""

    def __init__(self, names: Sequence[str]) -> None:
        """Raises ValueError for an empty list, a repeated, empty or too long name, or a datagram
        that would not fit in :data:`MAX_DATAGRAM`."""
        self.names = tuple(names)
        if not self.names:
            raise ValueError("a DFMI datagram needs at least one signal")
        if len(set(self.names)) != len(self.names):
            twice = next(n for n in self.names if self.names.count(n) > 1)
            raise ValueError(f"signal {twice!r} is named twice")
        raws = [_name_bytes(name) for name in self.names]
        self._struct = struct.Struct(_HEADER.format + "".join(f"B{len(raw)}sd" for raw in raws))
        if self._struct.size > MAX_DATAGRAM:
            raise _too_large(self._struct.size, len(raws))
        self._names_args = [(len(raw), raw) for raw in raws]

    def encode(self, values: Sequence[float], t: float, seq: int) -> bytes:
        """The binary datagram of ``values`` (in the order of ``names``) at time ``t`` with sequence
        number ``seq`` (taken modulo 2**32). Raises ValueError for a non-finite value or time."""
        if len(values) != len(self.names):
            raise ValueError(f"{len(values)} values for {len(self.names)} signals")
        _check_time(t)
        args: list = [MAGIC, VERSION, KIND_SIGNALS, len(self.names), seq & 0xFFFFFFFF, float(t)]
        for name, (size, raw), value in zip(self.names, self._names_args, values):
            value = float(value)
            _check_finite(name, value)
            args += (size, raw, value)
        return self._struct.pack(*args)


def _check_time(t: float) -> None:
    if not _isfinite(t):
        raise ValueError(f"the timestamp is {t}: DFMI v1 carries finite times only")


def encode(values: Mapping[str, float], t: float, seq: int) -> bytes:
    """The binary DFMI v1 datagram of the signal ``values`` (by name) at the sender's time ``t`` [s]
    with sequence number ``seq`` (taken modulo 2**32).

    Raises ValueError for no values, an empty or too long name (255 bytes of UTF-8), a NaN or
    infinite value or time, or a datagram larger than :data:`MAX_DATAGRAM` bytes."""
    return Encoder(list(values)).encode(list(values.values()), t, seq)


def encode_json(values: Mapping[str, float], t: float, seq: int) -> bytes:
    """The JSON DFMI v1 datagram of the same content as :func:`encode` (values round-trip exactly:
    Python writes the shortest decimal that reads back as the same float64)."""
    if not values:
        raise ValueError("a DFMI datagram needs at least one signal")
    _check_time(t)
    signals = {}
    for name, value in values.items():
        _name_bytes(name)
        value = float(value)
        _check_finite(name, value)
        signals[name] = value
    data = json.dumps({"format": "dfmi", "version": VERSION, "t": float(t), "seq": seq & 0xFFFFFFFF,
                       "signals": signals}, ensure_ascii=False, separators=(",", ":")).encode("utf-8")
    if len(data) > MAX_DATAGRAM:
        raise _too_large(len(data), len(signals))
    return data


def decode(data: bytes) -> Datagram:
    """The :class:`Datagram` in ``data``: DFMI v1 binary, or JSON when the first byte is ``{``.
    Raises :class:`MalformedDatagram` (and nothing else) when ``data`` is not a valid datagram."""
    if data[:1] == b"{":
        return _decode_json(data)
    size = len(data)
    if size < _HEADER_SIZE:
        if size == 0:
            raise MalformedDatagram("empty datagram")
        if data[:4] != MAGIC[:size]:
            raise MalformedDatagram(f"bad magic {bytes(data[:4])!r} (expected {MAGIC!r} or a JSON object)")
        raise MalformedDatagram(f"truncated header: {size} bytes (a DFMI v1 header has {_HEADER_SIZE})")
    magic, version, kind, count, seq, t = _HEADER.unpack_from(data)
    if magic != MAGIC:
        raise MalformedDatagram(f"bad magic {magic!r} (expected {MAGIC!r} or a JSON object)")
    if version != VERSION:
        raise MalformedDatagram(f"version {version} (this deltafmi reads {VERSION})")
    if kind != KIND_SIGNALS:
        raise MalformedDatagram(f"kind {kind} (this deltafmi reads kind {KIND_SIGNALS} = signals)")
    if count == 0:
        raise MalformedDatagram("count 0: no signals")
    if not _isfinite(t):
        raise MalformedDatagram(f"timestamp is {t}")
    values: Dict[str, float] = {}
    offset = _HEADER_SIZE
    unpack_value = _VALUE.unpack_from
    for k in range(1, count + 1):
        if offset >= size:
            raise MalformedDatagram(f"truncated at entry {k} of {count} (ends after {size} bytes)")
        length = data[offset]
        end = offset + 1 + length
        if end + 8 > size:
            raise MalformedDatagram(f"truncated at entry {k} of {count} (ends after {size} bytes)")
        if length == 0:
            raise MalformedDatagram(f"entry {k}: empty name")
        try:
            name = data[offset + 1:end].decode("utf-8")
        except UnicodeDecodeError:
            raise MalformedDatagram(f"entry {k}: name is not UTF-8 ({bytes(data[offset + 1:end])[:40]!r})") from None
        value = unpack_value(data, end)[0]
        if not _isfinite(value):
            raise MalformedDatagram(f"signal {name!r} is {value}")
        values[name] = value
        if len(values) != k:
            raise MalformedDatagram(f"signal {name!r} twice")
        offset = end + 8
    if offset != size:
        extra = size - offset
        raise MalformedDatagram(f"{extra} byte{'s' * (extra != 1)} after the last of {count} entries")
    return Datagram(t, seq, values)


class _Twice(Exception):
    pass


def _no_duplicates(pairs: Iterable[Tuple[str, object]]) -> dict:
    result: dict = {}
    for key, value in pairs:
        if key in result:
            raise _Twice(key)
        result[key] = value
    return result


def _finite(value: object) -> Optional[float]:
    """``value`` as a float when it is a finite JSON number (not a bool), else None."""
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return None
    try:
        value = float(value)
    except OverflowError:  # an integer beyond float64
        return None
    return value if _isfinite(value) else None


def _decode_json(data: bytes) -> Datagram:
    try:
        obj = json.loads(data.decode("utf-8"), object_pairs_hook=_no_duplicates)
    except UnicodeDecodeError:
        raise MalformedDatagram("JSON datagram is not UTF-8") from None
    except _Twice as twice:
        raise MalformedDatagram(f"JSON datagram: key {twice.args[0]!r} twice") from None
    except (ValueError, RecursionError) as error:
        raise MalformedDatagram(f"not JSON: {str(error).splitlines()[0][:120]}") from None
    if not isinstance(obj, dict):
        raise MalformedDatagram("JSON datagram is not an object")
    if obj.get("format") != "dfmi":
        raise MalformedDatagram(f'JSON datagram: "format" is {obj.get("format")!r} (expected "dfmi")')
    version = obj.get("version")
    if version != VERSION or isinstance(version, bool):
        raise MalformedDatagram(f"version {version!r} (this deltafmi reads {VERSION})")
    t = _finite(obj.get("t"))
    if t is None:
        raise MalformedDatagram(f'JSON datagram: "t" is {obj.get("t")!r} (expected a finite number)')
    seq = obj.get("seq", 0)
    if not isinstance(seq, int) or isinstance(seq, bool) or not 0 <= seq < 2 ** 32:
        raise MalformedDatagram(f'JSON datagram: "seq" is {seq!r} (expected an integer 0..2**32-1)')
    signals = obj.get("signals")
    if not isinstance(signals, dict) or not signals:
        raise MalformedDatagram('JSON datagram: "signals" must be a non-empty object of names to numbers')
    values: Dict[str, float] = {}
    for name, value in signals.items():
        if not name:
            raise MalformedDatagram("JSON datagram: empty signal name")
        number = _finite(value)
        if number is None:
            shown = repr(value)
            raise MalformedDatagram(f"signal {name!r} is {shown[:40] + '...' * (len(shown) > 40)} (expected a finite number)")
        values[name] = number
    return Datagram(t, seq, values)


_DTYPES = {"float64": "d", "float32": "f"}
_BYTE_ORDERS = {"little": "<", "big": ">"}


class PackedDoubles:
    """Datagrams of ``n`` plain values without header, as Simulink's UDP blocks send them: ``dtype``
    ``"float64"`` or ``"float32"``, ``byte_order`` ``"little"`` or ``"big"``."""

    def __init__(self, n: int, dtype: str = "float64", byte_order: str = "little") -> None:
        """Raises ValueError for an unknown ``dtype`` or ``byte_order``, n < 1, or a datagram
        larger than :data:`MAX_DATAGRAM` bytes."""
        if dtype not in _DTYPES:
            raise ValueError(f"dtype {dtype!r}: expected one of {', '.join(_DTYPES)}")
        if byte_order not in _BYTE_ORDERS:
            raise ValueError(f"byte_order {byte_order!r}: expected one of {', '.join(_BYTE_ORDERS)}")
        if not isinstance(n, int) or n < 1:
            raise ValueError(f"packed doubles need at least one value, not {n!r}")
        self.n, self.dtype, self.byte_order = n, dtype, byte_order
        self._struct = struct.Struct(f"{_BYTE_ORDERS[byte_order]}{n}{_DTYPES[dtype]}")
        if self._struct.size > MAX_DATAGRAM:
            raise _too_large(self._struct.size, n)

    @property
    def size(self) -> int:
        """The length of every datagram, in bytes."""
        return self._struct.size

    def encode(self, values: Sequence[float]) -> bytes:
        """The datagram of ``values`` (n of them). Raises ValueError for a wrong count, a non-finite
        value, or a value float32 cannot hold."""
        if len(values) != self.n:
            raise ValueError(f"{len(values)} values for a datagram of {self.n}")
        for k, value in enumerate(values, 1):
            _check_finite(f"value {k}", float(value))
        try:
            return self._struct.pack(*values)
        except (OverflowError, struct.error) as error:
            raise ValueError(f"cannot pack as {self.dtype}: {error}") from None

    def decode(self, data: bytes) -> Tuple[float, ...]:
        """The ``n`` values of ``data``; raises :class:`MalformedDatagram` for a wrong length or a
        NaN or infinite value."""
        if len(data) != self._struct.size:
            raise MalformedDatagram(f"{len(data)} bytes, expected {self._struct.size} ({self.n} {self.dtype} values)")
        values = self._struct.unpack(data)
        if not all(map(_isfinite, values)):
            k = next(k for k, v in enumerate(values, 1) if not _isfinite(v))
            raise MalformedDatagram(f"value {k} is {values[k - 1]}")
        return values


def sequence_went_back(last: Optional[int], seq: int, by: int = 1) -> bool:
    """Whether a sender's 32-bit sequence number went back from ``last`` to ``seq`` by ``by`` or
    more (a wrap from 2^32 - 1 to 0 is going on, not back)."""
    return last is not None and by <= ((last - seq) & 0xFFFFFFFF) < (1 << 31)
