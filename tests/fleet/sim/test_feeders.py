"""A conveyor feeder never drops a part onto another: one due while the last still lies at the drop spot waits."""

import numpy as np
import pytest

from fleet.sim.world import World
from scenes import load_scene
from scenes.schema import Arrival


def scene_with_burst(times_s: list[float]):
    scene = load_scene("pick_cell")
    feeder = scene.feeders[0].model_copy(update={"arrival": Arrival(schedule_s=times_s), "capacity": 8})
    return scene.model_copy(update={"feeders": [feeder]})


def test_a_burst_of_parts_is_released_one_clear_of_the_next_and_none_is_lost_or_stacked():
    world = World(scene_with_burst([1.0, 1.05, 1.1, 1.15]))
    released_at: dict[int, float] = {}
    while world.sim_time_s < 10.0:
        world.step()
        for p in world.parts:
            if p.active and p.part_id not in released_at:
                released_at[p.part_id] = world.sim_time_s
                others = [q for q in world.parts if q.active and q.part_id != p.part_id]
                for q in others:  # at its release no other part lies where it is dropped
                    gap = np.hypot(*(np.asarray(p.entity.pose.p[:2]) - np.asarray(q.entity.pose.p[:2])))
                    assert gap > max(p.part_type.size_m[:2]), (p.part_id, q.part_id, gap)
    assert sorted(released_at) == [0, 1, 2, 3], "every part of the burst comes, late rather than never"
    times = [released_at[i] for i in range(4)]
    # the belt (5 cm/s) carries each clear first
    assert times[0] < 1.05 and all(b - a > 0.5 for a, b in zip(times, times[1:])), times
    tops = [p.entity.pose.p[2] for p in world.parts if p.active]
    assert max(tops) - min(tops) < 0.03, "all lie on the belt: none on top of another"


def test_parts_dropped_into_a_tray_lie_side_by_side_and_a_part_with_no_free_spot_waits_upstream():
    scene = load_scene("mixed_infeed")
    rework = scene.feeder("rework").model_copy(update={"arrival": Arrival(schedule_s=[1.0, 1.1, 1.2, 1.3, 1.4, 1.5])})
    scene = scene.model_copy(update={"feeders": [rework]})
    world = World(scene)
    while world.sim_time_s < 4.0:
        world.step()
    lying = [p for p in world.parts if p.active]
    assert len(lying) == 4, "the tray has four spots for these parts: the fifth and sixth wait"
    xy = np.array([p.entity.pose.p[:2] for p in lying])
    gaps = [np.hypot(*(a - b)) for i, a in enumerate(xy) for b in xy[i + 1 :]]
    assert min(gaps) > 0.05, "side by side, none on another"
    tray = scene.station("rework_tray")
    assert all(abs(p.entity.pose.p[2] - (tray.surface_z_m + p.height_m / 2)) < 0.005 for p in lying), (
        "all on the tray's floor"
    )
    held = world.feeders[0].held_s
    assert held > 2.0
    world.retire_part(lying[0].part_id)  # an arm takes one away: the next is set down at once
    world.step()
    assert sum(p.active for p in world.parts) == 4 and world.feeders[0].held_s > held


def test_an_infeed_down_the_belt_sets_its_parts_down_there_and_the_capacity_model_rides_them_from_there():
    from coordinator.capacity import Hop, pick_points

    scene = load_scene("assembly_line", arms=6)
    world = World(scene)
    part = world.part_info(world.spawn_now("bases_b1"))
    along = np.dot(part.position[:2] - np.asarray(scene.conveyor.pose.xyz[:2]), scene.conveyor.direction[:2])
    assert along == pytest.approx(0.06 + 1.6, abs=0.03)  # bay 1's infeed, 1.6 m down from bay 0's
    points = pick_points(scene, Hop("bases_b1", 0, "conveyor", "fixture_0_b1"))
    first = min(points, key=lambda p: p[0])
    assert first[0] == 0.0 and first[1].position[0] >= scene.conveyor.pose.xyz[0] + 1.6 - 0.1
