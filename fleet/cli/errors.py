"""What every command shares: the errors a user causes (one line, exit 2), the consoles, output paths."""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

from rich.console import Console

from robots.registry import (
    MissingModelsError,
    UnknownRobotError,
)
from scenes.schema import MAX_SEED
from scenes.yaml_file import DeclarationError

out = Console()
err = Console(stderr=True)


class UsageError(ValueError):
    """A flag that cannot work: one line, exit 2, before anything starts."""


def user_errors() -> tuple[type[BaseException], ...]:
    """Errors a user causes: one line, exit 2 (a bad recording's only once the recording module is loaded: it imports
    mcap)."""
    errors: tuple[type[BaseException], ...] = (DeclarationError, UnknownRobotError, MissingModelsError, UsageError)
    recording = sys.modules.get("fleet.record.mcap_file")
    return errors + ((recording.RecordingError,) if recording else ())


def output_folder(flag: str, path: str, parents: bool = True) -> Path:
    """A folder to write results into, made if missing (with its parents, or refused when `parents` is False
    and the parent is missing); refused in one line when the path is a file."""
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{flag} {path}: exists and is not a folder")
    if not parents and not folder.parent.is_dir():
        raise UsageError(f"{flag} {path}: no folder {folder.parent}")
    try:
        folder.mkdir(parents=parents, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"{flag} {path}: cannot make the folder: {exc.strerror}") from None
    _can_write_in(flag, path, folder)
    return folder


def _can_write_in(flag: str, path: str, folder: Path) -> None:
    """Refused in one line unless a file can be made in `folder` (a read-only mount, no permission, a full disk
    show here, before any process starts)."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise UsageError(f"{flag} {path}: cannot write in {folder}: {exc.strerror}") from None


def writable_file(flag: str, path: str) -> Path:
    """A file path whose folder exists (refused in one line otherwise)."""
    target = Path(path)
    if target.is_dir():
        raise UsageError(f"{flag} {path}: is a directory; give a file name, e.g. run.mcap")
    if not target.parent.is_dir():
        raise UsageError(f"{flag} {path}: no folder {target.parent}")
    _can_write_in(flag, path, target.parent)
    return target


def positive_numbers(text: str, what: str) -> list[float]:
    """A flag's list of positive numbers separated by commas (argparse's `type`); `what` says what they are, with
    an example, in the one-line refusal."""
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        values = []
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: give {what}")
    return values


def seed_number(text: str) -> int:
    """An argparse type: a seed, a whole number from 0 to `MAX_SEED` (a signed 64-bit integer)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"a seed is a whole number from 0 to {MAX_SEED:,}")
    return value
