"""One line served over rosbridge, driven by roslibpy (a client clawfleet did not write) the way a ROS user drives
arms under ros2_controllers: what the client saw and got back, for the tests to check."""

from __future__ import annotations

import dataclasses
import json
import threading
import time
from pathlib import Path

import cbor2
import numpy as np
import roslibpy
from websockets.sync.client import connect

from fleet.run.launcher import Launcher, RunOptions
from robots.registry import get_robot
from tests.fleet.test_goal_storm import poses_into

ROS_CELL = str(Path(__file__).parents[1] / "scenes_data" / "ros_cell.yaml")
FJT = "control_msgs/action/FollowJointTrajectory"


def trajectory(joints: list[str], *points: tuple[list[float], float]) -> dict:
    """A `FollowJointTrajectory` goal through (positions, seconds from start) points."""
    return {
        "trajectory": {
            "joint_names": joints,
            "points": [
                {"positions": list(map(float, q)), "time_from_start": {"sec": int(t), "nanosec": int(t % 1 * 1e9)}}
                for q, t in points
            ],
        }
    }


class Driver:
    """A roslibpy connection to the line's rosbridge and what it was told."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.ros = roslibpy.Ros(host="127.0.0.1", port=port)
        self.ros.run(timeout=20)
        self.action = roslibpy.ActionClient(self.ros, "/arm_0/follow_joint_trajectory", FJT)

    def goal(self, goal: dict, then=None, timeout_s: float = 30.0, action=None) -> dict:
        """Send a goal (to arm_0's trajectory action, or `action`) and wait for its end: {"status", "values",
        "accepted", "feedback"}; `then(goal_id)` runs once it is sent (`self.answer`: that dict, filled at its end)."""
        action = action or self.action
        out: dict = {"feedback": []}
        self.answer = out
        done = threading.Event()

        def result(r) -> None:
            out.update(status=r["status"].value, values=r["values"], accepted=True)
            done.set()

        def error(r) -> None:
            out.update(status=r["status"].value, values=r["values"], accepted=False)
            done.set()

        goal_id = action.send_goal(roslibpy.Goal(goal), result, out["feedback"].append, error)
        if then is not None:
            then(goal_id)
        assert done.wait(timeout_s), "the action answered"
        return out

    def raw(self, requests: list[str]) -> list[dict]:
        """Send raw frames on a connection of its own; what the server answered (status messages)."""
        answers = []
        with connect(f"ws://127.0.0.1:{self.port}") as ws:
            for text in requests:
                ws.send(text)
                answers.append(json.loads(ws.recv(timeout=5)))
        return answers


def rosbridge_port(launcher: Launcher, timeout_s: float = 60.0) -> int:
    """The port the line's rosbridge serves on, once it says."""
    return int(launcher.server_url("rosbridge", timeout_s).rsplit(":", 1)[1])


def drive(launcher: Launcher, seen: dict) -> None:
    """What a ROS user does to the line; every observation goes into `seen`."""
    try:
        seen["ws_port"] = rosbridge_port(launcher)
        d = Driver(seen["ws_port"])
        spec = get_robot("openclaw")
        joints, home = list(spec.arm_joints), np.asarray(spec.home_q, float)
        seen["topics"] = d.ros.get_topics()
        seen["rosout"] = []
        roslibpy.Topic(d.ros, "/rosout", "rcl_interfaces/msg/Log").subscribe(seen["rosout"].append)
        seen["crowd"] = crowd(seen["ws_port"], 20)
        foxglove_contract(d, seen["ws_port"], seen)
        seen["details"] = d.ros.get_message_details("sensor_msgs/JointState")
        raw = roslibpy.Service(d.ros, "/rosapi/topics_and_raw_types", "rosapi_msgs/srv/TopicsAndRawTypes")
        seen["raw_types"] = raw.call(roslibpy.ServiceRequest({}), timeout=10)
        got = threading.Event()
        d.ros.get_action_servers(lambda r: (seen.update(actions=r["action_servers"]), got.set()))
        got.wait(10)
        states: list[dict] = []
        js = roslibpy.Topic(d.ros, "/arm_0/joint_states", "sensor_msgs/msg/JointState")
        js.subscribe(states.append)
        everyone: list[dict] = []
        roslibpy.Topic(d.ros, "/joint_states", "sensor_msgs/msg/JointState").subscribe(everyone.append)
        static: list[dict] = []
        roslibpy.Topic(d.ros, "/tf_static", "tf2_msgs/msg/TFMessage").subscribe(static.append)
        target = home + np.array([0.3, -0.2, 0.25, 0.0, 0.2, 0.0])
        seen["target"] = target.tolist()
        seen["reach"] = d.goal(trajectory(joints, (target, 1.5)))
        time.sleep(0.5)
        seen["after_reach"] = states[-1]
        seen["everyone_names"] = sorted({n for m in everyone for n in m["name"]})
        seen["tf_static"] = static[:1]
        seen["unknown_joints"] = d.goal(trajectory(["elbowz", *joints[1:]], (home, 1.0)))
        into = poses_into(launcher.scene, "arm_0", "arm_1", 1)[0]
        seen["into_neighbour"] = d.goal(trajectory(joints, (into, 2.0)))
        seen["unreadable"] = d.goal({"trajectory": {"joint_names": joints, "points": [{"positions": "x"}]}})
        slow = trajectory(joints, (home, 4.0))

        def preempt(_goal_id) -> None:
            time.sleep(0.5)
            threading.Thread(target=lambda: seen.update(preempting=d.goal(trajectory(joints, (target, 2.0))))).start()

        seen["preempted"] = d.goal(slow, then=preempt)
        wait_for(lambda: "preempting" in seen, 10.0)
        seen["cancelled"] = d.goal(slow, then=lambda gid: (time.sleep(0.5), d.action.cancel_goal(gid)))

        def estop(_goal_id) -> None:
            time.sleep(0.5)
            call = roslibpy.Service(d.ros, "/estop", "std_srvs/srv/SetBool")
            seen["estop_answer"] = call.call(roslibpy.ServiceRequest({"data": True}), timeout=10)

        seen["estopped"] = d.goal(trajectory(joints, (target, 4.0)), then=estop)
        time.sleep(0.5)  # held a while: the line's views (10 a sim second) show it, and /rosout says so
        roslibpy.Service(d.ros, "/estop", "std_srvs/srv/SetBool").call(roslibpy.ServiceRequest({"data": False}))
        seen["raw"] = d.raw(
            [
                "{not json",
                json.dumps({"op": "fly"}),
                json.dumps({"op": "subscribe", "topic": "/nope", "id": "s1"}),
                json.dumps(
                    {
                        "op": "send_action_goal",
                        "action": "/arm_9/follow_joint_trajectory",
                        "action_type": FJT,
                        "args": {},
                        "id": "g1",
                    }
                ),  # fmt: skip
                json.dumps({"op": "call_service", "service": "/estop", "args": {"data": "yes"}, "id": "c1"}),
            ]
        )
        seen["after_all"] = d.goal(trajectory([f"arm_0/{j}" for j in joints], (home, 1.0)))  # as /joint_states names
        claw = roslibpy.ActionClient(d.ros, "/arm_0/gripper_cmd", "control_msgs/action/GripperCommand")
        seen["claw_closed"] = d.goal({"command": {"position": spec.gripper_closed[0], "max_effort": 5.0}}, action=claw)
        seen["claw_opened"] = d.goal({"command": {"position": spec.gripper_open[0]}}, action=claw)
        arm_1: list[dict] = []
        roslibpy.Topic(d.ros, "/arm_1/joint_states", "sensor_msgs/msg/JointState").subscribe(arm_1.append)
        to_arm_1 = roslibpy.Topic(d.ros, "/arm_1/joint_trajectory", "trajectory_msgs/msg/JointTrajectory")
        seen["arm_1_target"] = (home - np.array([0.3, 0.2, -0.25, 0.0, 0.2, 0.0])).tolist()
        to_arm_1.publish(roslibpy.Message(trajectory(joints, (seen["arm_1_target"], 1.0))["trajectory"]))
        there = lambda: arm_1 and np.allclose(arm_1[-1]["position"][:6], seen["arm_1_target"], atol=0.03)  # noqa: E731
        wait_for(there, 5.0)
        seen["arm_1_after"] = arm_1[-1]["position"][:6]
        d.ros.close()  # not terminate(): that stops the Twisted reactor, which cannot be started again
    except Exception as exc:  # the test reports it
        seen["error"] = repr(exc)


def binary_publishes(port: int, subscribe: dict, count: int, timeout_s: float = 10.0) -> list[dict]:
    """Subscribe on a connection of its own as `subscribe` says (a `compression` that makes binary frames); the
    first `count` publishes, decoded with cbor2."""
    out = []
    with connect(f"ws://127.0.0.1:{port}") as ws:
        ws.send(json.dumps({"op": "subscribe", **subscribe}))
        deadline = time.monotonic() + timeout_s
        while len(out) < count and time.monotonic() < deadline:
            try:
                frame = ws.recv(timeout=0.5)
            except TimeoutError:
                continue
            out.append(cbor2.loads(frame) if isinstance(frame, bytes) else {"text": frame})
    return out


def foxglove_contract(d: Driver, port: int, seen: dict) -> None:
    """What Foxglove's rosbridge connection asks of a server besides the topics: a node's details, and topics in
    CBOR, whole (`cbor`) or as the message's CDR bytes (`cbor-raw`)."""
    details = roslibpy.Service(d.ros, "/rosapi/node_details", "rosapi_msgs/srv/NodeDetails")
    seen["node_details"] = details.call(roslibpy.ServiceRequest({"node": "/clawfleet_rosbridge"}), timeout=10)
    seen["nodes"] = d.ros.get_nodes()
    seen["cbor_raw"] = binary_publishes(port, {"topic": "/joint_states", "compression": "cbor-raw"}, 3)
    seen["cbor"] = binary_publishes(port, {"topic": "/tf_static", "compression": "cbor"}, 1)
    seen["png"] = d.raw([json.dumps({"op": "subscribe", "topic": "/clock", "compression": "png", "id": "p"})])


def crowd(port: int, clients: int) -> list[int]:
    """`clients` connections at once, each subscribed to `/joint_states`: how many messages each got in 2 s."""
    got = [0] * clients

    def one(i: int) -> None:
        with connect(f"ws://127.0.0.1:{port}") as ws:
            ws.send(json.dumps({"op": "subscribe", "topic": "/joint_states", "id": f"crowd{i}"}))
            deadline = time.monotonic() + 2.0
            while time.monotonic() < deadline:
                try:
                    if json.loads(ws.recv(timeout=0.5)).get("topic") == "/joint_states":
                        got[i] += 1
                except TimeoutError:
                    continue

    threads = [threading.Thread(target=one, args=(i,)) for i in range(clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    return got


def wait_for(condition, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.05)


def rosbridge_session(ros2_listener=None) -> tuple[dict, dict]:
    """The summary of a realtime ros_cell line with rosbridge (and, given `ros2_listener(launcher, heard, after)`,
    a native ROS 2 user, who drives once the rosbridge user is done: `seen["ros2"]`), and what the ROS user saw.
    The line stops once both are done."""
    options = RunOptions(scene=ROS_CELL, duration_s=360.0, mode="realtime", speed=2.0, rosbridge_port=0)
    if ros2_listener is not None:
        options = dataclasses.replace(options, ros2_domain=ros2_listener.domain, ros2_arms=ros2_listener.arms)
    seen: dict = {"ros2": {}}
    driven = threading.Event()

    def rosbridge_user() -> None:
        drive(launcher, seen)
        driven.set()

    with Launcher(options) as launcher:
        users = [threading.Thread(target=rosbridge_user, daemon=True)]
        if ros2_listener is not None:
            users.append(threading.Thread(target=ros2_listener, args=(launcher, seen["ros2"], driven), daemon=True))

        def stop_when_done() -> None:
            for user in users:
                user.join(180)
            launcher.interrupted = "the ROS users are done"

        for thread in [*users, threading.Thread(target=stop_when_done, daemon=True)]:
            thread.start()
        summary = launcher.run()
        for user in users:
            user.join(30)
    seen["endpoint"] = launcher.endpoint
    return summary, seen


def take_arm(launcher: Launcher, seen: dict) -> None:
    """A ROS user takes arm_0 of a working line for a few seconds (a trajectory holding it near home), then lets
    go."""
    try:
        d = Driver(rosbridge_port(launcher))
        spec = get_robot("openclaw")
        joints, home = list(spec.arm_joints), np.asarray(spec.home_q, float)
        seen["held"] = d.goal(trajectory(joints, (home, 1.0), (home + 0.1, 3.0), (home, 5.0)))
        d.ros.close()  # not terminate(): that stops the Twisted reactor, which cannot be started again
        time.sleep(3.0)  # the arm is let go 2 s (sim) after the path ends
    except Exception as exc:
        seen["error"] = repr(exc)
    finally:
        launcher.interrupted = "the ROS user let go"


def taken_arm_session(scene: str) -> tuple[dict, dict]:
    """A realtime line at work whose arm_0 a ROS user takes for a while: the summary and what the user got."""
    options = RunOptions(scene=scene, duration_s=30.0, mode="realtime", rosbridge_port=0)
    seen: dict = {}
    with Launcher(options) as launcher:
        user = threading.Thread(target=take_arm, args=(launcher, seen), daemon=True)
        user.start()
        summary = launcher.run()
        user.join(30)
    seen["endpoint"] = launcher.endpoint
    return summary, seen
