"""The bus flags every command that joins a line shares (`--run-id`, `--listen`, `--connect`, `--zenoh-config`),
checked in one place: a flag that cannot work is one line before any process starts."""

from __future__ import annotations

import argparse
import math
import re
from pathlib import Path

from fleet.bus.endpoint_checks import EndpointError, check_endpoints
from fleet.bus.keys import Keys
from fleet.bus.session import BusEndpoints, make_config
from fleet.cli.errors import UsageError

MAX_WAIT_S = 24 * 3600.0  # a command waiting for its line: a day is already more than anyone means


def check_bus_flags(args: argparse.Namespace, run_id: str | None = None, wait_s: float = 0.0) -> None:
    """The run id a bus key can hold, a readable Zenoh config that Zenoh accepts, addresses this machine has to
    listen on, endpoints that answer to connect to (within `wait_s`: a command that waits for its line). `run_id`
    where the command's own differs from `--run-id`."""
    if not (math.isfinite(wait_s) and 0 <= wait_s <= MAX_WAIT_S):
        raise UsageError(f"--wait {wait_s:g}: give seconds from 0 to {MAX_WAIT_S:,.0f}")
    try:
        Keys(run_id if run_id is not None else args.run_id)
    except ValueError as exc:
        raise UsageError(f"--run-id: {exc}") from None
    if args.zenoh_config and not Path(args.zenoh_config).is_file():
        raise UsageError(f"--zenoh-config {args.zenoh_config}: not a readable file")
    endpoints = BusEndpoints.from_args(args)
    try:
        make_config(endpoints)
    except Exception as exc:  # zenoh's own parser: keep its message, not its source locations
        said = re.search(r'msg: "([^"]*)"', str(exc))
        text = re.sub(r"\s+at /\S+", "", said.group(1) if said else (str(exc).splitlines() or [type(exc).__name__])[0])
        raise UsageError(f"bus flags: {text}") from None
    try:
        check_endpoints(endpoints, wait_s)
    except EndpointError as exc:
        raise UsageError(str(exc)) from None
