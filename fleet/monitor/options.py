"""The monitor's flags and address policy, kept free of Viser so the CLI stays quick to start."""

from __future__ import annotations

import argparse

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8080
DEFAULT_RATE_HZ = 20.0  # page updates per second: smooth enough to the eye, cheap for the line
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")


def add_monitor_arguments(parser: argparse.ArgumentParser) -> None:
    """The page's flags, shared by `fleet run --monitor` and `fleet monitor`."""
    parser.add_argument(
        "--host",
        default=DEFAULT_HOST,
        help="address the page listens on (default 127.0.0.1; any other is reachable by others)",
    )
    parser.add_argument(
        "--port",
        type=int,
        default=DEFAULT_PORT,
        help="HTTP port of the page (default 8080; the next free one if taken)",
    )


def exposure_warning(host: str) -> str | None:
    """A warning for any address but loopback: whoever reaches the page can stop the line."""
    if host in LOOPBACK_HOSTS or host.startswith("127."):
        return None
    return (
        f"warning: the monitor listens on {host}: whoever can reach that address can pause and emergency-stop the line"
    )
