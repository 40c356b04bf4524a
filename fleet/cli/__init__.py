"""The `fleet` command line: one module per command group, each building its own sub-parser.

Errors a user can cause (a bad scene, an unknown robot, a missing extra) end
with one readable line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from fleet.cli import allocators, bench, monitor, record, robots, ros, run, scenes, sweep
from fleet.cli.errors import user_errors

GROUPS = (run, record, sweep, allocators, monitor, ros, scenes, robots, bench)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fleet", description="clawfleet: several claw arms sharing one assembly line")
    sub = parser.add_subparsers(dest="command", required=True)
    for group in GROUPS:
        group.add_parsers(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except user_errors() as exc:
        print(f"fleet: error: {exc}", file=sys.stderr)
        return 2
    except RuntimeError as exc:  # a run that could not start (the launcher's RunError), a failed benchmark
        print(f"fleet: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("fleet: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader went away (`fleet check X | head -1`): nothing more to say, to anyone
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # Python's flush at exit must not fail again
        return 141


if __name__ == "__main__":
    sys.exit(main())
