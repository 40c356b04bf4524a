"""Where each node of `fleet run` starts: a hosts file names a network namespace (`ip netns`) per node.

    nodes:             # node -> network namespace; a node not named starts beside the launcher
      sim: simhost
      coordinator: coordhost
      arm_0: armhost

Nodes in other namespaces reach each other through the sim's router, so a hosts file goes with
`--bus-config` (`fleet/bus/bus_config.py`). Across real machines, start the nodes by hand there
with `--zenoh-config` (docs/running.md).
"""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, field_validator

from scenes.schema import is_valid_name
from scenes.yaml_file import DeclarationError, read_declaration, regular_file

MAX_HOSTS_FILE_BYTES = 64 * 1024
NETNS_DIR = Path("/run/netns")


class HostsFileError(DeclarationError):
    """A hosts file that cannot be used: the file, the field and why, on one line."""


class Hosts(BaseModel):
    """Node name -> the network namespace it runs in."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    nodes: dict[str, str]

    @field_validator("nodes")
    @classmethod
    def _names(cls, nodes: dict[str, str]) -> dict[str, str]:
        for node, netns in nodes.items():
            if not is_valid_name(netns.replace("-", "_")):
                raise ValueError(f"{node}: {netns!r} is not a network namespace name (letters, digits, _ and -)")
        return nodes

    def prefix(self, node: str) -> list[str]:
        """The command that starts a process in `node`'s namespace (empty: beside the launcher)."""
        netns = self.nodes.get(node)
        return ["ip", "netns", "exec", netns] if netns else []


def load_hosts(path: str, node_names: list[str]) -> Hosts:
    """The hosts file at `path`, its nodes checked against `node_names` and its namespaces against those that exist."""
    file = regular_file(Path(path), "hosts", HostsFileError)
    hosts = read_declaration(file, path, "hosts file", MAX_HOSTS_FILE_BYTES, Hosts, HostsFileError)
    for node, netns in hosts.nodes.items():
        if node not in node_names:
            raise HostsFileError(path, f"nodes.{node}", f"no such node; nodes: {', '.join(node_names)}")
        if not (NETNS_DIR / netns).exists():
            raise HostsFileError(path, f"nodes.{node}", f"no network namespace {netns!r} (ip netns add {netns})")
    return hosts
