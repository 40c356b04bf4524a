"""A scene's kinds of part as perception knows them: one `PartLook` per look (part types of one shape, size and
colour look the same to a camera: one kind), by its colour and size."""

from __future__ import annotations

from perception.looks import PartLook
from scenes.schema import Scene


def part_looks(scene: Scene) -> tuple[list[PartLook], dict[tuple[str, int], int]]:
    """The looks of `scene`'s part types (a look's `kind` is its index here), and each look's kind by (feeder,
    type index), the pair the world names a part's type by; types that look alike share a kind."""
    looks: list[PartLook] = []
    by_look: dict[tuple, int] = {}
    kinds: dict[tuple[str, int], int] = {}
    for feeder in scene.feeders:
        for index, part in enumerate(feeder.parts):
            seen_as = (part.kind, tuple(part.size_m), part.colour.lower())
            if seen_as not in by_look:
                by_look[seen_as] = len(looks)
                looks.append(PartLook(len(looks), part.rgb, tuple(part.size_m)))
            kinds[feeder.name, index] = by_look[seen_as]
    return looks, kinds
