"""`fleet allocators`: the allocators a line can run with, built in and installed as plug-ins."""

from __future__ import annotations

import argparse

from rich.table import Table

from fleet.cli.errors import UsageError, out


def allocator_spec(text: str) -> str:
    """An `--allocator` value that names an allocator which loads (argparse's `type` cannot say why: one line)."""
    from coordinator.allocator_plugins import AllocatorError, check_allocator

    try:
        return check_allocator(text)
    except AllocatorError as exc:
        raise UsageError(str(exc)) from None


def cmd_allocators(args: argparse.Namespace) -> int:
    from coordinator.allocator_plugins import ENTRY_POINT_GROUP, describe, known_allocators

    table = Table("name", "from", "what it does")
    for source in known_allocators().values():
        table.add_row(source.name, source.origin, describe(source))
    out.print(table)
    out.print(
        f"plug-ins: an installed package's entry point in `{ENTRY_POINT_GROUP}`, or --allocator package.module:Name; "
        "a trained policy: --allocator policy:FILE (docs/allocators.md)",
        markup=False,
        highlight=False,
    )
    return 0


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("allocators", help="list the allocators a line can run with (built-ins and plug-ins)")
    p.set_defaults(func=cmd_allocators)
