"""The line's log as ROS tools read one: `/rosout` (`rcl_interfaces/msg/Log`) says what happened to the arms, at
ROS's levels: an arm whose controller was lost (ERROR) or came back (INFO), an arm held by the line (WARN: the
e-stop, a watchdog) or let go, an arm taken by an outside driver and let go (INFO), and a goal the plant refused or
aborted, with its reason (WARN). Foxglove's rosbridge connection also takes a server with a Log topic for ROS 2."""

from __future__ import annotations

from dataclasses import dataclass

from fleet.bus.messages import ArmState, GoalResultMsg
from fleet.record.ros_types import ros_type, time_msg

INFO, WARN, ERROR = 20, 30, 40  # rcl_interfaces/msg/Log's levels
LOGGER = "clawfleet"


@dataclass(frozen=True)
class ArmFlags:
    lost: bool
    held: bool
    taken: bool

    @classmethod
    def of(cls, state: ArmState) -> ArmFlags:
        return cls(state.lost, state.held and not state.taken and not state.lost, state.taken)


class LineLog:
    """Log messages from the arms' states (each change of an arm's flags, once its first state set where it
    stands) and from goal results."""

    def __init__(self) -> None:
        self._flags: dict[str, ArmFlags] = {}

    def from_states(self, states: list[ArmState], sim_time_s: float) -> list[object]:
        out = []
        for state in states:
            now, before = ArmFlags.of(state), self._flags.get(state.arm)
            self._flags[state.arm] = now
            if before is not None and now != before:
                out += [log(level, state.arm, text, sim_time_s) for level, text in changes(before, now)]
        return out

    def from_result(self, result: GoalResultMsg, sim_time_s: float) -> object | None:
        if result.status not in ("rejected", "aborted"):
            return None
        return log(WARN, result.arm, f"goal {result.goal_id} {result.status}: {result.reason}", sim_time_s)


def changes(before: ArmFlags, now: ArmFlags) -> list[tuple[int, str]]:
    """What changed between two of an arm's flags, at its level."""
    out = []
    if now.lost != before.lost:
        out.append((ERROR, "its controller was lost: the arm holds") if now.lost else (INFO, "its controller is back"))
    if now.held != before.held:
        out.append((WARN, "held by the line (e-stop or watchdog)") if now.held else (INFO, "no longer held"))
    if now.taken != before.taken:
        out.append((INFO, "taken by an outside driver") if now.taken else (INFO, "let go by its outside driver"))
    return out


def log(level: int, arm: str, text: str, sim_time_s: float) -> object:
    """One `rcl_interfaces/msg/Log` of `arm`, stamped with the line's time."""
    return ros_type("rcl_interfaces/msg/Log")(
        stamp=time_msg(sim_time_s),
        level=level,
        name=f"{LOGGER}.{arm}",
        msg=f"{arm}: {text}",
        file="",
        function="",
        line=0,
    )
