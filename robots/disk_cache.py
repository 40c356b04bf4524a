"""Where clawfleet keeps what it works out once and reads ever after (reach tables, measured reaches), and the hash
that names a file after everything its content depends on, so a changed input finds a file of its own.

`CLAWFLEET_CACHE_DIR` says where (default `$XDG_CACHE_HOME/clawfleet`, else `~/.cache/clawfleet`); `off` keeps
nothing on disk.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import importlib
import os
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import IO, TYPE_CHECKING

import numpy as np
import pinocchio

if TYPE_CHECKING:
    from robots.spec import RobotSpec


CACHE_DIR_ENV = "CLAWFLEET_CACHE_DIR"


def cache_dir(kind: str) -> Path | None:
    """The folder that keeps one kind of worked-out data (`reach`, `robots`), or None when `CLAWFLEET_CACHE_DIR=off`."""
    chosen = os.environ.get(CACHE_DIR_ENV, "")
    if chosen == "off":
        return None
    if chosen:
        return Path(chosen) / kind
    home = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(home) / "clawfleet" / kind


def declaration_key(spec: RobotSpec, modules: Iterable[str], *extra: object, ignoring: tuple[str, ...] = ()) -> str:
    """A hash of a robot's declaration (less the fields `ignoring` names) and URDF, the source of the modules that
    compute from them, NumPy's and Pinocchio's versions and `extra` (reprs, or arrays by their bytes): what a file
    of worked-out data is named by."""
    h = hashlib.sha256()
    for f in dataclasses.fields(spec):
        if f.name in ignoring:
            continue
        value = getattr(spec, f.name)
        if not callable(value):
            h.update(f"{f.name}={value!r};".encode())
    h.update(spec.urdf_text().encode())
    h.update(repr((np.__version__, pinocchio.__version__)).encode())
    for name in modules:
        h.update(Path(importlib.import_module(name).__file__).read_bytes())
    for value in extra:
        h.update(value.tobytes() if isinstance(value, np.ndarray) else repr(value).encode())
    return h.hexdigest()[:24]


def replace_atomically(path: Path, write: Callable[[IO[bytes]], object], suffix: str = ".tmp") -> None:
    """Write a cache file through `write` into a temporary file beside `path`, then put it in `path`'s place in one
    step: a reader never sees half of it, and a failed write leaves no temporary file behind."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=suffix)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
