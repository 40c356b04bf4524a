"""A round part (a cylinder) is seen round by every arm, in process and over the bus, so the pick skill closes across it
at the arm's own yaw; a box is not."""

from fleet.sight.part_views import parts_from_message
from fleet.sim.observe import part_observations
from fleet.sim.world import World
from fleet.sim.world_messages import parts_state
from scenes import load_scene


def test_the_assembly_lines_tops_are_round_and_its_bases_are_not_in_the_world_and_on_the_wire():
    scene = load_scene("assembly_line")
    assert scene.round_part_types() == {("tops", 0)}
    world = World(scene)
    world.step(round(2.5 * scene.control_hz))  # a base at 1 s, a top at 2 s
    seen = part_observations(world)
    feeder_of = {p.part_id: p.feeder for p in world.active_parts()}
    assert sorted(feeder_of.values()) == ["bases", "tops"]
    wire = parts_from_message(parts_state(world, world.active_parts()), scene.round_part_types())
    for part_id, feeder in feeder_of.items():
        assert seen[part_id].round == wire[part_id].round == (feeder == "tops")
    assert not any(p.round for p in parts_from_message(parts_state(world, world.active_parts())).values())
