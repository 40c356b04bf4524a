"""ROS messages built and serialised in a forked process while the recorder builds others: once a lockstep line
is over, both cores are free and the recorder's held backlog is what the run still waits on.

Forked (not spawned), so the child has the makers (closures over decoded bus messages and the arms' Pinocchio
models) without pickling them, and only CDR bytes come back; the recorder forks only where it holds no bus
session (it reads the sim's spool), so no Zenoh thread is forked.
"""

from __future__ import annotations

import multiprocessing
import signal
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor

from fleet.common.processes import die_with_parent
from fleet.record.ros_types import serialize

SLICES = 4  # the child's share comes back in this many pieces


def serialized(make: Callable[[], object]) -> tuple[str, bytes]:
    """(ROS type name, CDR bytes) of the message `make` builds."""
    message = make()
    return message.__msgtype__, serialize(message)


class LaterInChild:
    """`makers[split:]` built and serialised in a forked process while the caller builds the rest; `collect()`
    gives them back a slice at a time, in order. Use in a `with` block: the child is gone on leaving it."""

    def __init__(self, makers: list[Callable[[], object]], split: int, slices: int = SLICES) -> None:
        self._later: deque[Future] = deque()
        self._executor = None
        # the makers reach the child as the fork's initializer arguments: inherited, not pickled
        if split < len(makers):
            fork = multiprocessing.get_context("fork")
            self._executor = ProcessPoolExecutor(1, mp_context=fork, initializer=_child_start, initargs=(makers,))
            step = max(1, -(-(len(makers) - split) // slices))
            self._later.extend(
                self._executor.submit(_serialize_slice, a, min(a + step, len(makers)))
                for a in range(split, len(makers), step)
            )

    def __enter__(self) -> LaterInChild:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._executor is not None:
            self._executor.shutdown(cancel_futures=True)

    def collect(self) -> list[tuple[str, bytes]]:
        """The next slice of the child's share, in order (each comes as soon as it is built: the caller writes one
        while the child builds the next)."""
        if not self._later:
            raise RuntimeError("nothing more is built in the child")
        return self._later.popleft().result()


_CHILD_MAKERS: list[Callable[[], object]] = []  # in the forked child only: what it builds


def _child_start(makers: list[Callable[[], object]]) -> None:
    """The child keeps the makers, outlives no recorder, and only the recorder stops it: a stop said to the
    recorder's process group (Ctrl-C, the launcher's SIGTERM while the backlog is written) must not take the
    child's half with it."""
    global _CHILD_MAKERS
    _CHILD_MAKERS = makers
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(signal.SIGKILL)


def _serialize_slice(start: int, stop: int) -> list[tuple[str, bytes]]:
    return [serialized(make) for make in _CHILD_MAKERS[start:stop]]
