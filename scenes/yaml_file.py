"""Reading a YAML declaration file (a scene, a robot): size and encoding checked, errors naming file and field."""

from __future__ import annotations

from pathlib import Path
from typing import TypeVar

import yaml
from pydantic import BaseModel, ValidationError

Model = TypeVar("Model", bound=BaseModel)
MAX_DEPTH = 16  # lists and mappings within each other: a scene needs 5


class DeclarationError(ValueError):
    """A declaration file that cannot be used: names the file, the field path and the reason, on one line."""

    def __init__(self, file: str, field: str, reason: str) -> None:
        self.file, self.field, self.reason = file, field, reason
        super().__init__(f"{file}: {field}: {reason}" if field else f"{file}: {reason}")


def regular_file(path: Path, what: str, error: type[DeclarationError] = DeclarationError) -> Path:
    """`path` if it is a regular file, else the error saying what it is instead."""
    if path.is_dir():
        raise error(str(path), "", f"a directory, not a {what} file")
    if path.exists() and not path.is_file():
        raise error(str(path), "", "not a regular file (a device or a pipe)")
    if not path.is_file():
        raise error(str(path), "", "no such file")
    return path


def named_in(declaring_file: Path, name: str) -> Path:
    """A file a declaration names (a scene's robot file, a robot file's URDF): as given if absolute, else relative
    to the declaring file's folder."""
    p = Path(name).expanduser()
    return p if p.is_absolute() else (Path(declaring_file).parent / p).resolve()


def yaml_text(
    path: Path, label: str, what: str, max_bytes: int, error: type[DeclarationError] = DeclarationError
) -> str:
    """The file's text: refused at once when larger than `max_bytes`, or when it is not UTF-8 (naming the byte)."""
    size = path.stat().st_size
    if size > max_bytes:
        raise error(label, "", f"{size:,} bytes: larger than a {what} can be ({max_bytes:,} bytes at most)")
    raw = path.read_bytes()
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(label, "", f"not UTF-8 text (byte {exc.start}: {raw[exc.start : exc.start + 1]!r})") from None


def yaml_mapping(
    path: Path, label: str, what: str, max_bytes: int, error: type[DeclarationError] = DeclarationError
) -> dict:
    """The file's top-level mapping of fields; one-line errors for size, encoding, YAML syntax and shape."""
    text = yaml_text(path, label, what, max_bytes, error)
    try:
        data = yaml.safe_load(text)
    except RecursionError:
        raise error(label, "", f"nested too deep: a {what} needs at most {MAX_DEPTH} levels") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else ""
        raise error(label, where, f"not valid YAML: {getattr(exc, 'problem', exc)}") from None
    if not isinstance(data, dict):
        raise error(label, "", f"a {what} file must hold a mapping of fields at its top level")
    deepest = _depth(data)
    if deepest > MAX_DEPTH:
        raise error(label, "", f"nested {deepest} levels deep: a {what} needs at most {MAX_DEPTH}")
    return data


def _depth(value: object, limit: int = 10 * 32) -> int:
    """How deeply lists and mappings nest in `value` (counted up to `limit`, without recursion)."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict | list):
            deepest = max(deepest, depth)
            if depth < limit:
                stack.extend((v, depth + 1) for v in (item.values() if isinstance(item, dict) else item))
    return deepest


def first_error(exc: ValidationError, top: str = "(top level)") -> tuple[str, str]:
    """The first problem pydantic found: the field's dotted path (`top` for the model as a whole) and the reason."""
    err = exc.errors()[0]
    reason = err["msg"].removeprefix("Value error, ")  # our validators' own words, without pydantic's label
    return ".".join(str(p) for p in err["loc"]) or top, reason


def read_declaration(
    path: Path,
    label: str,
    what: str,
    max_bytes: int,
    model: type[Model],
    error: type[DeclarationError] = DeclarationError,
) -> Model:
    """The file's fields validated by `model`; the first problem as one line naming the field."""
    data = yaml_mapping(path, label, what, max_bytes, error)
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise error(label, *first_error(exc)) from None
