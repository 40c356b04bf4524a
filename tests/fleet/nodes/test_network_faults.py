"""Bus faults between the sim server and a controller, in lockstep: a command lands exactly the injected ticks
later, lost states are not waited for, and a seed repeats the same faults and the same run.

The client here answers the sim's states over real Zenoh as a controller does, sending one trajectory goal
with its answer to chosen states, so that when each goal reaches the tracker can be read tick by tick.
"""

import threading
import time

import numpy as np
import pytest

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.goals import goal_message
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, ControllerStep
from fleet.bus.session import BusEndpoints, Inbox, free_loopback_port, loopback_endpoint, open_session
from fleet.nodes.sim_server import SimServer
from fleet.robot_tools.trials import trial_scene
from fleet.sim.world import World
from robots.joint_trajectory import TrajectoryGoal
from scenes.schema import Network

PERIOD_TICKS = 5  # the controller's default 20 Hz at the pick cell's 100 Hz servo rate


class GoalSender:
    """Answers every state of `arm_0`; with the states of `goal_ticks` (all ticks: with every `every`-th state
    answered) it sends a short trajectory goal and names it."""

    def __init__(
        self,
        session,
        keys: Keys,
        goal_ticks: set[int] | None,
        joints: tuple[str, ...],
        home: np.ndarray,
        every: int = 4,
    ) -> None:
        self.session, self.keys, self.goal_ticks, self.joints, self.home = session, keys, goal_ticks, joints, home
        self.every = every
        self.inbox = Inbox()
        self.sub = session.declare_subscriber(keys.arm_state("arm_0"), self.inbox)
        self.decoder = Decoder(ArmState, DropCounter())
        self.answered: set[int] = set()
        self.goal_of_tick: dict[int, int] = {}
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            self.inbox.wait(0.01)
            for key, payload in self.inbox.drain():
                state = self.decoder.decode(key, payload)
                if state is None or state.tick in self.answered:
                    continue
                self.answered.add(state.tick)
                goal_ids = ()
                chosen = (
                    state.tick in self.goal_ticks
                    if self.goal_ticks is not None
                    else len(self.answered) % self.every == 0
                )
                if chosen:
                    goal_id = 100 + state.tick
                    target = self.home + 0.02 * (len(self.goal_of_tick) % 2)
                    goal = TrajectoryGoal(goal_id, self.joints, (0.2,), (tuple(map(float, target)),))
                    self.session.put(self.keys.arm_goal("arm_0"), encode(goal_message("arm_0", goal)))
                    self.goal_of_tick[state.tick] = goal_id
                    goal_ids = (goal_id,)
                self.session.put(
                    self.keys.arm_step("arm_0"),
                    encode(ControllerStep("arm_0", state.tick, state.tick + PERIOD_TICKS, goal_ids)),
                )

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=5)
        self.sub.undeclare()


def landing_ticks(
    network: Network | None,
    goal_ticks: set[int] | None,
    ticks: int,
    mode: str = "lockstep",
    wall_at: dict[int, float] | None = None,
) -> tuple[dict[int, int], SimServer]:
    """Run the pick cell `ticks` ticks with `network`'s faults; the tick at which each goal reached the tracker
    (and in `wall_at`, the wall time each tick was done)."""
    scene = trial_scene("openclaw", 0).model_copy(update={"network": network})
    world = World(scene)
    keys = Keys("nf")
    endpoint = loopback_endpoint(free_loopback_port())
    spec = world.arms["arm_0"].spec
    with (
        open_session(BusEndpoints(listen=(endpoint,))) as server_session,
        open_session(BusEndpoints(connect=(endpoint,))) as client_session,
    ):
        server = SimServer(world, server_session, keys, mode=mode, lockstep_timeout_s=2.0, first_command_timeout_s=10.0)
        sender = GoalSender(client_session, keys, goal_ticks, spec.arm_joints, np.asarray(spec.home_q, float))
        time.sleep(0.3)  # the two sessions find each other
        landed: dict[int, int] = {}
        try:
            tracker = server.tracked.trackers["arm_0"]
            for _ in range(ticks):
                tick = world.tick
                server.run_ticks(1)  # paced by the wall clock in realtime
                if wall_at is not None:
                    wall_at[tick] = time.monotonic()
                if tracker.goal_id and tracker.goal_id not in landed:
                    landed[tracker.goal_id] = tick
        finally:
            sender.close()
            server.close()
    return {t: landed.get(g) for t, g in sender.goal_of_tick.items()}, server


def test_a_command_lands_the_injected_ticks_later_in_lockstep():
    plain, _ = landing_ticks(None, {10}, 40)
    delayed, server = landing_ticks(Network(latency_ms=30), {10}, 40)
    assert plain == {10: 10 + PERIOD_TICKS}, "without faults an answer takes effect one period after its state"
    assert delayed == {10: 10 + 3 + PERIOD_TICKS + 3}, "30 ms each way at 100 Hz: 3 ticks out, 3 ticks back"
    report = server.report()["network_faults"]["arm_0"]
    assert report["down"]["mean_delay_ms"] == pytest.approx(30.0) and report["up"]["mean_delay_ms"] == pytest.approx(
        30.0
    )
    assert server.stats.lost == []


def test_lost_messages_are_counted_never_waited_for_and_repeat_for_the_seed():
    network = Network(latency_ms=20, jitter_ms=15, loss=0.2)
    first, server = landing_ticks(network, None, 420)
    second, again = landing_ticks(network, None, 420)
    assert server.stats.lost == [] and again.stats.lost == [], "a lost state is not an unanswering controller"
    report = server.report()["network_faults"]["arm_0"]
    assert report["down"]["lost"] > 0 and report["up"]["lost"] > 0
    assert report == again.report()["network_faults"]["arm_0"]
    assert first == second, "the same goals landed at the same ticks"
    landed = [t for t in first.values() if t is not None]
    assert 0 < len(landed) < len(first), "some goals were lost with their answers, the rest landed"
    assert all(landed_at > sent for sent, landed_at in first.items() if landed_at is not None)


def test_in_realtime_the_faults_act_in_wall_time():
    wall_at: dict[int, float] = {}
    landed, server = landing_ticks(
        Network(latency_ms=100, jitter_ms=10, loss=0.1), None, 300, mode="realtime", wall_at=wall_at
    )
    report = server.report()["network_faults"]["arm_0"]
    assert report["down"]["lost"] > 0 and 90 < report["down"]["mean_delay_ms"] < 110
    trips = [wall_at[t] - wall_at[sent] for sent, t in landed.items() if t is not None and sent in wall_at]
    assert trips, "some goals landed"
    assert min(trips) >= 0.2 - 0.06, (
        "no command lands before its state went out and its answer came back (100 ms each way, 3 sigma jitter)"
    )
    assert server.stats.lost == []
