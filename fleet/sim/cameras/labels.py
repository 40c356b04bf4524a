"""What a segmentation image's ids mean: one documented table, the same in every frame (docs/cameras.md).

Ids are arithmetic, so a reader needs no side table: a part's id is `PART_BASE + part_id` (the part's id on the
bus and in the summary), an arm link's `ARM_BASE * (arm index + 1) + link index` (arms and links in scene and URDF
order), a station's `STATION_BASE + station index`.
"""

from __future__ import annotations

from dataclasses import dataclass

NOTHING = 0  # sky: no body along the ray within the camera's far_m
FLOOR = 1
BELT = 2
STATION_BASE = 100  # 100 + i: the scene's i-th station
ARM_BASE = 1000  # 1000 * (i + 1) + j: link j of the scene's i-th arm (at most 64 arms, 1000 links each)
PART_BASE = 100_000  # 100000 + id: the part with that id
MAX_ARMS = 64


def station_label(index: int) -> int:
    return STATION_BASE + index


def arm_link_label(arm_index: int, link_index: int) -> int:
    return ARM_BASE * (arm_index + 1) + link_index


def part_label(part_id: int) -> int:
    return PART_BASE + part_id


@dataclass(frozen=True)
class Label:
    """What one segmentation id stands for: a kind (`nothing`, `floor`, `belt`, `station`, `arm`, `part`) and which."""

    kind: str
    index: int | None = None  # station or arm index in scene order; a part's id
    link_index: int | None = None  # an arm link's index in its URDF


def read_label(value: int) -> Label:
    """The thing a segmentation id names (the inverse of the functions above)."""
    if value >= PART_BASE:
        return Label("part", value - PART_BASE)
    if value >= ARM_BASE:
        return Label("arm", value // ARM_BASE - 1, value % ARM_BASE)
    if value >= STATION_BASE:
        return Label("station", value - STATION_BASE)
    return Label({NOTHING: "nothing", FLOOR: "floor", BELT: "belt"}.get(value, "unknown"))
