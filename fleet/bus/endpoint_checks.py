"""Bus flags that cannot work, found before any process starts: a `--listen` address this machine does not have (or
a port already taken), a `--connect` endpoint where nothing answers. Zenoh itself would fail late for the first
(inside the sim, with a Rust source location) and silently retry for ever for the second."""

from __future__ import annotations

import errno
import socket
import time

from fleet.bus.session import BusEndpoints

CONNECT_TIMEOUT_S = 2.0
TCP_CARRIED = ("tcp", "tls", "ws")  # protocols over TCP: a TCP connection says whether anything answers
UDP_CARRIED = ("udp", "quic")  # nothing answers a bare UDP probe: only the address is checked


class EndpointError(ValueError):
    """A bus flag that cannot work, in one line naming the flag and the endpoint."""


def check_endpoints(endpoints: BusEndpoints, wait_s: float = 0.0) -> None:
    """Every `--listen` endpoint one this machine can bind, every `--connect` endpoint one that answers (within
    `wait_s`, for a command that waits for its line to come up)."""
    for ep in endpoints.listen:
        check_listen(ep)
    for ep in endpoints.connect:
        await_connect(ep, wait_s)


def await_connect(ep: str, wait_s: float) -> None:
    """`check_connect`, tried again every 0.2 s until it passes or `wait_s` has passed."""
    deadline = time.monotonic() + wait_s
    while True:
        try:
            return check_connect(ep)
        except EndpointError as exc:
            if time.monotonic() >= deadline:
                raise EndpointError(f"{exc} (waited {wait_s:g} s)" if wait_s > 0 else str(exc)) from None
        time.sleep(0.2)


def split_endpoint(ep: str) -> tuple[str, str, int | None]:
    """An endpoint's protocol, host (or socket path) and port (None where it has none)."""
    protocol, _, rest = ep.partition("/")
    if protocol.startswith("unixsock"):
        return protocol, rest, None
    host, sep, port = rest.rpartition(":")
    if not sep:
        return protocol, rest, None
    return protocol, host.strip("[]"), int(port)


def _addresses(ep: str, flag: str, host: str, port: int, kind: socket.SocketKind) -> list[tuple]:
    try:
        return socket.getaddrinfo(host, port, type=kind)
    except socket.gaierror as exc:
        raise EndpointError(f"{flag} {ep}: no such host {host!r} ({exc.strerror})") from None


def check_listen(ep: str) -> None:
    """`ep` names an address of this machine and a port nothing else holds."""
    protocol, host, port = split_endpoint(ep)
    if port is None or protocol not in TCP_CARRIED + UDP_CARRIED:
        return
    kind = socket.SOCK_STREAM if protocol in TCP_CARRIED else socket.SOCK_DGRAM
    family, _, _, _, address = _addresses(ep, "--listen", host, port, kind)[0]
    with socket.socket(family, kind) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as Zenoh binds: a closing socket does not count
        try:
            s.bind(address)
        except OSError as exc:
            if exc.errno == errno.EADDRNOTAVAIL:
                raise EndpointError(f"--listen {ep}: this machine has no address {host}") from None
            if exc.errno == errno.EADDRINUSE:
                raise EndpointError(f"--listen {ep}: port {port} is taken (another line listening there?)") from None
            raise EndpointError(f"--listen {ep}: cannot listen there ({exc.strerror})") from None


def check_connect(ep: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Something accepts a connection at `ep` (over TCP, or its Unix socket); UDP endpoints are not probed."""
    protocol, host, port = split_endpoint(ep)
    try:
        if protocol.startswith("unixsock"):
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
                s.settimeout(timeout_s)
                s.connect(host)
        elif protocol in TCP_CARRIED and port is not None:
            with socket.create_connection((host, port), timeout=timeout_s):
                pass
    except socket.gaierror as exc:  # before OSError, of which it is one
        raise EndpointError(f"--connect {ep}: no such host {host!r} ({exc.strerror})") from None
    except TimeoutError:
        raise EndpointError(f"--connect {ep}: no answer within {timeout_s:g} s") from None
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise EndpointError(f"--connect {ep}: nothing answers there ({reason.lower()})") from None
