"""Allocators by name: the built-ins, a trained policy's file (`policy:FILE`), those installed packages declare
(entry point group `clawfleet.allocators`), and any `package.module:Name` on the path. A plug-in is a class (or any
callable) taking the scene and returning an object with `name` and `allocate(...)`
(`coordinator.allocation.Allocator`; `docs/allocators.md`); it runs behind `GuardedAllocator`, so a faulty one costs a
decision, never the run.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path

from coordinator.allocation import ALLOCATORS, Allocator
from coordinator.guarded_allocator import GuardedAllocator
from coordinator.policy_allocator import PREFIX as POLICY_PREFIX
from coordinator.policy_allocator import PolicyAllocator
from coordinator.policy_file import PolicyFileError, load_policy
from scenes.schema import Scene

ENTRY_POINT_GROUP = "clawfleet.allocators"
FRAMES_HZ = (1.0, 5.0)  # the rates an allocator may look at the cameras (`frames_hz`): a brain's, not a controller's


class AllocatorError(ValueError):
    """An allocator that cannot be had by that name; the message is one line and lists the valid names."""


@dataclass(frozen=True)
class AllocatorSource:
    """Where an allocator comes from: `built-in`, an installed distribution's entry point, or a module path."""

    name: str
    target: str  # `module:attr`
    origin: str
    summary: str = ""


def installed_allocators() -> dict[str, AllocatorSource]:
    """The allocators installed packages declare in `clawfleet.allocators`, by entry point name."""
    found = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        dist = getattr(ep, "dist", None)
        origin = f"{dist.name} {dist.version}" if dist is not None else "installed"
        found[ep.name] = AllocatorSource(ep.name, ep.value, origin)
    return found


def known_allocators() -> dict[str, AllocatorSource]:
    """Every allocator a name reaches: the built-ins, then installed plug-ins (a built-in's name wins)."""
    out = {
        name: AllocatorSource(name, f"{cls.__module__}:{cls.__qualname__}", "built-in", _summary(cls))
        for name, cls in ALLOCATORS.items()
    }
    for name, source in installed_allocators().items():
        out.setdefault(name, source)
    return out


def _summary(obj: object) -> str:
    """The first sentence of a docstring."""
    return " ".join((getattr(obj, "__doc__", None) or "").split()).split(". ")[0].rstrip(".")


def _load(target: str, spec: str) -> Callable[[Scene], Allocator]:
    module_name, _, attr = target.partition(":")
    try:
        obj = importlib.import_module(module_name)
        for part in attr.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError) as exc:
        raise AllocatorError(f"allocator {spec!r}: cannot load {target} ({exc.__class__.__name__}: {exc})") from None
    if not callable(obj):
        raise AllocatorError(f"allocator {spec!r}: {target} is not a class or a function of the scene")
    return obj


def allocator_factory(spec: str) -> Callable[[Scene], Allocator]:
    """What makes the allocator `spec` names (a built-in, a trained policy's file `policy:FILE`, an installed
    plug-in, or `package.module:Name`)."""
    if spec in ALLOCATORS:
        return ALLOCATORS[spec]
    if spec.startswith(POLICY_PREFIX):
        try:
            policy = load_policy(spec.removeprefix(POLICY_PREFIX))
        except PolicyFileError as exc:
            raise AllocatorError(f"allocator {spec!r}: {exc}") from None
        return lambda scene: PolicyAllocator(scene, policy)
    known = known_allocators()
    if spec in known:
        return _load(known[spec].target, spec)
    if ":" in spec and all(spec.partition(":")[::2]):
        return _load(spec, spec)
    raise AllocatorError(
        f"unknown allocator {spec!r}; valid allocators: {', '.join(known)} (or package.module:Name of a plug-in, "
        "or policy:FILE of a trained policy)"
    )


def frames_wanted(made: object, spec: str) -> float | None:
    """The rate (Hz) at which an allocator, or the class that makes it, asks to see the cameras' frames (its
    `frames_hz`; None: it does not look); AllocatorError for a rate it may not have."""
    hz = getattr(made, "frames_hz", None)
    if hz is None:
        return None
    if not isinstance(hz, (int, float)) or not FRAMES_HZ[0] <= hz <= FRAMES_HZ[1]:
        raise AllocatorError(f"allocator {spec!r} asks for frames at {hz!r} Hz: it may look at 1-5 Hz")
    if not callable(getattr(made, "see", None)):
        raise AllocatorError(f"allocator {spec!r} asks for frames but has no see(frames) to be handed them")
    return float(hz)


def sees(spec: str | None) -> bool:
    """Whether the allocator `spec` names asks to see the cameras' frames (False also when it does not load: where
    it is made, that is said)."""
    if not spec:
        return False
    try:
        return frames_wanted(allocator_factory(spec), spec) is not None
    except AllocatorError:
        return False


def describe(source: AllocatorSource) -> str:
    """What an allocator does (its docstring's first sentence), or why it does not load."""
    if source.summary:
        return source.summary
    try:
        return _summary(_load(source.target, source.name)) or source.target
    except AllocatorError as exc:
        return f"does not load: {exc}"


def check_allocator(spec: str) -> str:
    """`spec` if it names an allocator that loads (a policy file's path made absolute: the line's processes may
    start elsewhere); AllocatorError otherwise (a CLI checks before it starts a line)."""
    frames_wanted(allocator_factory(spec), spec)
    if spec.startswith(POLICY_PREFIX):
        return POLICY_PREFIX + str(Path(spec.removeprefix(POLICY_PREFIX)).resolve())
    return spec


def make_any_allocator(spec: str, scene: Scene) -> Allocator:
    """An allocator by name: a built-in, an installed plug-in or `package.module:Name`; a plug-in runs guarded
    (`GuardedAllocator`). AllocatorError for one that is unknown, cannot be loaded or cannot be made."""
    factory = allocator_factory(spec)
    if spec in ALLOCATORS or spec.startswith(POLICY_PREFIX):  # a policy's answers are valid by construction
        return factory(scene)
    try:
        inner = factory(scene)
    except Exception as exc:  # a plug-in's constructor: its fault, said in one line
        raise AllocatorError(f"allocator {spec!r} could not be made: {exc.__class__.__name__}: {exc}") from None
    if not callable(getattr(inner, "allocate", None)):
        raise AllocatorError(f"allocator {spec!r}: what it made has no allocate(tasks, arms, parts, busy_stations)")
    frames_wanted(inner, spec)
    return GuardedAllocator(inner, scene)
