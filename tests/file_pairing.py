"""Which test file a worker takes next, so that the two workers' locks (tests/conftest.py) keep them both busy.

A wall-time file holds the `lines` lock alone: beside it the other worker can only run light tests, so light files
are kept for those moments. Files that run lines share the lock and pair with each other; a browser file runs alone
whatever the other does. pytest-xdist's own `loadfile` order (most tests first) left the workers waiting for each
other about 13 minutes of a 20-minute suite; this order hands a worker, by what the other worker runs now:

| the other runs | this one takes, first that is left |
|---|---|
| a wall-time file | light, wall-time, lines, alone |
| a light file | wall-time, lines, light, alone |
| lines, or nothing | alone, lines, light, wall-time |
| an alone file | lines, light, wall-time, alone |
"""

from __future__ import annotations

from collections.abc import Callable

from xdist.scheduler import LoadFileScheduling

ALONE, WALL, LINES, LIGHT = "alone", "wall", "lines", "light"
NEXT_BESIDE = {
    WALL: (LIGHT, WALL, LINES, ALONE),
    LIGHT: (WALL, LINES, LIGHT, ALONE),
    LINES: (ALONE, LINES, LIGHT, WALL),
    None: (ALONE, LINES, LIGHT, WALL),
    ALONE: (LINES, LIGHT, WALL, ALONE),
}


class PairedFileScheduling(LoadFileScheduling):
    """`loadfile` (a file to a worker at a time), choosing each next file by `NEXT_BESIDE`; `kind_of(file)` says
    what a file is (`ALONE`, `WALL`, `LINES` or `LIGHT`)."""

    def __init__(self, config, log, kind_of: Callable[[str], str]) -> None:
        super().__init__(config, log)
        self.kind_of = kind_of

    def _running(self, node) -> str | None:
        """The kind of the file `node` runs now (its first assigned file with a test not done), or None."""
        for scope, work_unit in self.assigned_work.get(node, {}).items():
            if not all(work_unit.values()):
                return self.kind_of(scope)
        return None

    def _assign_work_unit(self, node) -> None:
        others = [self._running(n) for n in self.assigned_work if n is not node]
        beside = next((kind for kind in others if kind is not None), None)
        scope = next_file({scope: self.kind_of(scope) for scope in self.workqueue}, beside)
        if scope is not None:
            self.workqueue.move_to_end(scope, last=False)  # the base class takes the queue's first
        super()._assign_work_unit(node)


def next_file(waiting: dict[str, str], beside: str | None) -> str | None:
    """Of the files `waiting` (file: kind, in the queue's order), the one to take beside a worker running `beside`."""
    for wanted in NEXT_BESIDE[beside]:
        for file, kind in waiting.items():
            if kind == wanted:
                return file
    return None
