"""Lines a node writes to its log that its user must see on `fleet run`'s terminal (a plug-in allocator's fault is
said by the coordinator, whose output goes to its log): read as they are written, each passed on once."""

from __future__ import annotations

from pathlib import Path


class LogRelay:
    """The new lines of a log file that start with one of `prefixes`, since the last call."""

    def __init__(self, path: Path, prefixes: tuple[str, ...]) -> None:
        self.path, self.prefixes = Path(path), prefixes
        self._offset = 0
        self._partial = b""

    def new_lines(self) -> list[str]:
        """The matching lines written since the last call (a log started afresh is read from its start)."""
        try:
            size = self.path.stat().st_size
        except OSError:
            return []
        if size < self._offset:  # the file was started afresh (a respawned node)
            self._offset, self._partial = 0, b""
        if size == self._offset:
            return []
        with open(self.path, "rb") as f:
            f.seek(self._offset)
            data = self._partial + f.read(size - self._offset)
        self._offset = size
        *whole, self._partial = data.split(b"\n")
        lines = (line.decode("utf-8", "replace").rstrip() for line in whole)
        return [line for line in lines if line.startswith(self.prefixes)]
