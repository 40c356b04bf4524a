"""The monitor's flags and address policy, kept free of Viser so the CLI stays quick to start."""

from __future__ import annotations

import argparse
import ipaddress
import re

from fleet.bus.session import is_loopback_host

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8080
DEFAULT_RATE_HZ = 20.0  # page updates per second: smooth enough to the eye, cheap for the line


HOST_NAME = re.compile(
    r"^(?=.{1,253}$)[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?(?:\.[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*$"
)


def page_host(text: str) -> str:
    """A `--host` value: an IP address or a host name (argparse's `type`; nothing is looked up)."""
    try:
        ipaddress.ip_address(text)
        return text
    except ValueError:
        pass
    if not HOST_NAME.match(text):
        raise argparse.ArgumentTypeError(f"{text!r} is neither an IP address nor a host name")
    return text


def add_monitor_arguments(parser: argparse.ArgumentParser) -> None:
    """The page's flags, shared by `fleet run --monitor` and `fleet monitor`."""
    parser.add_argument(
        "--host",
        default=DEFAULT_HOST,
        type=page_host,
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
    if is_loopback_host(host):
        return None
    return (
        f"warning: the monitor listens on {host}: whoever can reach that address can pause and emergency-stop the line"
    )
