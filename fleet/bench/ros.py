"""`fleet bench ros`: what serving a line to ROS tools costs, and how fast a ROS goal moves an arm.

- cost: lockstep lines of the sorting line without, and with `--rosbridge` and N WebSocket clients each subscribed
  to `/joint_states` and `/tf` (reading everything as it comes) and `--ros2` (rmw_zenoh publishing), in turn; the
  sim loop's wall time compared.
- latency: a realtime line; a rosbridge client sends `FollowJointTrajectory` goals to arm_0 (between two poses,
  1 s each) and times, in wall time, from sending to the first feedback (the arm's state saying the goal drives it:
  the tracker moves the arm along it), and from the last `/arm_0/joint_states` that still shows it moving to the
  result. States come at the arm's state rate (20 Hz of sim time), so both figures include up to one state period
  (50 ms); goals are sent at random moments (0-100 ms after the last result), not in step with the states.

The clients here are plain WebSocket clients speaking rosbridge's JSON; the tests prove the protocol with roslibpy.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass

import numpy as np
from websockets.sync.client import connect

from fleet.ros.names import DEFAULT_MAX_RATE_HZ
from fleet.run.launcher import Launcher, RunOptions
from robots.registry import get_robot

FJT = "control_msgs/action/FollowJointTrajectory"


@dataclass(frozen=True)
class RosCostRow:
    variant: str
    loop_wall_seconds: float
    ratio_to_plain: float
    messages_per_client: float


@dataclass(frozen=True)
class RosLatencyRow:
    goals: int
    start_p50_ms: float
    start_p90_ms: float
    result_after_motion_p50_ms: float
    result_after_motion_p90_ms: float


def _subscriber(launcher: Launcher, counts: list[int], i: int, stop: threading.Event) -> None:
    with connect(launcher.server_url("rosbridge")) as ws:
        for topic in ("/joint_states", "/tf"):
            ws.send(json.dumps({"op": "subscribe", "topic": topic, "id": f"{topic}{i}"}))
        while not stop.is_set():
            try:
                ws.recv(timeout=0.2)
                counts[i] += 1
            except TimeoutError:
                continue
            except Exception:
                return


def _run(
    arms: int, seconds: float, subscribers: int | None, max_rate_hz: float = DEFAULT_MAX_RATE_HZ
) -> tuple[float, float]:
    """One lockstep run; with `subscribers` (not None) a rosbridge server and that many clients, and the native
    ROS 2 node publishing. The sim loop's wall seconds and the messages each client got."""
    served = subscribers is not None
    options = RunOptions(
        "sorting_line",
        arms=arms,
        duration_s=seconds,
        rosbridge_port=0 if served else None,
        ros2_domain=0 if served else None,
        ros_max_rate_hz=max_rate_hz,
    )
    counts, stop = [0] * (subscribers or 0), threading.Event()
    with Launcher(options) as launcher:
        threads = [
            threading.Thread(target=_subscriber, args=(launcher, counts, i, stop), daemon=True)
            for i in range(subscribers or 0)
        ]
        for t in threads:
            t.start()
        summary = launcher.run()
        stop.set()
        for t in threads:
            t.join(5)
    return float(summary["loop_wall_seconds"]), float(np.mean(counts)) if counts else 0.0


def bench_ros_cost(
    arms: int = 4,
    seconds: float = 60.0,
    subscribers: int = 10,
    repeats: int = 3,
    max_rate_hz: float = DEFAULT_MAX_RATE_HZ,
) -> list[RosCostRow]:
    """Plain and served runs in turn, `repeats` pairs; medians, and the median of the pairs' ratios."""
    plain, served, got = [], [], []
    for _ in range(repeats):
        plain.append(_run(arms, seconds, None)[0])
        wall, per_client = _run(arms, seconds, subscribers, max_rate_hz)
        served.append(wall)
        got.append(per_client)
    ratio = float(np.median(np.array(served) / np.array(plain)))
    return [
        RosCostRow("plain", float(np.median(plain)), 1.0, 0.0),
        RosCostRow(
            f"rosbridge, {subscribers} clients, rmw_zenoh", float(np.median(served)), ratio, float(np.median(got))
        ),
    ]


def _drive(launcher: Launcher, goals: int, out: dict) -> None:
    try:
        spec = get_robot(launcher.scene.arms[0].model)
        joints, home = list(spec.arm_joints), np.asarray(spec.home_q, float)
        poses = [home + np.array([0.3, -0.2, 0.25, 0.0, 0.2, 0.0])[: home.size], home]
        starts, ends = [], []
        rng = np.random.default_rng(0)
        with connect(launcher.server_url("rosbridge")) as ws:
            ws.send(json.dumps({"op": "subscribe", "topic": "/arm_0/joint_states", "id": "js"}))
            for k in range(goals):
                time.sleep(
                    rng.uniform(0.0, 0.1)
                )  # goals at any moment, not in step with the states that ended the last
                target = poses[k % 2]
                points = [{"positions": target.tolist(), "time_from_start": {"sec": 1, "nanosec": 0}}]
                goal = {"trajectory": {"joint_names": joints, "points": points}}
                last_q = None
                sent = time.perf_counter()
                ws.send(json.dumps({"op": "send_action_goal", "id": f"g{k}", "action": "/arm_0/follow_joint_trajectory",
                                    "action_type": FJT, "args": goal, "feedback": True}))  # fmt: skip
                moved = last_moving = None
                while True:
                    msg = json.loads(ws.recv(timeout=30))
                    now = time.perf_counter()
                    if msg["op"] == "action_feedback":
                        moved = moved or now  # the tracker drives the arm along the goal
                    elif msg["op"] == "publish":
                        q = np.array(msg["msg"]["position"][: home.size])
                        if last_q is not None and np.abs(q - last_q).max() > 1e-4:
                            last_moving = now
                        last_q = q
                    elif msg["op"] == "action_result":
                        break
                if moved is not None and last_moving is not None:
                    starts.append(moved - sent)
                    ends.append(now - last_moving)
        out["starts"], out["ends"] = starts, ends
    except Exception as exc:
        out["error"] = repr(exc)
    finally:
        launcher.interrupted = "the latency run is over"


def bench_ros_latency(goals: int = 20) -> RosLatencyRow:
    """Realtime sorting line of 2 arms; `goals` goals to arm_0 (it is taken from the line while they run)."""
    out: dict = {}
    with Launcher(
        RunOptions(scene="sorting_line", arms=2, duration_s=600.0, mode="realtime", rosbridge_port=0)
    ) as launcher:
        driver = threading.Thread(target=_drive, args=(launcher, goals, out), daemon=True)
        driver.start()
        launcher.run()
        driver.join(30)
    if "error" in out or not out.get("starts"):
        raise RuntimeError(f"the latency run failed: {out.get('error', 'no goal moved the arm')}")
    s, e = np.array(out["starts"]) * 1e3, np.array(out["ends"]) * 1e3
    return RosLatencyRow(len(s), *(float(np.percentile(v, p)) for v in (s, e) for p in (50, 90)))
