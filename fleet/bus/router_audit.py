"""What a run's router refused, counted from Zenoh's own log of its access control.

Zenoh keeps no count of the messages its access control refuses; it logs each decision (at trace level, under
`zenoh::net::routing::interceptor`) and each connection that fails its TLS handshake (`zenoh_link_tls`). The
router process sends that log (Zenoh writes it to standard output), and only it, to files of its own
(`RouterAudit.start`, before its session opens; Python's own output keeps going to its log), counted as it goes:
a message refused is an "is unauthorized to <Action> (ingress) on <key>" decision, or a "Using cached result:"
one, followed on the same thread by "Msg intercepted!". The decisions the router works out for its cache when a
key is first declared (after "caching permissions for `<key>`") are about no message and are never counted."""

from __future__ import annotations

import os
import re
import sys
import threading
from collections import Counter
from pathlib import Path

import zenoh

AUDIT_FILTER = "error,zenoh::net::routing::interceptor=trace,zenoh_link_tls=warn"
ROTATE_S = 5.0  # wall seconds between switches of the log file
MAX_KINDS = 50  # distinct refusals named in the count; the rest are summed under "other"
_ANSI = re.compile(rb"\x1b\[[0-9;]*m")
_DECISION = re.compile(  # "<zid> on <subject> is ..." decided now, "Using cached result: <zid> is ..." from the cache
    rb"ThreadId\((\d+)\).*?access_control: (?:Using cached result: )?(\w+)(?: on (\S+))? is (un)?authorized to"
    rb" ([A-Za-z/ ]+) \((ingress|egress)\) on (\S+)"
)
_CACHING = re.compile(
    rb"ThreadId\((\d+)\).*?access_control: ACL \((?:ingress|egress)\): caching permissions for `([^`]*)`"
)
_LOGIN = re.compile(rb"Username\(([^)]*)\)")
_INTERCEPTED = re.compile(rb"ThreadId\((\d+)\) zenoh::net::routing::interceptor: Msg intercepted!")
_TLS_REFUSED = re.compile(rb" (?:WARN|ERROR) .*zenoh_link_tls::unicast: (.*)")


class RouterAudit:
    """The router process's Zenoh log, counted into what was refused as it goes. The log alternates between two
    files (`path` and `path.1`) every `ROTATE_S`: the one just left is counted and emptied, so the files stay small
    however long the run."""

    def __init__(self, path: str | Path) -> None:
        self.paths = (Path(path), Path(f"{path}.1"))
        self.writing = 0
        self.tally = RefusalTally()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Send this process's native output stream (Zenoh logs to standard output) to the log and turn on Zenoh's
        access control log; Python's `sys.stdout` stays where it was. Call once, before the router's session
        opens."""
        sys.stdout.flush()
        sys.stdout = os.fdopen(os.dup(1), "w", buffering=1, closefd=True)
        self._write_to(0)
        os.environ["RUST_LOG"] = AUDIT_FILTER
        zenoh.init_log_from_env_or(AUDIT_FILTER)
        self._thread = threading.Thread(target=self._rotate_every, name="router-audit", daemon=True)
        self._thread.start()

    def _write_to(self, which: int) -> None:
        fd = os.open(self.paths[which], os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o600)
        os.dup2(fd, 1)
        os.close(fd)
        self.writing = which

    def _rotate_every(self) -> None:
        while not self._stop.wait(ROTATE_S):
            self.rotate()

    def rotate(self) -> None:
        """Log to the other file from now on; count the one left (a line Zenoh was writing at the switch may still
        land in it, and is counted at the next switch)."""
        left = self.writing
        self._write_to(1 - left)
        try:
            text = self.paths[left].read_bytes()
        except OSError:
            return
        self.tally.feed(_ANSI.sub(b"", text).splitlines())

    def refused(self) -> dict[str, int]:
        """Refused messages by "<login>: <action> on <key>", and connections refused at the TLS handshake."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self.rotate()
        self.rotate()
        return self.tally.counts_named()


class RefusalTally:
    """Refusals in Zenoh's log lines, fed in order (see the module's docstring for what counts). Per thread, the
    latest decision about a message is kept until "Msg intercepted!" says whether it stopped one; the decisions of a
    cache being worked out (on the cached key, after its "caching permissions" line) are about no message."""

    def __init__(self) -> None:
        self.counts: Counter = Counter()
        self.decided: dict[bytes, str | None] = {}  # thread -> its latest decision about a message: a refusal, or None
        self.caching: dict[bytes, bytes] = {}  # thread -> the key whose cache it is working out
        self.logins: dict[bytes, str] = {}  # a session's Zenoh id -> its login, from the decisions that name both

    def feed(self, lines: list[bytes]) -> None:
        for line in lines:
            if b"authorized" in line and (m := _DECISION.search(line)):
                self._decision(*m.groups())
            elif b"caching permissions" in line and (m := _CACHING.search(line)):
                thread, key = m.groups()
                self.caching[thread], self.decided[thread] = key, None
            elif b"intercepted" in line and (m := _INTERCEPTED.search(line)):
                thread = m.group(1)
                self.caching.pop(thread, None)
                if (what := self.decided.pop(thread, None)) is not None:
                    self.counts[what] += 1
            elif b"zenoh_link_tls" in line and _TLS_REFUSED.search(line):
                self.counts["connections refused at the TLS handshake"] += 1

    def _decision(
        self, thread: bytes, zid: bytes, subject: bytes | None, un: bytes | None, action: bytes, flow: bytes, key: bytes
    ) -> None:
        if subject is not None:
            login = _LOGIN.search(subject)
            self.logins[zid] = login.group(1).decode() if login and login.group(1) else "no login"
            if self.caching.get(thread) == key:
                return  # a decision for the cache of the key being declared: about no message
        self.caching.pop(thread, None)
        refused = un is not None and flow == b"ingress"
        login = self.logins.get(zid, f"session {zid.decode()}")
        self.decided[thread] = f"{login}: {action.decode().lower()} on {key.decode()}" if refused else None

    def counts_named(self) -> dict[str, int]:
        """The counts, the `MAX_KINDS` commonest by name and the rest as "other"."""
        named = dict(self.counts.most_common(MAX_KINDS))
        other = sum(self.counts.values()) - sum(named.values())
        return named | ({"other": other} if other else {})
