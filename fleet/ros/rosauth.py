"""rosbridge's authentication (the `auth` op, rosauth's MAC scheme): a trusted party that holds the server's secret
gives a client a MAC for its address, the server's address, a random string, the time and an end time; the server
checks it before taking any other request. Needed beyond loopback, where anyone on the network could connect."""

from __future__ import annotations

import hashlib
import hmac
import time
from dataclasses import dataclass

MAX_SKEW_S = 300.0  # how far a request's time may be from the server's clock


@dataclass(frozen=True)
class AuthRequest:
    mac: str
    client: str
    dest: str
    rand: str
    t: int
    level: str
    end: int


def _seconds(value: object, field: str) -> int:
    """A time as roslibpy and roslibjs send it: seconds, or {secs|sec, nsecs|nanosec}."""
    if isinstance(value, dict):
        value = value.get("secs", value.get("sec"))
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        raise ValueError(f"auth needs {field} as seconds")
    return int(value)


def auth_request(message: dict) -> AuthRequest:
    """The `auth` op's fields; ValueError naming the first one missing or of the wrong type."""
    fields = {}
    for name in ("mac", "client", "dest", "rand", "level"):
        if not isinstance(message.get(name), str):
            raise ValueError(f"auth needs {name!r} as a string")
        fields[name] = message[name]
    return AuthRequest(t=_seconds(message.get("t"), "t"), end=_seconds(message.get("end"), "end"), **fields)


def mac_of(secret: str, client: str, dest: str, rand: str, t: int, level: str, end: int) -> str:
    """rosauth's MAC: SHA-512 of the secret and the fields, in this order, as hex."""
    return hashlib.sha512(f"{secret}{client}{dest}{rand}{t}{level}{end}".encode()).hexdigest()


def auth_problem(request: AuthRequest, secret: str, client_ip: str, server_ip: str, now_s: float | None = None) -> str:
    """Why the request does not authenticate this connection ("" if it does)."""
    now = time.time() if now_s is None else now_s
    if request.client != client_ip or request.dest != server_ip:
        return f"the MAC is for {request.client} -> {request.dest}, this connection is {client_ip} -> {server_ip}"
    if abs(now - request.t) > MAX_SKEW_S:
        return "the request's time is too far from the server's clock"
    if request.end < now:
        return "the session's end time has passed"
    expected = mac_of(secret, request.client, request.dest, request.rand, request.t, request.level, request.end)
    return "" if hmac.compare_digest(expected, request.mac) else "the MAC does not match"
