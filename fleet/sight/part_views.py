"""A parts message (`PartsState`: the sim's, or perception's) as each reader of it needs it: the skills' part
observations, the allocators' part views."""

from __future__ import annotations

import numpy as np

from coordinator.allocation import PartView
from fleet.bus.messages import PartsState
from robots.skills.interface import PartObservation


def parts_from_message(
    msg: PartsState, round_types: frozenset[tuple[str, int]] = frozenset()
) -> dict[int, PartObservation]:
    """Part observations from the flattened parts message; `round_types`: the scene's round part types
    (`Scene.round_part_types`)."""
    out = {}
    for i, pid in enumerate(msg.part_ids):
        size = tuple(msg.sizes_m[3 * i : 3 * i + 3])
        out[pid] = PartObservation(
            pid,
            np.array(msg.positions[3 * i : 3 * i + 3]),
            np.array(msg.quaternions_wxyz[4 * i : 4 * i + 4]),
            np.array(msg.velocities[3 * i : 3 * i + 3]),
            float(min(size[0], size[1])),
            float(size[2]),
            size,
            (msg.feeders[i], msg.type_indices[i]) in round_types,
        )
    return out


def part_views(msg: PartsState) -> dict[int, PartView]:
    """The allocators' view of the parts message: each part's position and velocity, by id."""
    return {
        pid: PartView(np.array(msg.positions[3 * i : 3 * i + 3]), np.array(msg.velocities[3 * i : 3 * i + 3]))
        for i, pid in enumerate(msg.part_ids)
    }
