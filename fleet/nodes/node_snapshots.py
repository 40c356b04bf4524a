"""A node whose state goes into a run's snapshot (the arm controller, the coordinator): written without its live
handles, and put back (also by the node that wrote it: it goes on exactly as a node restored from it will)."""

from __future__ import annotations

from fleet.snapshot.process_state import capture, restore


class SnapshotNode:
    """Mixed into a node with `_decoders`, `drops` and a `snapshot_link`; `SNAPSHOT_LIVE` names its live handles."""

    SNAPSHOT_LIVE: tuple[str, ...] = ()

    def capture_state(self) -> bytes:
        """This node's state (put it back with `restore_state`: the node that wrote it goes on from it too); its
        scene written by name, so a node restored into one with a field set otherwise reads that."""
        return capture(self, self.SNAPSHOT_LIVE, self._live())

    def restore_state(self, state: bytes) -> None:
        """Put back a state from `capture_state` (this process's bus handles stay; its decoders count into the
        drop counter put back)."""
        restore(self, state, self._live())
        for decoder in self._decoders.values():
            decoder.drops = self.drops
        self.snapshot_link.use_drops(self.drops)
        self.after_restore()

    def _live(self) -> dict:
        return {"scene": self.scene} if hasattr(self, "scene") else {}

    def after_restore(self) -> None:
        """What a node sets afresh after its state is put back (wall-clock stamps)."""
