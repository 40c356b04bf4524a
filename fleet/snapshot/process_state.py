"""One process's state as bytes and back: every attribute of its node object but the live handles (bus sessions,
publishers, queues, the physics), pickled.

Objects a state merely points at that belong to the running process (the physics world, its arms, the node itself)
are written as names and found again by name on restore (`live`), so a restored tracker points at the new process's
world rather than at a copy of the old one.
"""

from __future__ import annotations

import io
import pickle
from collections.abc import Iterable, Mapping


class StateError(RuntimeError):
    """A process's state that cannot be written or read back; the message is one line."""


class _Pickler(pickle.Pickler):
    def __init__(self, file: io.BytesIO, live: Mapping[str, object]) -> None:
        super().__init__(file, protocol=pickle.HIGHEST_PROTOCOL)
        self._names = {id(obj): name for name, obj in live.items()}

    def persistent_id(self, obj: object) -> str | None:
        return self._names.get(id(obj))


class _Unpickler(pickle.Unpickler):
    def __init__(self, file: io.BytesIO, live: Mapping[str, object]) -> None:
        super().__init__(file)
        self._live = live

    def persistent_load(self, pid: str) -> object:
        if pid not in self._live:
            raise StateError(f"the state names {pid!r}, which this process does not have")
        return self._live[pid]


def capture(owner: object, keep: Iterable[str], live: Mapping[str, object] | None = None) -> bytes:
    """`owner`'s attributes but those named in `keep` (its live handles), pickled; objects of `live` by name."""
    kept = set(keep)
    state = {name: value for name, value in vars(owner).items() if name not in kept}
    out = io.BytesIO()
    try:
        _Pickler(out, live or {}).dump(state)
    except (pickle.PicklingError, TypeError, AttributeError) as exc:
        bad = [name for name, value in state.items() if not _pickles(value, live or {})]
        raise StateError(f"cannot snapshot {type(owner).__name__} (attributes {', '.join(bad) or '?'}): {exc}") from exc
    return out.getvalue()


def restore(owner: object, blob: bytes, live: Mapping[str, object] | None = None) -> None:
    """Put a state from `capture` back into `owner` (its live handles stay as they are)."""
    vars(owner).update(read_state(blob, live, type(owner).__name__))


def read_state(blob: bytes, live: Mapping[str, object] | None = None, owner: str = "a process") -> dict:
    """A state from `capture` as its attributes by name (objects of `live` found by name), without an owner: what
    another front end takes of it (an env episode from a line's snapshot)."""
    try:
        return _Unpickler(io.BytesIO(blob), live or {}).load()
    except StateError:
        raise
    except Exception as exc:  # noqa: BLE001 - any fault of a foreign blob is one line
        raise StateError(f"cannot read back the state of {owner}: {exc}") from exc


def _pickles(value: object, live: Mapping[str, object]) -> bool:
    try:
        _Pickler(io.BytesIO(), live).dump(value)
    except Exception:  # noqa: BLE001
        return False
    return True
