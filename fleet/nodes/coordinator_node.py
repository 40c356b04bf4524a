"""The coordinator process: the ledger and allocator of `coordinator/` behind the bus.

It listens to the sim's line events, to its frames (every arm's state, whose skill
echo says what each arm does in step with the sim clock, and the parts, in one
message every `1 / COORD_RATE_HZ` of sim time) and to the controllers' heartbeats;
at each frame it refreshes the tasks, allocates them, answers motion requests and
publishes assignments. In lockstep it then answers the sim
with a `CoordTick`, so its decisions land on the same tick in every run. An arm
whose heartbeats stop for `heartbeat_timeout_s` (wall clock) is lost: its tasks
go back to the pool. It never imports the simulator.

    python -m fleet.nodes.coordinator_node --scene assembly_line --run demo --connect tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time

import numpy as np
import zenoh

from coordinator.capacity import capacity_bound, measured_hop_seconds
from coordinator.allocation import ALLOCATORS, Allocator, ArmView, CachedReach, Eligibility, PartView, TimeCost, make_allocator
from coordinator.deadlines import belt_deadline_s, cannot_make_it, last_reach_along_belt_m
from coordinator.geometry import ArmGeometry
from coordinator.guard import CollisionGuard, TimedPath
from coordinator.ledger import Ledger
from coordinator.tasks import CONVEYOR, Task, TaskState
from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.plausible import TickClock, arm_state_problem, parts_problem
from fleet.bus.messages import (
    ArmState, ArmStatus, Assignment, CoordTick, LineEvent, LineView, MotionGrant, PartsState, Progress, separations_from_pairs,
)
from fleet.bus.session import BusEndpoints, Inbox, add_bus_arguments, open_session
from fleet.processes import add_scene_arguments, node_arguments, write_report
from robots.frames import yaw_transform
from robots.registry import get_robot
from scenes.schema import Scene

COORD_RATE_HZ = 10.0
PROGRESS_PERIOD_S = 0.5
IDLE_SKILLS = ("idle", "done", "failed")
OVERRUN_S = 2.0  # a task this late on its estimate: its arm's end is unknown
DECISION_WAIT_S = 0.5  # a reach check must not miss a reachable spot for an unlucky start


class CoordinatorNode:
    """Feed it with `poll()` in a loop; `report()` gives the coordinator's part of the run summary."""

    def __init__(
        self,
        session: zenoh.Session,
        keys: Keys,
        scene: Scene,
        *,
        lockstep: bool = True,
        allocator: Allocator | None = None,
        heartbeat_timeout_s: float = 0.75,
    ) -> None:
        self.scene, self.keys, self.lockstep = scene, keys, lockstep
        self.ledger = Ledger(scene)
        self.allocator = allocator or make_allocator("optimal", scene)
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.arm_names = [a.name for a in scene.arms]
        self.guard = CollisionGuard({
            a.name: ArmGeometry(a.name, get_robot(a.model), yaw_transform(a.base.xyz, a.base.yaw_rad)) for a in scene.arms
        })
        self.min_separation_m = math.inf
        self.closest_pair: tuple[str, str] | None = None
        self.reach = {a.name: CachedReach.of(a) for a in scene.arms}
        self.bases = {a.name: a.base.xyz for a in scene.arms}
        self.period_ticks = max(1, round(scene.control_hz / COORD_RATE_HZ))
        self.drops = DropCounter()
        self._decoders = {
            "events": Decoder(LineEvent, self.drops), "frame": Decoder(LineView, self.drops), "status": Decoder(ArmStatus, self.drops),
        }
        self.sim_clock = TickClock(scene.control_hz)  # frames and events are the sim's: none may run far ahead of it
        self._dof = {a.name: get_robot(a.model).arm_dof for a in scene.arms}
        self._inbox = Inbox()  # one queue for everything: messages are handled in arrival order
        self._subs = [session.declare_subscriber(k, self._inbox) for k in (keys.events, keys.frame, keys.all_arms("status"))]
        self._heard_at: dict[str, float] = {}  # arm -> wall time its last heartbeat arrived (set on arrival)
        self._subs.append(session.declare_subscriber(keys.all_arms("status"), self._on_heartbeat_arrival))
        self._assign_pubs = {a: session.declare_publisher(keys.arm_assign(a)) for a in self.arm_names}
        self._tick_pub = session.declare_publisher(keys.coord("tick"))
        self._progress_pub = session.declare_publisher(keys.coord("progress"))
        self._separation_pub = session.declare_publisher(keys.coord("separation"))
        self.assign_seq = {a: 0 for a in self.arm_names}
        self.skill = {a: "idle" for a in self.arm_names}
        self.last_tick = {a: -1 for a in self.arm_names}
        self.acts_at_tick = {a: 0 for a in self.arm_names}  # when an order sent now takes effect on each arm
        self.incarnation: dict[str, int] = {}
        self.last_stations: dict[str, tuple[str, ...]] = {a: () for a in self.arm_names}
        self.heartbeat_at: dict[str, float] = {}
        self.requests: dict[str, TimedPath] = {}  # motion requests waiting for a decision, by arm (the newest wins)
        self.request_seq: dict[str, int] = {a: 0 for a in self.arm_names}
        self.grants_given = 0
        self.reassigned = 0
        self.deadline_known: set[int] = set()  # tasks whose belt deadline was worked out (once each)
        self.lost: dict[str, float] = {}
        self.busy_until_s: dict[str, float] = {}  # when each arm's current task should end (the allocator's estimate)
        self.losses: list[dict] = []
        self.parts: dict[int, PartView] = {}
        self.sim_time_s = 0.0
        self.last_decision_tick = -10**9
        self.decisions = 0
        self._progress_at = 0.0
        self.events_seen = 0
        self._due: tuple[int, int, float] | None = None  # (tick, events published by then, wall deadline) of a pending decision
        self.capacity = capacity_bound(scene, reach=self.reach)  # what the line could do at best, for the summary
        conveyor = scene.conveyor  # the belt's last reachable point, worked out once before the run starts
        self.last_reach_along_belt_m = last_reach_along_belt_m(conveyor, self.arm_views(), conveyor.pose.xyz[2] + 0.015) if conveyor else None

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        for pub in [*self._assign_pubs.values(), self._tick_pub, self._progress_pub, self._separation_pub]:
            pub.undeclare()

    def wait(self, timeout_s: float) -> None:
        """Sleep until a message arrives (heartbeat checks still run every `timeout_s`)."""
        self._inbox.wait(timeout_s)

    def _on_heartbeat_arrival(self, sample: zenoh.Sample) -> None:
        """Only stamps the arrival time: a coordinator busy planning must not mistake queued heartbeats for silence."""
        try:
            self._heard_at[Keys.arm_of(str(sample.key_expr))] = time.monotonic()
        except ValueError:
            pass

    # --- inputs ---------------------------------------------------------------------
    def poll(self) -> bool:
        """Handle everything queued, in order. True if anything was."""
        items = self._inbox.drain()
        for key, payload in items:
            leaf = key.rsplit("/", 1)[-1]
            msg = self._decoders[leaf].decode(key, payload) if leaf in self._decoders else None
            if msg is None:
                continue
            problem = self._problem(leaf, msg)
            if problem:
                self.drops.drop(key, problem)
            elif leaf == "events":
                self._on_event(msg)
            elif leaf == "frame":
                self._on_frame(msg)
            else:
                self._on_status(msg)
        self._check_heartbeats()
        self._decide_when_complete()
        if time.monotonic() - self._progress_at > PROGRESS_PERIOD_S:
            self.publish_progress()
        return bool(items)

    def _problem(self, leaf: str, msg) -> str:
        """Why a decoded message cannot be true ("" if it can): it is then dropped and counted, never acted on."""
        if leaf == "events":
            return self.sim_clock.problem(msg.tick) or self.ledger.event_problem(msg.kind, msg.part_id, msg.detail, msg.type_index)
        if leaf == "frame":
            problem = self.sim_clock.problem(msg.tick) or parts_problem(msg.parts)
            if not problem and sorted(s.arm for s in msg.arms) != sorted(self.arm_names):
                problem = "a frame whose arms are not this line's"
            for s in msg.arms if not problem else ():
                problem = problem or arm_state_problem(s, s.arm, self._dof[s.arm]) or ("" if s.tick == msg.tick else "a frame mixing ticks")
            if not problem:
                self.sim_clock.believe(msg.tick)
            return problem
        if msg.arm not in self.skill:
            return f"a heartbeat of no arm of this line ({msg.arm!r})"
        return ""

    def _on_event(self, e: LineEvent) -> None:
        self.events_seen += 1
        self.ledger.on_event(e.kind, e.part_id, e.detail, e.type_index, e.tick / self.scene.control_hz)

    def _on_frame(self, f: LineView) -> None:
        for s in f.arms:
            self._on_state(s)
        self._on_parts(f.parts)

    def _on_state(self, s: ArmState) -> None:
        if s.arm not in self.skill or s.tick <= self.last_tick[s.arm]:
            return  # count each tick once
        self.last_tick[s.arm] = s.tick
        self.acts_at_tick[s.arm] = s.next_tick + s.period_ticks  # heard with its next state, answered a period later
        self.skill[s.arm] = s.skill
        self.guard.set_state(s.arm, np.asarray(s.q))
        # a new request is one whose number differs from the last taken (a respawned controller counts from 1 again)
        if s.request_seq > 0 and s.request_seq != self.request_seq[s.arm] and len(s.request_q_to) == len(s.q):
            self.request_seq[s.arm] = s.request_seq
            n = len(s.q)
            then_q = tuple(tuple(s.request_then_q[k:k + n]) for k in range(0, len(s.request_then_q), n))
            self.requests[s.arm] = TimedPath(s.arm, s.q, s.request_q_to, s.sim_time_s, s.sim_time_s + s.request_duration_s,
                                             then_q, tuple(s.request_then_after_s))
        if s.lost and s.arm not in self.lost:
            self._arm_lost(s.arm, "the sim stopped hearing its controller", time.monotonic() - self._heard_at.get(s.arm, 0.0))
        self.ledger.arm_report(s.arm, s.task_id, s.skill, s.sim_time_s, s.failure)

    def _on_status(self, s: ArmStatus) -> None:
        if s.arm not in self.skill:
            return
        previous = self.heartbeat_at.get(s.arm)
        self.heartbeat_at[s.arm] = self._heard_at.get(s.arm, time.monotonic())
        known = self.incarnation.setdefault(s.arm, s.incarnation)
        if known != s.incarnation:  # restarted faster than the heartbeat timeout: still a loss
            self.incarnation[s.arm] = s.incarnation
            if s.arm not in self.lost:
                self._arm_lost(s.arm, "its controller restarted", self.heartbeat_at[s.arm] - (previous or 0.0))
        if s.arm in self.lost:  # a respawned controller rejoined
            del self.lost[s.arm]
            self.losses.append({"arm": s.arm, "event": "rejoined", "sim_time_s": round(self.sim_time_s, 3)})

    def _on_parts(self, p: PartsState) -> None:
        self.sim_time_s = p.sim_time_s
        self.parts = {
            pid: PartView(np.array(p.positions[3 * i : 3 * i + 3]), np.array(p.velocities[3 * i : 3 * i + 3]))
            for i, pid in enumerate(p.part_ids)
        }
        due = p.tick % self.period_ticks == 0 if self.lockstep else p.tick - self.last_decision_tick >= self.period_ticks
        if due and p.tick > self.last_decision_tick and (self._due is None or self._due[0] != p.tick):  # a re-sent frame: once
            self._due = (p.tick, p.events_published, time.monotonic() + DECISION_WAIT_S)

    def _decide_when_complete(self) -> None:
        """Decide for the due frame's tick once every event published before it is in.

        Events and frames travel on different keys and may arrive in either order; waiting for
        them is what makes a lockstep run repeat exactly.
        """
        if self._due is None:
            return
        tick, events, deadline = self._due
        complete = self.events_seen >= events
        if complete or time.monotonic() > deadline:
            self._due = None
            self.decide(tick)

    def _check_heartbeats(self) -> None:
        now = time.monotonic()
        for arm in self.heartbeat_at:
            at = self._heard_at.get(arm, self.heartbeat_at[arm])
            if arm not in self.lost and now - at > self.heartbeat_timeout_s:
                self._arm_lost(arm, f"no heartbeat for {self.heartbeat_timeout_s} s", silent_for_s=now - at)

    def _arm_lost(self, arm: str, why: str, silent_for_s: float) -> None:
        self.lost[arm] = self.sim_time_s
        self.requests.pop(arm, None)
        self.guard.release(arm)  # its granted path is void: it holds still where it is
        returned = self.ledger.arm_lost(arm, self.sim_time_s)
        self.losses.append({
            "arm": arm, "event": "lost", "why": why, "sim_time_s": round(self.sim_time_s, 3),
            "silent_for_s": round(silent_for_s, 3), "tasks_returned": returned,
        })
        print(f"coordinator: arm {arm} lost ({why}); {len(returned)} task(s) back in the pool", file=sys.stderr, flush=True)

    # --- decisions ------------------------------------------------------------------
    def arm_views(self) -> list[ArmView]:
        open_arms = {t.arm for t in self.ledger.tasks.values() if t.state.value in ("assigned", "active")}
        return [
            ArmView(
                a, self.bases[a], a not in self.lost and a not in open_arms and self.skill[a] in IDLE_SKILLS, self.reach[a],
                tuple(self.guard.state[a].tolist()), self.free_in_s(a) if a in open_arms else None, a not in self.lost,
            )
            for a in self.arm_names
        ]

    def free_in_s(self, arm: str) -> float | None:
        """About when a busy arm's task ends; None once it overran its estimate (or is lost): not planned for."""
        remaining = self.busy_until_s.get(arm, -math.inf) - self.last_decision_tick / self.scene.control_hz
        return None if arm in self.lost or remaining < -OVERRUN_S else max(remaining, 0.0)

    def busy_stations(self) -> set[str]:
        """Stations in use: by open tasks, and by arms still moving away from their last task's stations."""
        busy = self.ledger.busy_stations()
        for arm, stations in self.last_stations.items():
            if self.skill[arm] not in IDLE_SKILLS and arm not in self.lost:
                busy.update(stations)
        return busy

    def decide(self, tick: int) -> None:
        """Refresh tasks, allocate, publish assignments (and the lockstep barrier's answer)."""
        now = tick / self.scene.control_hz
        self.last_decision_tick = tick
        self.decisions += 1
        if len(self.arm_names) > 1:
            self.watch_separations(now)
        self.answer_motion_requests(now)
        self.reassign_late_tasks(now)
        pending = self.ledger.refresh(now)
        for task in pending:
            if task.source == CONVEYOR and task.task_id not in self.deadline_known and task.part_id in self.parts:
                self.deadline_known.add(task.task_id)
                task.deadline_s = belt_deadline_s(self.scene.conveyor, self.last_reach_along_belt_m, self.parts[task.part_id], now)
        if pending:
            views = self.arm_views()
            cost_s = TimeCost(Eligibility(self.scene, views))
            for task_id, arm in self.allocator.allocate(pending, views, self.parts, self.busy_stations()):
                task = self.ledger.assign(task_id, arm, now)
                self.busy_until_s[arm] = now + cost_s(next(v for v in views if v.name == arm), task, self.parts[task.part_id])
                self._send(task, arm)
        self._tick_pub.put(encode(CoordTick(tick, tuple(self.assign_seq[a] for a in self.arm_names))))

    def reassign_late_tasks(self, now_s: float) -> None:
        """A belt task whose arm has not started moving for it, and can no longer meet the part, goes back to the
        pool (its arm is told to drop it), so an arm further down the belt can still take it before its deadline."""
        views = {v.name: v for v in self.arm_views()}
        rules = Eligibility(self.scene, list(views.values()))
        for task in list(self.ledger.tasks.values()):
            arm = task.arm
            not_started = task.state == TaskState.ASSIGNED or (task.state == TaskState.ACTIVE and self.skill.get(arm) == "approach" and arm in self.requests)
            part = self.parts.get(task.part_id)
            if arm is None or part is None or not not_started or not cannot_make_it(rules, views[arm], task, part):
                continue
            self.ledger.requeue(task.task_id, f"{arm} could no longer meet the part")
            self.requests.pop(arm, None)
            self.reassigned += 1
            self.assign_seq[arm] += 1
            self._assign_pubs[arm].put(encode(Assignment(arm, self.assign_seq[arm], None, task.part_id, 0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))))

    def answer_motion_requests(self, now_s: float) -> None:
        """Check every waiting request with the guard, arms in scene order (one global order: no cycle of waits).

        A grant starts when the arm next hears from the sim (its controller acts on it then), for the duration
        asked; `deny` (an arm that is not moving is in the way) goes back
        to the arm; `wait` (an arm with a granted move is in the way) stays here until that move is over.
        """
        self.guard.expire(now_s)
        for arm in [a for a in self.arm_names if a in self.requests]:
            asked = self.requests[arm]
            hz = self.scene.control_hz
            start = max(self.acts_at_tick[arm], self.last_decision_tick + 1) / hz  # the controller's answer to its next state
            path = dataclasses.replace(asked, t_start_s=start, t_end_s=start + (asked.t_end_s - asked.t_start_s))
            self.guard.set_state(arm, np.asarray(asked.q_from))
            verdict = self.guard.request(path)
            if verdict.decision == "wait":
                continue
            del self.requests[arm]
            self.grants_given += verdict.granted
            self.assign_seq[arm] += 1
            self._assign_pubs[arm].put(encode(MotionGrant(
                arm, self.assign_seq[arm], self.request_seq[arm], verdict.decision, verdict.conflict_arm or "",
                verdict.min_separation_m if math.isfinite(verdict.min_separation_m) else -1.0, start if verdict.granted else -1.0,
            )))

    def watch_separations(self, now_s: float) -> None:
        """The cell's closest approach, sampled at the decision rate; each arm's nearest neighbour goes to the monitor."""
        pairs = self.guard.nearest_pairs()
        if pairs and pairs[0].distance_m < self.min_separation_m:
            self.min_separation_m, self.closest_pair = pairs[0].distance_m, (pairs[0].a, pairs[0].b)
        self._separation_pub.put(encode(separations_from_pairs(now_s, pairs, self.guard.margin_m)))

    def _send(self, task: Task, arm: str) -> None:
        part, rec = self.parts[task.part_id], self.ledger.parts[task.part_id]
        station = self.scene.station(task.target)
        velocity = self._belt_velocity() if task.source == CONVEYOR else (0.0, 0.0, 0.0)
        place = (station.pose.xyz[0], station.pose.xyz[1], self.ledger.place_height_m(task.target))
        self.assign_seq[arm] += 1
        self.last_stations[arm] = task.stations
        self._assign_pubs[arm].put(encode(Assignment(
            arm, self.assign_seq[arm], task.task_id, task.part_id, float(part.position[2] - rec.height_m / 2), place, velocity,
        )))

    def _belt_velocity(self) -> tuple[float, float, float]:
        c = self.scene.conveyor
        return tuple(d * c.speed_m_per_s for d in c.direction) if c else (0.0, 0.0, 0.0)

    def publish_progress(self) -> None:
        self._progress_at = time.monotonic()
        t = self.ledger.totals()
        busy = sum(s not in IDLE_SKILLS for s in self.skill.values())
        closest = self.min_separation_m if math.isfinite(self.min_separation_m) else -1.0
        self._progress_pub.put(encode(Progress(
            self.sim_time_s, t["parts_spawned"], t["parts_completed"], t["parts_missed"], busy,
            t.get("parts_failed", 0), self.guard.denied, closest,
        )))

    def report(self) -> dict:
        return self.ledger.totals() | {
            "allocator": self.allocator.name,
            "arm_events": self.losses,
            "unfinished_parts": self.ledger.unfinished(),
            "tasks": [
                {"task_id": t.task_id, "part_id": t.part_id, "source": t.source, "target": t.target, "state": t.state.value,
                 "arm": t.arm, "created_s": t.created_s, "assigned_s": t.assigned_s, "deadline_s": t.deadline_s, "done_s": t.done_s,
                 "reassignments": t.reassignments, "reason": t.reason}
                for t in self.ledger.tasks.values()
            ],
            "decisions": self.decisions,
            "grants_denied": self.guard.denied,
            "grants_given": self.grants_given,
            "tasks_reassigned": self.reassigned,
            "grant_waits": self.guard.waits,
            "grant_requests_open": {a: round(self.sim_time_s - p.t_start_s, 3) for a, p in self.requests.items()},
            "min_separation_m": round(self.min_separation_m, 4) if math.isfinite(self.min_separation_m) else None,
            "closest_pair": list(self.closest_pair) if self.closest_pair else None,
            "dropped_messages": self.drops.total,
            "capacity": self.capacity.as_dict(),
            "capacity_measured": self.measured_capacity(),
        }

    def measured_capacity(self) -> dict | None:
        """The capacity bound again with the hop times this run measured (None before any task was done)."""
        measured = measured_hop_seconds(list(self.ledger.tasks.values()))
        if not measured:
            return None
        return capacity_bound(self.scene, measured, self.reach).as_dict() | {"measured_hop_s": {
            f"{arm}: {source} -> {target}": round(s, 3) for (arm, source, target), s in sorted(measured.items())}}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fleet-coordinator", description=__doc__.splitlines()[0])
    add_scene_arguments(parser)
    parser.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    parser.add_argument("--allocator", choices=tuple(ALLOCATORS), default="optimal")
    parser.add_argument("--report", help="write the end-of-run figures to this JSON file")
    add_bus_arguments(parser)
    opened = node_arguments(parser, argv, "coordinator")
    if opened is None:
        return 2
    args, stop, scene = opened
    with open_session(BusEndpoints.from_args(args)) as session:
        node = CoordinatorNode(session, Keys(args.run), scene, lockstep=args.mode == "lockstep", allocator=make_allocator(args.allocator, scene))
        try:
            while not stop.should_stop():
                if not node.poll():
                    node.wait(0.05)
        finally:
            node.publish_progress()
            node.close()
            write_report(args.report, node.report() | {"stopped_by": stop.reason})
    return 0


if __name__ == "__main__":
    sys.exit(main())
