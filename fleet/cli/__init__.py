"""The `fleet` command line: one module per command group, each building its own sub-parser.

Errors a user can cause (a bad scene, an unknown robot, a missing extra) end
with one readable line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

from fleet.run.node_factory import close_kept_factory, keep_factory, kept_factory

GROUPS = ("run", "record", "sweep", "allocators", "monitor", "ros", "twin", "scenes", "robots", "bench")


class OneLineParser(argparse.ArgumentParser):
    """argparse, but a usage error is one line (what is wrong, and where the help is), not the whole usage."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="fleet", description="clawfleet: several claw arms sharing one assembly line")
    sub = parser.add_subparsers(dest="command", required=True)
    for group in GROUPS:
        importlib.import_module(f"fleet.cli.{group}").add_parsers(sub)
    return parser


def starts_a_line(argv: Sequence[str]) -> bool:
    """Whether the command line is a `fleet run` (not its help): its node factory may start before the rest."""
    return bool(argv) and argv[0] == "run" and not {"-h", "--help"} & set(argv)


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    ahead = starts_a_line(argv) and kept_factory() is None  # a caller's kept factory (a test session) serves as is
    if ahead:  # the factory imports the nodes' modules (~0.8 s) while this process imports and checks the rest
        keep_factory()
    try:
        return _command(argv)
    finally:
        if ahead:
            close_kept_factory()


def _command(argv: Sequence[str]) -> int:
    from fleet.cli.errors import user_errors

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
