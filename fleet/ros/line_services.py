"""The line's own ROS services (`/estop`, `/pause`, `/resume`), one behaviour for every ROS front end: a request
(JSON-like values) becomes a bus message, the response says what was done."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from fleet.bus.messages import TrajectoryGoalMsg
from fleet.ros import names


@dataclass(frozen=True)
class LineBus:
    """What a ROS client may do to the line, as bus messages."""

    send_goal: Callable[[TrajectoryGoalMsg], None]
    estop: Callable[[bool], None]
    pause: Callable[[bool], None]


class ServiceError(ValueError):
    """A request a line service cannot take; the message says what it takes."""


def answer_line_service(service: str, args: dict, bus: LineBus) -> dict:
    """Do what `service` (one of `names.SERVICE_TYPES`) asks; its response's values (`success`, `message`)."""
    if service == names.ESTOP:
        engaged = args.get("data")
        if not isinstance(engaged, bool):
            raise ServiceError("/estop takes std_srvs/srv/SetBool: {data: true|false}")
        bus.estop(engaged)
        return {"success": True, "message": "emergency stop engaged" if engaged else "emergency stop released"}
    if service in (names.PAUSE, names.RESUME):
        bus.pause(service == names.PAUSE)
        return {"success": True, "message": "paused" if service == names.PAUSE else "resumed"}
    raise KeyError(service)
