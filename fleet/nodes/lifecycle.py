"""What every node process does the same way: stop on SIGTERM/SIGINT, die with its parent, report at exit.

A node started by `fleet run` must never outlive the launcher, even when the
launcher is killed with SIGKILL: on Linux the kernel sends the node SIGTERM when
its parent dies (prctl PR_SET_PDEATHSIG); elsewhere `should_stop` notices the
parent change within one loop.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import signal
import sys
from pathlib import Path

from scenes.loader import SceneError, load_scene
from scenes.schema import Scene

PR_SET_PDEATHSIG = 1


class StopFlag:
    """Set by SIGTERM or SIGINT (and by the parent's death); loops poll `should_stop`."""

    def __init__(self, watch_parent: bool = True) -> None:
        self.reason = ""
        self._parent = os.getppid() if watch_parent else None
        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, self._on_signal)
        if watch_parent and sys.platform.startswith("linux"):
            try:
                ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
            except (OSError, AttributeError):
                pass

    def _on_signal(self, signum: int, _frame: object) -> None:
        self.reason = signal.Signals(signum).name

    def should_stop(self) -> bool:
        if not self.reason and self._parent is not None and os.getppid() != self._parent:
            self.reason = "parent exited"
        return bool(self.reason)


def add_scene_arguments(parser: argparse.ArgumentParser, run_required: bool = True) -> None:
    """The scene and run flags every node takes."""
    parser.add_argument("--scene", default="assembly_line", help="bundled scene name or scene file")
    parser.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    parser.add_argument("--run", required=run_required, help="run id: keeps several lines on one Zenoh network apart")


def load_node_scene(args: argparse.Namespace, prog: str) -> Scene | None:
    """The node's scene, or None after printing one line naming the file, field and reason."""
    try:
        return load_scene(args.scene, arms=args.arms)
    except SceneError as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return None


def write_text_atomically(path: str, text: str) -> None:
    """Write a file so that a reader never sees half of it."""
    target = Path(path)
    tmp = target.with_suffix(target.suffix + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, target)


def write_report(path: str | None, report: dict) -> None:
    """Write a node's end-of-run figures as JSON."""
    if path:
        write_text_atomically(path, json.dumps(report, indent=1, sort_keys=True))
