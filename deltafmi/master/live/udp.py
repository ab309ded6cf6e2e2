"""UDP live inputs and outputs: :class:`UdpSource` (a live source) and :class:`UdpSink` (a stream).

A source binds a non-blocking socket and, at each communication point, drains the datagrams that
arrived since (at most ``max_per_poll``, so a flood cannot stall a step; the rest wait for the
next poll). Datagrams are DFMI v1 (binary or JSON, :mod:`.datagram`) or packed doubles.

Which value wins: the newest datagram, by the sender's timestamp, then by arrival. Timestamps
are compared per sender (address and port): two programs have two clocks. A DFMI datagram older
than the newest one accepted from its sender is *stale*: counted and dropped; unless its sequence
number went back too, by :data:`RESTART_GAP` or more: the sender restarted (a rebooted device
keeps its port), which is said once and its data taken again. Packed doubles have no timestamp: arrival order wins.
Datagrams from any sender are accepted unless ``sender`` names the one host to listen to.
Nothing from outside raises: malformed datagrams are counted and dropped (a warning for the
first five), names the scenario does not declare are counted as *unknown* (one warning per name).
"""
from __future__ import annotations

import errno
import socket
import struct
from typing import Any, Callable, Dict, Mapping, Optional, Sequence, Tuple, Union

from deltafmi.errors import BadInput

from .datagram import (MAX_DATAGRAM, Encoder, MalformedDatagram, PackedDoubles, decode, encode_json,
                       sequence_went_back)

__all__ = ["UdpSink", "UdpSource", "parse_host_port"]

#: the formats a source reads and a sink writes ("dfmi" reads both DFMI v1 forms)
SOURCE_FORMATS = ("dfmi", "doubles")
SINK_FORMATS = ("dfmi", "dfmi-json", "doubles")
#: malformed datagrams a source warns about; the further ones are counted only
MALFORMED_WARNINGS = 5
#: the receive buffer a source asks for: room for a burst between two polls (the OS may give less)
RECEIVE_BUFFER = 1 << 22
#: how many senders a source remembers the newest timestamp of
MAX_SENDERS = 256
#: a sender whose time goes back while its sequence number goes back by this much or more has
#: restarted (a device rebooted, a model restarted: its data is taken again); a datagram the
#: network merely reordered is only a few numbers behind, and stale
RESTART_GAP = 64
_SO_RXQ_OVFL = getattr(socket, "SO_RXQ_OVFL", 40)  # Linux: ancillary count of datagrams the OS dropped
_OVERFLOW_COUNT = struct.Struct("=I")

Warn = Callable[[str], None]


def parse_host_port(text: str, what: str = "address", allow_port_0: bool = False) -> Tuple[str, int]:
    """``(host, port)`` of ``"host:port"`` (``"[::1]:port"`` for IPv6). Raises :class:`BadInput`
    naming ``text`` (and ``what`` it is) when it is not of that form or the port is out of range."""
    host, sep, port_text = str(text).rpartition(":")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not sep or not host or not port_text.isdigit():
        raise BadInput(f"{what} {text!r}: expected host:port, e.g. 127.0.0.1:25000")
    return host, check_port(int(port_text), f"{what} {text!r}", allow_port_0)


def check_port(port: object, what: str, allow_port_0: bool = False) -> int:
    """``port`` when it is an integer UDP port (1..65535, or 0 = any free port when ``allow_port_0``);
    raises :class:`BadInput` naming ``what`` otherwise."""
    low = 0 if allow_port_0 else 1
    if not isinstance(port, int) or isinstance(port, bool) or not low <= port <= 65535:
        raise BadInput(f"{what}: port {port!r} is not in {low}..65535")
    return port


def _resolve(host: str, port: Optional[int], what: str) -> list:
    """``socket.getaddrinfo`` for UDP; raises :class:`BadInput` naming ``what`` for an unknown host."""
    try:
        return socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    except (socket.gaierror, UnicodeError) as error:
        raise BadInput(f"{what}: unknown host {host!r} ({getattr(error, 'strerror', None) or error})") from None


def _address(host: str, port: int, what: str) -> Tuple[int, tuple]:
    """The socket family and address of ``host:port`` (resolved once, the first answer)."""
    family, _, _, _, address = _resolve(host, port, what)[0]
    return family, address


class UdpSource:
    """A live source of ``signals`` (their names, in the scenario's order) received as UDP datagrams
    on ``host:port`` (port 0: any free port, :attr:`port` tells which after :meth:`open`).

    ``format``: ``"dfmi"`` (DFMI v1, binary or JSON, signals by name) or ``"doubles"`` (one value
    per signal in this order, ``dtype`` float64 or float32, ``byte_order`` little or big).
    ``sender``: only datagrams from this host are read (the others are counted as ``foreign``).
    ``max_per_poll``: the most datagrams one poll reads (1000 take about 5 ms); more wait for the
    next poll, and a warning says so once."""

    def __init__(self, name: str, signals: Sequence[str], host: str = "127.0.0.1", port: int = 0,
                 format: str = "dfmi", byte_order: str = "little", dtype: str = "float64",
                 sender: Optional[str] = None, max_per_poll: int = 1000) -> None:
        """Raises :class:`BadInput` for a wrong option (the message names the source)."""
        self.name = name
        self.signals = tuple(signals)
        where = f"live input '{name}'"
        if not self.signals:
            raise BadInput(f"{where}: no signals")
        if len(set(self.signals)) != len(self.signals):
            raise BadInput(f"{where}: a signal is declared twice")
        if format not in SOURCE_FORMATS:
            raise BadInput(f"{where}: format {format!r}: expected one of {', '.join(SOURCE_FORMATS)}")
        self.host, self.port = host, check_port(port, f"{where} udp", allow_port_0=True)
        self.format = format
        self._packed: Optional[PackedDoubles] = None
        if format == "doubles":
            try:
                self._packed = PackedDoubles(len(self.signals), dtype, byte_order)
            except ValueError as error:
                raise BadInput(f"{where}: {error}") from None
        self.sender = sender
        self.max_per_poll = max(1, int(max_per_poll))
        self._where = where
        self._declared = frozenset(self.signals)
        self._socket: Optional[socket.socket] = None
        self._warn: Warn = lambda text: None
        self._sender_ips: frozenset = frozenset()
        #: sender address -> (newest accepted timestamp, its sequence number)
        self._newest: Dict[tuple, Tuple[float, int]] = {}
        self._unknown_warned: set = set()
        self._stale_warned: set = set()
        self._backlog_warned = False
        self._counts = dict.fromkeys(("received", "accepted", "malformed", "stale", "restarts", "unknown", "foreign",
                                      "overflow"), 0)
        #: the master's C loop reads the socket between its points (:mod:`.native_udp`), or None
        self.native: Optional[Any] = None

    def open(self, warn: Warn) -> None:
        """Binds the socket (non-blocking); ``warn(text)`` takes the warnings of later polls.
        Raises :class:`BadInput` naming host:port when the address cannot be bound."""
        if self._socket is not None:
            return
        self._warn = warn
        what = f"{self._where}: cannot listen on UDP {self.host}:{self.port}"
        family, address = _address(self.host, self.port, what)
        if self.sender is not None:
            self._sender_ips = frozenset(info[4][0] for info in _resolve(self.sender, None, f"{self._where}: sender"))
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
                sock.setsockopt(socket.SOL_SOCKET, _SO_RXQ_OVFL, 1)
            except OSError:  # not Linux: no drop count, the default buffer
                pass
            sock.bind(address)
        except OSError as error:
            sock.close()
            raise BadInput(f"{what}: {error.strerror or error}") from None
        self._socket = sock
        self.port = sock.getsockname()[1]

    def poll(self, t: float) -> Optional[Dict[str, float]]:
        """The newest value of each signal that arrived since the last poll (only those that did),
        or None when nothing new came. Reads at most ``max_per_poll`` datagrams; never blocks and
        never raises on what it receives. ``t`` (simulation time) only dates warnings."""
        sock = self._socket
        if sock is None:
            raise RuntimeError(f"{self._where}: poll before open (or after close)")
        counts = self._counts
        updates: Dict[str, float] = {}
        if self.native is not None:  # what the C loop read since: its values, then the datagram it left to us
            updates, pending = self.native.after_c()
            if self.native.s.backlog:
                self._warn_backlog(t)
            if pending is not None:
                data, sender = pending
                if self._sender_ips and sender[0] not in self._sender_ips:
                    counts["foreign"] += 1
                else:
                    self._take(data, sender, updates)
        ancillary = socket.CMSG_SPACE(_OVERFLOW_COUNT.size)
        for _ in range(self.max_per_poll):
            try:
                data, ancdata, _, sender = sock.recvmsg(MAX_DATAGRAM + 1, ancillary)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # an ICMP error reported on the socket: nothing to read now
                break
            counts["received"] += 1
            if ancdata:
                self._read_overflow(ancdata)
            if self._sender_ips and sender[0] not in self._sender_ips:
                counts["foreign"] += 1
                continue
            self._take(data, sender, updates)
        else:
            self._warn_backlog(t)
        return updates or None

    def _warn_backlog(self, t: float) -> None:
        if not self._backlog_warned:
            self._backlog_warned = True
            self._warn(f"{self._where}: {self.max_per_poll} or more datagrams waiting at t = {t:.9g} s: "
                       "the rest are read at the next communication points (their values arrive late)")

    def _read_overflow(self, ancdata: list) -> None:
        for level, kind, payload in ancdata:
            if level == socket.SOL_SOCKET and kind == _SO_RXQ_OVFL and len(payload) >= _OVERFLOW_COUNT.size:
                self._counts["overflow"] = _OVERFLOW_COUNT.unpack_from(payload)[0]

    def _take(self, data: bytes, sender: tuple, updates: Dict[str, float]) -> None:
        counts = self._counts
        try:
            if self._packed is not None:
                values = dict(zip(self.signals, self._packed.decode(data)))
            else:
                datagram = decode(data)
                newest, last_seq = self._newest.get(sender, (None, None))
                if newest is not None and datagram.t < newest:
                    if not sequence_went_back(last_seq, datagram.seq, RESTART_GAP):
                        counts["stale"] += 1
                        self._warn_stale(sender, datagram.t, newest)
                        return
                    counts["restarts"] += 1
                    self._warn(f"{self._where}: {_show(sender)} restarted (its time went back to "
                               f"{datagram.t:.9g} s and its sequence number to {datagram.seq}): taking its data again")
                self._remember(sender, datagram.t, datagram.seq)
                values = datagram.values
        except MalformedDatagram as error:
            counts["malformed"] += 1
            if counts["malformed"] <= MALFORMED_WARNINGS:
                more = "; further malformed datagrams are counted only" if counts["malformed"] == MALFORMED_WARNINGS else ""
                self._warn(f"{self._where}: dropped a malformed datagram from {_show(sender)}: {error.reason}{more}")
            return
        counts["accepted"] += 1
        declared = self._declared
        for signal, value in values.items():
            if signal in declared:
                updates[signal] = value
            else:
                counts["unknown"] += 1
                if signal not in self._unknown_warned and len(self._unknown_warned) < 100:
                    self._unknown_warned.add(signal)
                    self._warn(f"{self._where}: ignoring signal {signal!r} from {_show(sender)}: not declared "
                               f"(the declared signals: {', '.join(self.signals)})")

    def _remember(self, sender: tuple, t: float, seq: int) -> None:
        newest = self._newest
        if sender not in newest and len(newest) >= MAX_SENDERS:
            del newest[next(iter(newest))]  # forget the sender heard of first
        newest[sender] = (t, seq)

    def _warn_stale(self, sender: tuple, t: float, newest: float) -> None:
        if sender not in self._stale_warned and len(self._stale_warned) < MAX_SENDERS:
            self._stale_warned.add(sender)
            self._warn(f"{self._where}: dropped a stale datagram from {_show(sender)}: its time {t:.9g} s is "
                       f"before {newest:.9g} s, already received; "
                       "further stale datagrams are counted only")

    def counters(self) -> Dict[str, int]:
        """Datagrams ``received``; of those ``accepted``, ``malformed``, ``stale`` (older than the
        newest of their sender) and ``foreign`` (from another host than ``sender``); ``unknown``:
        values of undeclared signals; ``overflow``: datagrams the OS dropped because they came
        faster than polled (Linux)."""
        counts = dict(self._counts)
        if self.native is not None:
            _add_native(counts, self.native.counters())
        return counts

    def native_done(self) -> None:
        """The C loop reads the socket no more: what it counted is kept, Python reads on."""
        if self.native is not None:
            _add_native(self._counts, self.native.counters())
            self.native = None

    def close(self) -> None:
        """Closes the socket; idempotent."""
        sock, self._socket = self._socket, None
        if sock is not None:
            sock.close()


def _add_native(counts: Dict[str, int], native: Dict[str, int]) -> None:
    """The counters of the C loop's reading (:mod:`.native_udp`) added to ``counts``."""
    for key in ("received", "accepted", "foreign"):
        counts[key] += native[key]
    counts["overflow"] = max(counts["overflow"], native["overflow"])


def _show(address: tuple) -> str:
    host, port = address[0], address[1]
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


class UdpSink:
    """A live output: ``signals`` (names, in order) sent as one UDP datagram per :meth:`send` to
    ``host:port``. ``format``: ``"dfmi"`` (DFMI v1 binary), ``"dfmi-json"`` (DFMI v1 JSON, for
    scripts; slower and larger) or ``"doubles"`` (packed, ``dtype``, ``byte_order``: what a
    Simulink UDP Receive block reads). Sequence numbers count every datagram built."""

    def __init__(self, signals: Sequence[str], host: str, port: int, format: str = "dfmi",
                 byte_order: str = "little", dtype: str = "float64") -> None:
        """Raises :class:`BadInput` for a wrong option."""
        self.signals = tuple(signals)
        self.host, self.port = host, port
        self._where = f"UDP stream to {_show((host, port))}"
        check_port(port, self._where)
        if format not in SINK_FORMATS:
            raise BadInput(f"{self._where}: format {format!r}: expected one of {', '.join(SINK_FORMATS)}")
        self.format = format
        try:
            if format == "doubles":
                packed = PackedDoubles(len(self.signals), dtype, byte_order)
                self._encode: Callable[[Sequence[float], float, int], bytes] = lambda values, t, seq: packed.encode(values)
            elif format == "dfmi":
                self._encode = Encoder(self.signals).encode
            else:
                names = self.signals
                self._encode = lambda values, t, seq: encode_json(dict(zip(names, values)), t, seq)
        except ValueError as error:
            raise BadInput(f"{self._where}: {error}") from None
        self._socket: Optional[socket.socket] = None
        self._warn: Warn = lambda text: None
        self._seq = 0
        self._failure_warned = False
        self._counts = {"sent": 0, "failed": 0}

    def open(self, warn: Warn) -> None:
        """Resolves the address and makes a non-blocking socket connected to it (so that the OS
        reports a refused port). Raises :class:`BadInput` for an unknown host."""
        if self._socket is not None:
            return
        self._warn = warn
        family, address = _address(self.host, self.port, self._where)
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            if family == socket.AF_INET:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)  # a broadcast address is a target too
            sock.connect(address)
        except OSError as error:
            sock.close()
            raise BadInput(f"{self._where}: {error.strerror or error}") from None
        self._socket = sock

    def send(self, t: float, values: Union[Sequence[float], Mapping[str, float]]) -> bool:
        """Sends ``values`` (in the order of ``signals``, or a mapping by name) at time ``t``; True
        when the OS took the datagram. Never blocks; a failure (nobody listening, a full buffer,
        a NaN to send) is counted and warned about once, never raised."""
        sock = self._socket
        if sock is None:
            raise RuntimeError(f"{self._where}: send before open (or after close)")
        if isinstance(values, Mapping):
            values = [values[name] for name in self.signals]
        seq, self._seq = self._seq, (self._seq + 1) & 0xFFFFFFFF
        try:
            sock.send(self._encode(values, t, seq))
        except (OSError, ValueError) as error:
            self._counts["failed"] += 1
            if not self._failure_warned:
                self._failure_warned = True
                reason = error.strerror if isinstance(error, OSError) and error.strerror else str(error)
                hint = " (nobody listening?)" if getattr(error, "errno", None) == errno.ECONNREFUSED else ""
                self._warn(f"{self._where}: a datagram was not sent at t = {t:.9g} s: {reason}{hint}; "
                           "further failures are counted only")
            return False
        self._counts["sent"] += 1
        return True

    def counters(self) -> Dict[str, int]:
        """Datagrams ``sent`` (taken by the OS) and ``failed``."""
        return dict(self._counts)

    def close(self) -> None:
        """Closes the socket; idempotent."""
        sock, self._socket = self._socket, None
        if sock is not None:
            sock.close()
