"""Connecting to a running Dask scheduler by address (``deltafmi sweep --scheduler``).

A refused connection is reported at once, naming the address (Dask itself would retry until its
connect timeout); a host that does not answer at all is given ``timeout`` seconds
(``--connect-timeout``). A ``tls://`` address needs this client's certificate, key and the CA
that signed the scheduler's: Dask's :class:`~distributed.security.Security` made from the
``--tls-*`` options, else read by Dask from its own configuration (``distributed.comm.tls.ca-file``,
``distributed.comm.tls.client.cert``, ``distributed.comm.tls.client.key``, in a Dask YAML file
or as ``DASK_DISTRIBUTED__COMM__TLS__...`` environment variables).
"""
from __future__ import annotations

import socket
import ssl
from pathlib import Path
from typing import Any, List, Optional, Union

from deltafmi.errors import BadInput

__all__ = ["CONNECT_TIMEOUT", "connect", "tls_security"]

#: seconds to wait for a scheduler host that does not answer (a refusal is known at once)
CONNECT_TIMEOUT = 10.0
#: the port of a scheduler address that names none (Dask's default)
DEFAULT_PORT = 8786

PathLike = Union[str, Path]


def tls_security(ca_file: Optional[PathLike] = None, cert: Optional[PathLike] = None,
                 key: Optional[PathLike] = None) -> Any:
    """Dask's ``Security`` of a client from the ``--tls-*`` options; None when none is given
    (then Dask reads its configuration). ``key`` may be left out when ``cert`` holds the key."""
    if ca_file is None and cert is None and key is None:
        return None
    if ca_file is None or cert is None:
        raise BadInput("--tls-ca-file and --tls-cert go together (with --tls-key, unless the certificate "
                       "file also holds the key)")
    from distributed.security import Security

    return Security(tls_ca_file=str(ca_file), tls_client_cert=str(cert),
                    tls_client_key=None if key is None else str(key), require_encryption=True)


def connect(address: str, security: Any = None, timeout: float = CONNECT_TIMEOUT) -> Any:
    """A :class:`distributed.Client` of the scheduler at ``address``; :class:`BadInput` with one
    line naming the address when it cannot be reached or refuses this client."""
    from distributed import Client
    from distributed.comm import parse_address

    from distributed.comm.registry import get_backend

    try:
        protocol, location = parse_address(address)
        get_backend(protocol)
    except ValueError as exc:  # a malformed address, an unknown scheme
        raise BadInput(f"--scheduler {address!r}: {exc}") from None
    context = _tls_context(address, protocol, security)
    if protocol in ("tcp", "tls"):
        _probe(address, location, timeout, context)
    try:
        if security is None:  # Dask's Security() from its configuration
            return Client(address, timeout=f"{timeout}s")
        return Client(address, timeout=f"{timeout}s", security=security)
    except (OSError, TimeoutError) as exc:
        reason = _reason(exc)
        if protocol == "tcp" and "reset by peer" in reason:
            reason += f" (a scheduler that speaks TLS? then its address is tls://{location})"
        raise BadInput(f"cannot connect to the Dask scheduler at {address}: {reason}") from None
    except Exception as exc:  # noqa: BLE001 - e.g. a web server at that port: its answer read as Dask's
        raise BadInput(f"cannot connect to the Dask scheduler at {address}: what answers there is no Dask "
                       f"scheduler ({type(exc).__name__}: {str(exc)[:100]})") from None


def _probe(address: str, location: str, timeout: float, context: Optional[ssl.SSLContext]) -> None:
    """Open (and close) a connection to the scheduler's port: a refusal ends the sweep now. With
    TLS, shake hands too (a scheduler sees a failed handshake as a warning in its log)."""
    from distributed.comm.addressing import parse_host_port

    try:
        host, port = parse_host_port(location, default_port=DEFAULT_PORT)
    except ValueError as exc:
        raise BadInput(f"--scheduler {address!r}: {exc}") from None
    host = host or "127.0.0.1"
    why = f"cannot reach the Dask scheduler at {address}"
    try:
        with socket.create_connection((host, port), timeout=timeout) as connection:
            if context is not None:
                context.wrap_socket(connection).close()
    except ssl.SSLError as exc:
        raise BadInput(f"cannot connect to the Dask scheduler at {address}: {_reason(exc)}") from None
    except ConnectionRefusedError:
        raise BadInput(f"{why}: connection refused (no scheduler listens on port {port} of {host}; "
                       "is `dask scheduler` running there?)") from None
    except socket.timeout:
        raise BadInput(f"{why}: no answer in {timeout:g} s (a host that is down or a firewall that drops the "
                       "connection; --connect-timeout sets how long to wait)") from None
    except socket.gaierror as exc:
        raise BadInput(f"{why}: unknown host {host!r} ({exc.strerror})") from None
    except OSError as exc:
        raise BadInput(f"{why}: {exc.strerror or exc}") from None


def _tls_context(address: str, protocol: str, security: Any) -> Optional[ssl.SSLContext]:
    """The client's TLS context of a tls:// address (which needs one); None for other addresses
    (which take no --tls-* options)."""
    if protocol != "tls":
        if security is not None:
            raise BadInput(f"--tls-ca-file, --tls-cert and --tls-key are for a tls:// scheduler address, not {address}")
        return None
    from distributed.security import Security

    try:
        context = (security or Security()).get_connection_args("client").get("ssl_context")
    except (OSError, ValueError) as exc:  # ssl.SSLError is an OSError: a file that is no certificate or key
        raise BadInput(f"the TLS files for {address} cannot be used (PEM files: a CA certificate, this client's "
                       f"certificate and its matching key): {exc}") from None
    if context is None:
        raise BadInput(f"the Dask scheduler at {address} speaks TLS: give this client's certificate with "
                       "--tls-ca-file CA.pem --tls-cert CLIENT.pem --tls-key CLIENT.key (or set Dask's "
                       "distributed.comm.tls.ca-file, distributed.comm.tls.client.cert and .key)")
    return context


def _reason(exc: BaseException) -> str:
    """Why a connection failed, in words: a TLS failure says which side refused whom."""
    chain: List[BaseException] = []
    seen: Optional[BaseException] = exc
    while seen is not None and len(chain) < 10:
        chain.append(seen)
        seen = seen.__cause__ or seen.__context__
    for error in chain:
        if isinstance(error, ssl.SSLCertVerificationError):
            return (f"the scheduler's certificate is not signed by the CA this client trusts (--tls-ca-file): "
                    f"{error.verify_message}")
    text = " ".join(str(error) for error in chain)
    alert = next((a for a in ("UNKNOWN_CA", "BAD_CERTIFICATE", "CERTIFICATE_REQUIRED") if a in text), None)
    # the scheduler's alert may come as an alert, or as the connection closed after the handshake
    if alert or any(isinstance(e, (ssl.SSLEOFError, ssl.SSLZeroReturnError)) for e in chain):
        return (f"the scheduler refused this client's certificate ({alert or 'it closed the TLS connection'}): "
                "it must be signed by a CA the scheduler trusts (its --tls-ca-file)")
    tls = next((e for e in chain if isinstance(e, ssl.SSLError)), None)
    return f"TLS failed: {tls}" if tls is not None else str(exc)
