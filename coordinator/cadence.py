"""What the sim and the coordinator must agree on: when the coordinator decides, and which skill phases mean
an arm is not working on a task. One place, imported by both."""

from __future__ import annotations

from scenes.schema import Scene

COORD_RATE_HZ = 10.0  # coordinator decisions per second of sim time
IDLE_SKILLS = ("idle", "done", "failed")  # skill phases of an arm that is not working on a task
AVAILABLE_SKILLS = (*IDLE_SKILLS, "home")  # phases in which an arm may take a task: its way home is given up for it
GRASP_SKILLS = ("descend", "close", "lift")  # the grasp after an approach: moves asked no grant
PLACE_SKILLS = ("lower", "release", "retreat")  # the place after a transfer: moves asked no grant
LOCAL_SKILLS = (*GRASP_SKILLS, *PLACE_SKILLS)


def decision_period_ticks(scene: Scene) -> int:
    """Sim ticks between two coordinator decisions."""
    return max(1, round(scene.control_hz / COORD_RATE_HZ))


def moves_need_grants(scene: Scene) -> bool:
    """Whether the arms ask the coordinator before each free move: whenever another arm could be in the way."""
    return len(scene.arms) > 1
