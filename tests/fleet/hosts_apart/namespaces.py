"""Hosts for a test: network namespaces joined by a bridge that lives in a namespace of its own.

Nothing of the machine's own network is touched: every interface and address is made inside
namespaces the test creates, and deleting them (on leaving the block) removes it all.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass

SUBNET = "10.77.0"  # inside the test's namespaces only


@dataclass(frozen=True)
class Host:
    netns: str
    address: str

    def run(self, *argv: str) -> list[str]:
        """`argv` as a command that runs on this host."""
        return ["ip", "netns", "exec", self.netns, *argv]


class NamespacesUnavailable(RuntimeError):
    """This machine does not let the test make network namespaces (not root, no `ip`)."""


def ip(*argv: str) -> None:
    done = subprocess.run(["ip", *argv], capture_output=True, text=True)
    if done.returncode != 0:
        raise NamespacesUnavailable(f"ip {' '.join(argv)}: {done.stderr.strip()}")


@contextlib.contextmanager
def hosts_on_one_switch(names: list[str]) -> Iterator[dict[str, Host]]:
    """One namespace per name, each with one interface (`eth0`, 10.77.0.N/24) on a bridge in a switch namespace."""
    tag = f"cf{os.getpid() % 100000}"
    made: list[str] = []
    try:
        switch = f"{tag}_switch"
        ip("netns", "add", switch)
        made.append(switch)
        ip("-n", switch, "link", "add", "br0", "type", "bridge")
        ip("-n", switch, "link", "set", "br0", "up")
        hosts = {}
        for n, name in enumerate(names, start=1):
            host = Host(f"{tag}_{name}", f"{SUBNET}.{n}")
            ip("netns", "add", host.netns)
            made.append(host.netns)
            ip("-n", host.netns, "link", "add", "eth0", "type", "veth", "peer", "name", f"port{n}", "netns", switch)
            ip("-n", host.netns, "addr", "add", f"{host.address}/24", "dev", "eth0")
            for link in ("lo", "eth0"):
                ip("-n", host.netns, "link", "set", link, "up")
            ip("-n", switch, "link", "set", f"port{n}", "master", "br0")
            ip("-n", switch, "link", "set", f"port{n}", "up")
            hosts[name] = host
        yield hosts
    finally:
        for netns in reversed(made):
            subprocess.run(["ip", "netns", "del", netns], capture_output=True)


def processes_in(netns: str) -> list[int]:
    """The pids running in a namespace (none should be left after a run)."""
    done = subprocess.run(["ip", "netns", "pids", netns], capture_output=True, text=True)
    return [int(p) for p in done.stdout.split()]
