"""The one place that opens Zenoh sessions: peer mode, no multicast scouting, loopback endpoints by default.

Every fleet program takes the same flags (`--listen`, `--connect`,
`--zenoh-config`) through `add_bus_arguments`, and opens its session with
`open_session(BusEndpoints.from_args(args))` in a `with` block, so the session
is always closed and its port freed.
"""

from __future__ import annotations

import argparse
import contextlib
import ipaddress
import json
import re
import socket
import threading
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import zenoh

LOOPBACK = "127.0.0.1"


def is_loopback_host(host: str) -> bool:
    """Whether a listening address is this host's loopback (127.0.0.0/8, ::1, `localhost`): nobody else reaches it."""
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host == "localhost"


def free_loopback_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((LOOPBACK, 0))
        return s.getsockname()[1]


def loopback_endpoint(port: int) -> str:
    return f"tcp/{LOOPBACK}:{port}"


@dataclass(frozen=True)
class BusEndpoints:
    """Where a session listens and whom it connects to; an optional Zenoh config file underneath."""

    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    config_file: str | None = None

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> BusEndpoints:
        return cls(tuple(args.listen or ()), tuple(args.connect or ()), args.zenoh_config)

    def client_argv(self) -> list[str]:
        """The flags that make a node join as these endpoints' client: its connects and config file (not where
        to listen)."""
        argv = [flag for ep in self.connect for flag in ("--connect", ep)]
        return argv + (["--zenoh-config", self.config_file] if self.config_file else [])


ENDPOINT_FORM = re.compile(r"^(tcp|udp|tls|quic|ws|unixsock-stream)/[^\s/]+(:\d{1,5})?$")


def endpoint(text: str) -> str:
    """An endpoint flag's value, checked for Zenoh's form `<protocol>/<address>:<port>` (argparse's `type`)."""
    if not ENDPOINT_FORM.match(text):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not an endpoint: give <protocol>/<address>:<port>, e.g. tcp/127.0.0.1:7447"
        )
    return text


def add_bus_arguments(parser: argparse.ArgumentParser) -> None:
    """The bus flags every fleet program shares."""
    group = parser.add_argument_group("bus (Zenoh)")
    group.add_argument(
        "--listen",
        action="append",
        type=endpoint,
        metavar="ENDPOINT",
        help="endpoint to listen on, e.g. tcp/127.0.0.1:7447 (repeatable)",
    )
    group.add_argument(
        "--connect",
        action="append",
        type=endpoint,
        metavar="ENDPOINT",
        help="endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)",
    )
    group.add_argument(
        "--zenoh-config", metavar="FILE", help="a Zenoh JSON5 config file; --listen/--connect override its endpoints"
    )


def make_config(endpoints: BusEndpoints) -> zenoh.Config:
    """A Zenoh config: peer mode (or the config file's), multicast scouting off, and only the given endpoints
    (loopback if none)."""
    config = zenoh.Config.from_file(endpoints.config_file) if endpoints.config_file else zenoh.Config()
    # a config file's mode stands (a line across hosts: the sim a router, the rest clients)
    if not endpoints.config_file:
        config.insert_json5("mode", json.dumps("peer"))
    config.insert_json5("scouting/multicast/enabled", "false")
    # every sample carries its publisher's HLC time: a recorder puts what it hears back in publish order
    config.insert_json5("timestamping/enabled", json.dumps({"router": True, "peer": True, "client": True}))
    listen = list(endpoints.listen)
    if not listen and not endpoints.config_file:
        listen = [loopback_endpoint(0)]  # an OS-chosen port, never every interface
    if listen:
        config.insert_json5("listen/endpoints", json.dumps(listen))
    if endpoints.connect or not endpoints.config_file:
        config.insert_json5("connect/endpoints", json.dumps(list(endpoints.connect)))
    return config


@contextlib.contextmanager
def open_session(endpoints: BusEndpoints) -> Iterator[zenoh.Session]:
    """An open Zenoh session, closed on leaving the block (also on errors)."""
    session = zenoh.open(make_config(endpoints))
    try:
        yield session
    finally:
        session.close()


def open_listening_session(endpoints: BusEndpoints, attempts: int = 5) -> tuple[zenoh.Session, str]:
    """A session listening on a free loopback port it picked itself, and that endpoint.

    A port found free can be taken (by another program's outgoing connection) before Zenoh
    binds it; on such a clash another port is tried.
    """
    for attempt in range(attempts):
        endpoint = loopback_endpoint(free_loopback_port())
        try:
            return zenoh.open(
                make_config(BusEndpoints((endpoint,), endpoints.connect, endpoints.config_file))
            ), endpoint
        except zenoh.ZError as exc:
            if "already in use" not in str(exc) or attempt == attempts - 1:
                raise
    raise AssertionError("unreachable")


class Hold:
    """Holds back what arrives at a node's inboxes after a mark (`start`) until `release`, then queues it in arrival
    order: a node asked for its state as of a tick boundary (a run's snapshot) writes it while the line goes on, and
    what the line sent after that boundary waits. `keeps(key, payload, mark)` says which arrivals are from after
    the mark (each subscriber's callback runs on a thread of its own, so one sent before the mark may arrive after
    it: those pass)."""

    def __init__(self, keeps: Callable[[str, bytes, object], bool]) -> None:
        self._keeps = keeps
        self._lock = threading.Lock()
        self._held: list[tuple[Inbox, tuple[str, bytes]]] | None = None
        self._mark: object = None

    def start(self, mark: object) -> None:
        """Hold what `keeps` says is from after `mark`."""
        with self._lock:
            if self._held is None:
                self._held = []
            self._mark = mark

    @property
    def holding(self) -> bool:
        return self._held is not None

    def put(self, inbox: Inbox, item: tuple[str, bytes]) -> None:
        """Queue `item` in `inbox`, or hold it there if it is from after the mark."""
        with self._lock:
            if self._held is not None and self._keeps(item[0], item[1], self._mark):
                self._held.append((inbox, item))
            else:
                inbox.items.append(item)

    def release(self) -> None:
        """Everything held queued in its inbox, in arrival order, and the owners woken."""
        with self._lock:
            held, self._held, self._mark = self._held or [], None, None
            for inbox, item in held:
                inbox.items.append(item)
        for inbox in {id(i): i for i, _ in held}.values():
            inbox.wake.set()


@dataclass
class Inbox:
    """A subscriber callback that only queues raw payloads and wakes the owner; the owner's loop drains them.

    Several inboxes may share one `wake` event, so a node sleeps until any of them has work
    instead of polling. Inboxes sharing a `hold` are held back together (`Hold`).
    """

    items: deque = field(default_factory=deque)
    wake: threading.Event = field(default_factory=threading.Event)
    hold: Hold | None = None

    def __call__(self, sample: zenoh.Sample) -> None:
        item = (str(sample.key_expr), sample.payload.to_bytes())
        if self.hold is None:
            self.items.append(item)  # deque.append is thread-safe
        else:
            self.hold.put(self, item)
        self.wake.set()

    def wait(self, timeout_s: float) -> None:
        """Sleep until something arrives in this inbox (or any sharing its event), at most `timeout_s`."""
        self.wake.wait(timeout_s)
        self.wake.clear()

    def drain(self) -> list[tuple[str, bytes]]:
        """Everything queued so far, oldest first."""
        out = []
        while self.items:
            out.append(self.items.popleft())
        return out


class Tap:
    """Subscribers whose samples queue inside Zenoh (no Python callback per sample: a busy reader never slows the
    publishers), drained in batches in publish order (their HLC timestamps). Use in a `with` block."""

    ended = False  # a bus has no end of its own (a spool has: `SpoolReader.ended`); its reader's stop ends it

    def __init__(self, session: zenoh.Session, key_exprs: list[str], capacity: int = 1 << 16) -> None:
        self._subs = [session.declare_subscriber(k, zenoh.handlers.FifoChannel(capacity)) for k in key_exprs]

    def __enter__(self) -> Tap:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self._subs = []

    def drain(self) -> list[tuple[str, bytes]]:
        """Everything queued so far as (key, payload), oldest publication first."""
        batch = []
        for sub in self._subs:
            while (sample := sub.try_recv()) is not None:
                stamp = sample.timestamp
                batch.append(
                    (
                        stamp.get_time_as_ntp64() if stamp is not None else 0,
                        len(batch),
                        str(sample.key_expr),
                        sample.payload.to_bytes(),
                    )
                )
        batch.sort()
        return [(key, payload) for _, _, key, payload in batch]
