"""Reading a YAML declaration file (a scene, a robot): size and encoding checked, errors naming file and field."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import yaml
from pydantic import BaseModel, ValidationError

Model = TypeVar("Model", bound=BaseModel)
MAX_DEPTH = 16  # lists and mappings within each other: a scene needs 5
MAX_VALUES = 20_000  # scalars, lists and mappings, aliases expanded: a bundled scene holds under 300
LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml's parser where PyYAML was built with it


class DeclarationError(ValueError):
    """A declaration file that cannot be used: names the file, the field path and the reason, on one line."""

    def __init__(self, file: str, field: str, reason: str) -> None:
        self.file, self.field, self.reason = file, field, reason
        super().__init__(one_line(f"{file}: {field}: {reason}" if field else f"{file}: {reason}"))


def one_line(text: str) -> str:
    """`text` with its control characters written as escapes (a value holding a newline stays one line)."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


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
    """The file's top-level mapping of fields; one-line errors for size, encoding, YAML syntax, bounds and shape."""
    data = parse_yaml(yaml_text(path, label, what, max_bytes, error), label, what, error)
    if not isinstance(data, dict):
        raise error(label, "", f"a {what} file must hold a mapping of fields at its top level")
    return data


def parse_yaml(text: str, label: str, what: str, error: type[DeclarationError] = DeclarationError) -> object:
    """The YAML document in `text`, built only once its size with every alias expanded (`MAX_VALUES`) and its depth
    (`MAX_DEPTH`) are known to be within bounds: an alias bomb or a deep nest is refused after reading at most about
    `MAX_VALUES` events, never built."""
    try:
        _check_bounds(text, label, what, error)
        return yaml.load(text, Loader=LOADER)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else ""
        raise error(label, where, f"not valid YAML: {getattr(exc, 'problem', None) or exc}") from None


@dataclass
class _Open:
    """A mapping or list being read: its anchor, the values in it so far, its deepest child."""

    anchor: str | None
    values: int = 0
    child_depth: int = 0


def _check_bounds(text: str, label: str, what: str, error: type[DeclarationError]) -> None:
    """Reads `text`'s events (libyaml's parser, no document built) and refuses it at the first bound it passes."""
    anchors: dict[str, tuple[int, int]] = {}  # anchor -> (values, depth) of the node it names
    stack: list[_Open] = []
    seen = 0
    for event in yaml.parse(text, Loader=LOADER):
        if isinstance(event, yaml.CollectionStartEvent):
            if len(stack) + 1 > MAX_DEPTH:
                raise error(label, _line(event), f"nested more than {MAX_DEPTH} levels deep: a {what} needs fewer")
            stack.append(_Open(event.anchor))
            seen += 1
        elif isinstance(event, yaml.CollectionEndEvent):
            done = stack.pop()
            size, depth = done.values + 1, done.child_depth + 1
            if done.anchor is not None:
                anchors[done.anchor] = (size, depth)
            _add(stack, size, depth)
        elif isinstance(event, yaml.ScalarEvent):
            if event.anchor is not None:
                anchors[event.anchor] = (1, 0)
            _add(stack, 1, 0)
            seen += 1
        elif isinstance(event, yaml.AliasEvent):
            if event.anchor not in anchors:
                inside = any(o.anchor == event.anchor for o in stack)
                reason = "refers to a value that holds it" if inside else "names no anchor before it"
                raise error(label, _line(event), f"alias *{event.anchor} {reason}")
            size, depth = anchors[event.anchor]
            if len(stack) + depth > MAX_DEPTH:
                raise error(label, _line(event), f"alias *{event.anchor} nests more than {MAX_DEPTH} levels deep")
            _add(stack, size, depth)
            seen += size
        if seen > MAX_VALUES:
            raise error(
                label, _line(event), f"more than {MAX_VALUES:,} values with aliases expanded: a {what} needs far fewer"
            )


def _add(stack: list[_Open], values: int, depth: int) -> None:
    if stack:
        stack[-1].values += values
        stack[-1].child_depth = max(stack[-1].child_depth, depth)


def _line(event: yaml.Event) -> str:
    return f"line {event.start_mark.line + 1}" if event.start_mark is not None else ""


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
