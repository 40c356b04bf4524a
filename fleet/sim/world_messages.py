"""The world as bus messages: an arm's `ArmState` and the parts' `PartsState`, built the one way the sim
server publishes them and the env's watcher draws them."""

from __future__ import annotations

from fleet.bus.messages import ArmState, PartsState
from fleet.sim.world import PartInfo, World


def arm_state(world: World, name: str, **echo: object) -> ArmState:
    """One arm's joints, gripper and tool pose now; `echo` fills the optional fields (held, phase, ...)."""
    arm = world.arms[name]
    q, dq, n = arm.qpos(), arm.qvel(), arm.spec.arm_dof
    tool = arm.tool_pose_world()
    return ArmState(
        name,
        world.tick,
        world.sim_time_s,
        tuple(q[:n].tolist()),
        tuple(dq[:n].tolist()),
        tuple(q[n:].tolist()),
        tuple(map(float, tool.p)),
        tuple(map(float, tool.q)),
        **echo,
    )


def parts_state(world: World, parts: list[PartInfo], events_published: int = 0) -> PartsState:
    """Every given part's pose, velocity and size, flattened as the wire carries them."""
    return PartsState(
        world.tick,
        world.sim_time_s,
        tuple(p.part_id for p in parts),
        tuple(p.feeder for p in parts),
        tuple(p.type_index for p in parts),
        tuple(float(v) for p in parts for v in p.position),
        tuple(float(v) for p in parts for v in p.quaternion_wxyz),
        tuple(float(v) for p in parts for v in p.velocity),
        tuple(float(v) for p in parts for v in p.size_m),
        events_published,
    )
