"""Live UDP inputs read by the master's C loop between its paced steps (``native/udp_reader.c``).

A paced run whose live sources are all UDP sources on IPv4 sockets lets the C loop read them at
every communication point, after the point's wait and before its row, as
:meth:`~deltafmi.master.live.input_units.LiveInputUnit.sample` would: the datagrams that arrived
since the last point, in arrival order, the newest value of each signal winning, into the unit's
values and the bus. No Python runs between two points, so the run can go as fast as its pacing
(a hand-back to Python at every point costs more than a 20 us paced step). What the C reader does
not take itself (a JSON datagram, a malformed one, an undeclared name, a sender beyond the 16 it
remembers, a timestamp older than its sender's newest, a change of the source's silence) it hands to
Python with that point: :class:`~deltafmi.master.live.udp.UdpSource` reads on from exactly that
datagram by its own rules, so the values, counters and warnings are those of a Python-read run.
"""
from __future__ import annotations

import ctypes
import socket
from ctypes import POINTER, c_double, c_int, c_long, c_uint16, c_uint32, c_void_p
from pathlib import Path
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np

from deltafmi.toolchain import BuildError, plain_c_library

from .datagram import MAX_DATAGRAM

__all__ = ["NativeReaders", "native_readers"]

_MAX_SENDERS, _MAX_ALLOWED = 16, 8
_FORMAT = {"dfmi": 0, "doubles": 1}


class _Sender(ctypes.Structure):
    _fields_ = [("host", c_uint32), ("port", c_uint16), ("known", c_int), ("t", c_double), ("seq", c_uint32)]


class _Source(ctypes.Structure):
    _fields_ = [("fd", c_int), ("format", c_int), ("float32", c_int), ("big_endian", c_int), ("n", c_long),
                ("names", c_void_p), ("name_start", c_void_p), ("name_length", c_void_p),
                ("values", c_void_p), ("bus", c_void_p), ("fresh", c_void_p), ("scratch", c_void_p),
                ("seen", c_void_p), ("timeout", c_double), ("silent", c_int), ("last_news", c_double),
                ("max_per_poll", c_long), ("n_allowed", c_long), ("allowed", c_uint32 * _MAX_ALLOWED),
                ("senders", _Sender * _MAX_SENDERS), ("n_senders", c_long), ("buffer", c_void_p),
                ("pending", c_long), ("pending_host", c_uint32), ("pending_port", c_uint16),
                ("received", c_long), ("accepted", c_long), ("foreign", c_long), ("overflow", c_uint32),
                ("backlog", c_int)]


class _Readers(ctypes.Structure):
    _fields_ = [("sources", POINTER(_Source)), ("n", c_long)]


_sample: Optional[Any] = None


def _sample_function() -> Any:
    global _sample
    if _sample is None:
        library = ctypes.CDLL(str(plain_c_library(Path(__file__).parent / "native" / "udp_reader.c")))
        _sample = library.deltafmi_live_sample
    return _sample


def _address(host: int, port: int) -> Tuple[str, int]:
    """The (host, port) Python's socket gives for an IPv4 address and port in network byte order."""
    return socket.inet_ntoa(int(host).to_bytes(4, "little")), socket.ntohs(port)


class NativeReader:
    """The C reader's state of one :class:`~deltafmi.master.live.udp.UdpSource` (its socket, its
    unit's values and bus slots), and the hand-over between the two at a point C hands back."""

    def __init__(self, source: Any, unit: Any, struct: _Source) -> None:
        self.source, self.unit, self.s = source, unit, struct
        n = len(source.signals)
        names = [name.encode("utf-8") for name in source.signals]
        self._names = np.frombuffer(b"".join(names) or b"\0", dtype=np.uint8).copy()
        self._start = np.cumsum([0] + [len(b) for b in names[:-1]]).astype(np.int_)
        self._length = np.array([len(b) for b in names], dtype=np.int_)
        self._bus = (c_void_p * n)()
        if unit._bus is not None:
            for vr, slot in zip(unit._vrs.tolist(), unit._slots.tolist()):
                self._bus[vr] = unit._bus.ctypes.data + slot * unit._bus.itemsize
        self.fresh = np.zeros(n, dtype=np.uint8)
        self._scratch, self._seen = np.zeros(n), np.zeros(n, dtype=np.uint8)
        self._buffer = np.zeros(MAX_DATAGRAM + 1, dtype=np.uint8)
        packed = source._packed
        s = struct
        s.fd, s.format, s.n = source._socket.fileno(), _FORMAT[source.format], n
        s.float32 = int(packed is not None and packed.dtype == "float32")
        s.big_endian = int(packed is not None and packed.byte_order == "big")
        s.names, s.name_start, s.name_length = (self._names.ctypes.data, self._start.ctypes.data,
                                                self._length.ctypes.data)
        s.values, s.bus, s.fresh = unit.values.ctypes.data, ctypes.cast(self._bus, c_void_p), self.fresh.ctypes.data
        s.scratch, s.seen, s.buffer = self._scratch.ctypes.data, self._seen.ctypes.data, self._buffer.ctypes.data
        s.timeout = -1.0 if unit.timeout is None else float(unit.timeout)
        s.max_per_poll = source.max_per_poll
        allowed = sorted(source._sender_ips)
        s.n_allowed = len(allowed)
        for i, ip in enumerate(allowed):
            s.allowed[i] = int.from_bytes(socket.inet_aton(ip), "little")
        s.pending = -1
        self.before_c()

    def before_c(self) -> None:
        """Python's view handed to C before it reads again: the silence, the last news, and the
        newest timestamp of each sender both know of."""
        s, unit = self.s, self.unit
        s.silent = int(unit._silent_since is not None)
        s.last_news = unit._last_news
        newest = dict(self.source._newest)
        for i in range(s.n_senders):  # every one C knows of, Python knows of too (after_c)
            sender = s.senders[i]
            known = newest.pop(_address(sender.host, sender.port), None)
            if known is not None:
                sender.t, sender.seq = known[0], known[1] & 0xFFFFFFFF
        for address, (t, seq) in newest.items():  # the senders only Python heard of, while C has room
            if s.n_senders >= _MAX_SENDERS:
                break
            if len(address) != 2:
                continue
            sender = s.senders[s.n_senders]
            sender.host = int.from_bytes(socket.inet_aton(address[0]), "little")
            sender.port, sender.known, sender.t, sender.seq = socket.htons(address[1]), 1, t, seq & 0xFFFFFFFF
            s.n_senders += 1

    def after_c(self) -> Tuple[dict, Optional[Tuple[bytes, Tuple[str, int]]]]:
        """What C took at the point it read last (signal -> value: the point's news) and the
        datagram it handed over with its sender (or None); the senders' newest timestamps C
        accepted, and its last news, given to Python."""
        s, unit = self.s, self.unit
        unit._last_news = max(unit._last_news, s.last_news)
        newest = self.source._newest
        for i in range(s.n_senders):
            sender = s.senders[i]
            if sender.known and sender.t != -np.inf:  # -inf: remembered, nothing accepted yet
                newest[_address(sender.host, sender.port)] = (sender.t, sender.seq)
        taken = {self.source.signals[i]: float(unit.values[i]) for i in np.flatnonzero(self.fresh).tolist()}
        self.fresh[:] = 0
        pending = None
        if s.pending >= 0:
            pending = (self._buffer[:s.pending].tobytes(), _address(s.pending_host, s.pending_port))
            s.pending = -1
        return taken, pending

    def counters(self) -> dict:
        """What C counted of the datagrams it read (received, accepted, foreign; overflow: the OS's count)."""
        s = self.s
        return {"received": s.received, "accepted": s.accepted, "foreign": s.foreign, "overflow": s.overflow,
                "backlog": s.backlog}


class NativeReaders:
    """The C readers of a run's live sources: :attr:`function` and :attr:`context` for the C loop."""

    def __init__(self, pairs: Sequence[Tuple[Any, Any]]) -> None:
        self._structs = (_Source * len(pairs))()
        self.readers: List[NativeReader] = []
        for (unit, source), struct in zip(pairs, self._structs):
            reader = NativeReader(source, unit, struct)
            source.native = reader
            self.readers.append(reader)
        self._readers = _Readers(self._structs, len(pairs))
        self.function = ctypes.cast(_sample_function(), c_void_p).value
        self.context = ctypes.addressof(self._readers)

    def before_c(self) -> None:
        for reader in self.readers:
            reader.before_c()

    def close(self) -> None:
        """The sources read by Python again (after the run), what C counted kept."""
        for reader in self.readers:
            reader.source.native_done()


def native_readers(units: Sequence[Any]) -> Optional[NativeReaders]:
    """C readers for the live input ``units`` when every one reads an open IPv4 UDP source, else
    None (the sources are then sampled in Python at every point)."""
    from .udp import UdpSource

    pairs = [(unit, unit.source) for unit in units]
    if not pairs or not all(isinstance(source, UdpSource) and source._socket is not None
                            and source._socket.family == socket.AF_INET
                            and len(source._sender_ips) <= _MAX_ALLOWED
                            and all(":" not in ip for ip in source._sender_ips) for _, source in pairs):
        return None
    try:
        return NativeReaders(pairs)
    except (BuildError, OSError):  # no compiler and no prebuilt reader: Python reads them
        return None
