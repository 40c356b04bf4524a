"""Which test file a worker runs next, chosen for what the other worker is running (pytest-xdist's
`pytest_xdist_make_scheduler`): the suite's locks (`tests/conftest.py`) let a wall-time test run beside light tests
only, and heavy tests beside each other, so a worker handed a heavy file while the other runs a wall-time one only
waits. Each worker writes the kind of every test it collected (`write_kinds`); the scheduler reads them."""

from __future__ import annotations

import json
import os
from pathlib import Path

from xdist.scheduler import LoadFileScheduling

KINDS = ("light", "heavy", "wall", "alone")  # in the order of what each excludes beside it
# rough seconds a test of each kind takes, to start the longest files first (a long file last makes a long tail)
WEIGHT_S = {"light": 0.2, "heavy": 3.0, "wall": 4.0, "alone": 20.0}
# what a worker is best handed while the other runs a file of a kind: first the kind that runs beside it
PREFERENCE = {
    None: ("wall", "heavy", "light", "alone"),  # the wall-time files first, while light ones can run beside them
    "light": ("wall", "alone", "heavy", "light"),
    "heavy": ("heavy", "light", "wall", "alone"),
    "wall": ("light", "wall", "heavy", "alone"),
    "alone": ("light", "wall", "heavy", "alone"),
}


def write_kinds(folder: Path, worker: str, kinds: dict[str, str]) -> None:
    """Each collected test's kind (`KINDS`), by node id, for the scheduler (written whole, then renamed)."""
    partial = folder / f"kinds-{worker}.json.partial"
    partial.write_text(json.dumps(kinds))
    os.replace(partial, folder / f"kinds-{worker}.json")


def read_kinds(folder: Path) -> dict[str, str]:
    kinds: dict[str, str] = {}
    for path in sorted(folder.glob("kinds-*.json")):
        kinds |= json.loads(path.read_text())
    return kinds


class LockAwareScheduling(LoadFileScheduling):
    """A test file to a worker, as `--dist loadfile`, but the next file for a worker is of the kind that can run
    beside what the other worker runs (`PREFERENCE`), the longest of that kind first."""

    def __init__(self, config, log=None, folder: Path | None = None) -> None:
        super().__init__(config, log)
        self.folder = folder
        self._kinds: dict[str, str] | None = None

    def _scope_kind(self, work_unit: dict[str, bool]) -> str:
        kinds = self._kinds or {}
        return max((kinds.get(nodeid, "light") for nodeid in work_unit), key=KINDS.index)

    def _scope_weight(self, work_unit: dict[str, bool]) -> float:
        kinds = self._kinds or {}
        return sum(WEIGHT_S[kinds.get(nodeid, "light")] for nodeid in work_unit)

    def _running_beside(self, node) -> str | None:
        """The strongest kind among the files the other workers still have tests of (None: they have none)."""
        running = [
            self._scope_kind(unit)
            for other, units in self.assigned_work.items()
            if other is not node
            for unit in units.values()
            if not all(unit.values())
        ]
        return max(running, key=KINDS.index) if running else None

    def _assign_work_unit(self, node) -> None:
        """As `LoadScopeScheduling._assign_work_unit`, with the file chosen by `_running_beside`."""
        assert self.workqueue
        if self._kinds is None:
            self._kinds = read_kinds(self.folder) if self.folder is not None else {}
        by_kind: dict[str, list[str]] = {}
        for scope, unit in self.workqueue.items():
            by_kind.setdefault(self._scope_kind(unit), []).append(scope)
        kind = next(k for k in PREFERENCE[self._running_beside(node)] if k in by_kind)
        scope = max(by_kind[kind], key=lambda s: self._scope_weight(self.workqueue[s]))
        work_unit = self.workqueue.pop(scope)
        self.assigned_work.setdefault(node, {})[scope] = work_unit
        collection = self.registered_collections[node]
        node.send_runtest_some([collection.index(nodeid) for nodeid, done in work_unit.items() if not done])
