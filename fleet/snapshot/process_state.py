"""The one error every process's saved state raises when it cannot be written or read back."""

from __future__ import annotations


class StateError(RuntimeError):
    """A process's state that cannot be written or read back; the message is one line."""
