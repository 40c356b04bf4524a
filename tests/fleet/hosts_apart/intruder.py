"""A process that tries to move arm_0 of a running line: `--config FILE` logs in as the file says.

It connects (retrying until the line's router is up), listens to arm_0's states to show that it is
on the bus, and for `--seconds` publishes what would stop or move the arm if believed: an e-stop,
a pause, a trajectory goal, an assignment and a state for arm_0, and a line event losing a part. Prints one JSON line:
whether the
router let it in, the states it heard and the messages it sent.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import zenoh

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, Assignment, EStop, LineEvent, SimControl, TrajectoryGoalMsg
from fleet.bus.session import BusEndpoints, make_config
from robots.registry import get_robot


def fakes(keys: Keys) -> list[tuple[str, bytes]]:
    arm = get_robot("openclaw")  # a goal the arm's tracker would follow: swing the base joint half a turn
    target = (arm.home_q[0] + 1.5, *arm.home_q[1:])
    goal = TrajectoryGoalMsg("arm_0", 999_999, tuple(arm.arm_joints), (2.0,), target)
    return [
        (keys.estop, encode(EStop(True, "intruder"))),
        (keys.control, encode(SimControl("intruder", paused=True))),
        (keys.arm_goal("arm_0"), encode(goal)),
        (keys.arm_assign("arm_0"), encode(Assignment("arm_0", 1, 424242, 0, 0.1, (0.0, 0.0, 0.2), (0.0, 0.0, 0.0)))),
        (
            keys.arm_state("arm_0"),
            encode(ArmState("arm_0", 1, 0.01, target, (0.0,) * 6, (0.0, 0.0), (0.3, 0.0, 0.2), (1.0, 0.0, 0.0, 0.0))),
        ),
        (keys.events, encode(LineEvent("lost", 0, 1, "taken by the intruder"))),
    ]


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--config", required=True)
    parser.add_argument("--seconds", type=float, default=6.0)
    parser.add_argument("--connect-within", type=float, default=60.0)
    args = parser.parse_args()
    keys = Keys("line")
    deadline = time.monotonic() + args.connect_within
    while True:
        try:
            session = zenoh.open(make_config(BusEndpoints(config_file=args.config)))
            break
        except zenoh.ZError as exc:
            if time.monotonic() > deadline:
                print(json.dumps({"connected": False, "error": str(exc).splitlines()[0][:200]}))
                return 0
            time.sleep(0.2)
    heard = []
    sub = session.declare_subscriber(keys.arm_state("arm_0"), lambda sample: heard.append(1))
    sent = 0
    end = time.monotonic() + args.seconds
    while time.monotonic() < end:
        for key, payload in fakes(keys):
            session.put(key, payload)
            sent += 1
        time.sleep(0.05)
    sub.undeclare()
    session.close()
    print(json.dumps({"connected": True, "heard_states": len(heard), "sent": sent}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
