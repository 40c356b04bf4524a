"""The run summary: the nodes' reports merged into one, with the line's bound, each arm's time and the faults."""

from __future__ import annotations

from dataclasses import dataclass

from fleet.bus.codec import DropCounter
from fleet.bus.messages import Progress
from fleet.run.run_node import (
    Node,
    node_of,
    read_report,
)
from scenes.schema import Scene


def count_problems(summary: dict) -> list[str]:
    """Why a summary's part counts do not add up (none when every spawned part is counted once): more parts done,
    missed or failed than spawned, or parts the coordinator never heard of."""
    spawned = summary["parts_spawned"]
    counted = sum(summary[k] for k in ("parts_completed", "parts_missed", "parts_failed"))
    unannounced = summary.get("parts_unannounced", 0)
    return [
        *([f"{counted} parts done, missed or failed of {spawned} spawned"] if counted > spawned else []),
        *([f"{unannounced} of {spawned} parts spawned were never announced"] if unannounced else []),
    ]


@dataclass(frozen=True)
class RunEnd:
    """What the launcher knows of a run when it ends, beside the nodes' reports: the summary's input."""

    scene: Scene
    seed: int | None
    mode: str
    secure_bus: bool
    nodes: list[Node]
    drops: DropCounter  # what the launcher itself heard and refused
    last_progress: Progress | None  # the line's counts as last heard (the summary's where the coordinator died)
    last_sim_time_s: float
    interrupted: str  # the signal that stopped the run ("" if none did)
    respawns: int
    respawn_requests: list[dict]
    server_urls: dict[str, str]


def _report_of(nodes: list[Node], role: str) -> dict:
    """The report of the node of `role` (empty where it wrote none, or there is none)."""
    node = node_of(nodes, role)
    return read_report(node.report) if node is not None else {}


def picks(tasks: list[dict]) -> dict:
    """The grasps the line tried and how they ended: a task done was picked; a task failed with `grasp_missed`
    closed the claw on nothing (a pose seen wrong, a part knocked away)."""
    done = sum(t["state"] == "done" for t in tasks)
    missed = sum(t.get("failure_code") == "grasp_missed" for t in tasks)
    vanished = sum(t.get("failure_code") == "part_vanished" for t in tasks)
    tried = done + missed
    return {
        "done": done,
        "grasp_missed": missed,
        "part_vanished": vanished,
        "success": round(done / tried, 3) if tried else None,
    }


class RunSummary:
    """The run summary of a run that ended: its nodes' reports (read once, each by its role) merged with what the
    launcher knows (`RunEnd`)."""

    def __init__(self, end: RunEnd) -> None:
        self.end = end
        self.sim, self.coord = _report_of(end.nodes, "sim"), _report_of(end.nodes, "coordinator")
        self.controllers = [read_report(n.report) for n in end.nodes if n.role == "controller"]
        monitor, seer = node_of(end.nodes, "monitor"), node_of(end.nodes, "perception")
        self.monitor = read_report(monitor.report) if monitor is not None else None
        self.perception = read_report(seer.report) if seer is not None else None

    def _perception(self) -> dict | None:
        """What seeing cost (`--perception cameras`): the perception node's figures, its parts scored against the
        truth (the sim's `seen`), and how old the parts the coordinator decided on were."""
        if self.perception is None:
            return None
        return self.perception | {
            "scored": (self.sim or {}).get("seen"),
            "coordinator": (self.coord or {}).get("seen_parts"),
            "picks": picks((self.coord or {}).get("tasks", [])),
        }

    @staticmethod
    def _capacity(capacity: dict | None, of_run: dict | None, completed: int, sim_s: float) -> dict:
        """The line's capacity bound (the coordinator's) and how much of it this run achieved; the same against the
        bound of this run's own arrivals (those in time to be finished), which a short run's luck moves."""
        if not capacity:
            return {
                "throughput_bound_per_min": None,
                "bound_fraction": None,
                "bottleneck": None,
                "run_bound_per_min": None,
                "run_bound_fraction": None,
                "parts_finishable": None,
                "parts_completable": None,
            }
        bound = capacity["throughput_bound_per_min"]
        achieved = completed / (sim_s / 60.0) if sim_s > 0 else 0.0
        busy = capacity["arm_busy_at_bound"] | capacity["station_busy_at_bound"]
        run_bound = of_run["throughput_bound_per_min"] if of_run else None
        return {
            "throughput_bound_per_min": bound,
            "bound_fraction": round(achieved / bound, 4) if bound > 0 else None,
            "bottleneck": {"name": capacity["bottleneck"], "busy_fraction_at_bound": busy.get(capacity["bottleneck"])},
            "run_bound_per_min": run_bound,
            "run_bound_fraction": round(achieved / run_bound, 4) if run_bound else None,
            "parts_finishable": of_run["parts_finishable"] if of_run else None,
            "parts_completable": of_run.get("parts_completable") if of_run else None,
            "capacity": capacity,
        }

    @staticmethod
    def _lockstep_timeouts(coord: dict, controllers: list[dict]) -> dict:
        """Lockstep waits that ran out (0.5 s of wall time) and went on without what they waited for: a decision made
        without every event, a controller's tick planned with older parts or without an announced order. Zero in
        a run that repeats exactly; more means the machine was too loaded for that."""
        return {
            "coordinator_decisions": coord.get("decisions_on_deadline", 0),
            "controllers": {
                c["arm"]: c.get("parts_late", 0) + c.get("missed_assignments", 0) for c in controllers if "arm" in c
            },
        }

    @staticmethod
    def _arm_time(arm_time: dict, held_s: dict, sim_s: float) -> dict:
        """The sim's per-arm fractions, with the time an arm held still for a fixture that was not ready yet (the
        coordinator's count) told apart from waiting for a grant: holding a part at the edge is the pipeline
        working, not a blocked move."""
        out = {}
        for arm, t in arm_time.items():
            held = min(held_s.get(arm, 0.0) / sim_s, t.get("waiting_for_grant", 0.0)) if sim_s > 0 else 0.0
            out[arm] = t | {
                "waiting_for_grant": round(t.get("waiting_for_grant", 0.0) - held, 4),
                "held_at_fixture": round(held, 4),
            }
        return out

    @staticmethod
    def _faults(links: dict, controllers: list[dict]) -> dict:
        """What the bus faults were and what they cost the controllers (goals sent again); empty without faults."""
        if not links:
            return {}
        return {"links": links, "goals_resent": {c["arm"]: c.get("goals_resent", 0) for c in controllers if "arm" in c}}

    def _realtime_clock(self) -> dict | None:
        """Realtime: the sim's clock against the wall (`fleet.sim.realtime_clock`), the controllers' answers and the
        coordinator's decisions; None in lockstep."""
        clock = self.sim.get("realtime_clock")
        if clock is None:
            return None
        decisions = self.coord.get("decision_wall_ms") or {}
        timed = {k: decisions[k] for k in ("p50", "p99") if k in decisions}
        return clock | {"coordinator_decision_ms": timed | {"worst": decisions["max"]} if timed else None}

    def summary(self, wall_s: float, error: str) -> dict:
        """The run summary: the nodes' reports merged (a dead node's figures from what was last heard of it)."""
        end, sim, coord = self.end, self.sim, self.coord
        heard = end.last_progress
        sim_s = sim.get("sim_seconds", max(end.last_sim_time_s, heard.sim_time_s if heard else 0.0))
        status = "error" if error else ("interrupted" if end.interrupted else "ok")
        return (
            {
                "scene": end.scene.name,
                "arms": len(end.scene.arms),
                "arm_ids": [a.name for a in end.scene.arms],
                "mode": end.mode,
                "seed": end.seed,
                "randomised": dict(end.scene.randomised),
                "allocator": coord.get("allocator"),
                "allocator_faults": coord.get("allocator_faults", {}),  # a plug-in's decisions greedy took instead
                "allocator_eyes": coord.get("allocator_eyes"),  # an allocator that sees: its looks at the cameras
                "pipeline": coord.get("pipeline"),
                "bus": "secure" if end.secure_bus else "insecure",
                "status": status,
                "error": error,
                "stopped_by": end.interrupted or sim.get("stopped_by", ""),
                "sim_seconds": sim_s,
                "wall_seconds": round(wall_s, 3),
                "loop_wall_seconds": sim.get("loop_wall_seconds"),
                "wall_s_by_stage": sim.get("wall_s_by_stage", {}),
                "realtime_clock": self._realtime_clock(),
            }
            | self._parts(sim_s)
            | self._coordination()
            | self._bus()
            | {
                "arms_lost": sim.get("arms_lost", []),
                "arm_events": coord.get("arm_events", []),
                "respawns": end.respawns,
                "coordinator_takeover": coord.get("takeover"),
                "respawn_requests": end.respawn_requests,
                "monitor": None if self.monitor is None else {"url": end.server_urls.get("monitor", "")} | self.monitor,
                "perception": self._perception(),
                "unfinished_parts": coord.get("unfinished_parts", []),
                "processes": [h for n in end.nodes for h in n.history] + [n.record() for n in end.nodes],
            }
        )

    def _parts(self, sim_s: float) -> dict:
        """Every part's fate counted, throughput, each arm's time and the line's bound."""
        sim, coord, heard = self.sim, self.coord, self.end.last_progress
        if coord:
            counts = {k: coord.get(k, 0) for k in ("parts_completed", "parts_missed", "parts_failed")}
        else:  # the coordinator died: its last progress message is what is known
            counts = {
                "parts_completed": heard.parts_completed if heard else 0,
                "parts_missed": heard.parts_missed if heard else 0,
                "parts_failed": heard.parts_failed if heard else 0,
            }
        spawned = sim.get("parts_spawned", max(heard.parts_spawned if heard else 0, sum(counts.values())))
        known = coord.get("parts_in_progress", 0) + sum(counts.values()) if coord and sim else spawned
        # parts the sim spawned that the coordinator never heard of (an arrival it was not told): on the line
        unannounced = max(0, spawned - known)
        in_progress = spawned - sum(counts.values())
        completed = counts["parts_completed"]
        return {
            "parts_spawned": spawned,
            "parts_completed": completed,
            "parts_missed": counts["parts_missed"],
            "parts_failed": counts["parts_failed"],
            "parts_in_progress": max(0, in_progress),
            "parts_unannounced": unannounced,
            "parts_buffered": coord.get("parts_buffered", 0),
            "throughput_per_min": round(completed / (sim_s / 60.0), 3) if sim_s > 0 else 0.0,
            "utilisation": sim.get("utilisation", {}),
            "arm_time": self._arm_time(sim.get("arm_time", {}), coord.get("held_at_station_s", {}), sim_s),
            **self._capacity(coord.get("capacity"), coord.get("capacity_of_run"), completed, sim_s),
            "capacity_measured": coord.get("capacity_measured"),
            "capacity_of_run": coord.get("capacity_of_run"),
            "feeder_held_s": sim.get("feeder_held_s", {}),
        }

    def _coordination(self) -> dict:
        """Contacts, separations, grants and the coordinator's timing."""
        sim, coord = self.sim, self.coord
        return {
            "inter_arm_contacts": sim.get("inter_arm_contacts", 0),
            "contact_pairs": sim.get("contact_pairs", []),
            "safety_refused_goals": sim.get("safety_refused_goals", {}),
            "safety_stops": sim.get("safety_stops", 0),
            "safety_separation_m": sim.get("safety_separation_m"),
            "min_separation_m": coord.get("min_separation_m"),
            "closest_pair": coord.get("closest_pair"),
            "grants_denied": coord.get("grants_denied", 0),
            "grants_given": coord.get("grants_given", 0),
            "grant_waits": coord.get("grant_waits", 0),
            "tasks_reassigned": coord.get("tasks_reassigned", 0),
            "grant_requests_open": coord.get("grant_requests_open", {}),
            "held_at_station_s": coord.get("held_at_station_s", {}),
            "lockstep_timeouts": self._lockstep_timeouts(coord, self.controllers),
            "decision_wall_ms": coord.get("decision_wall_ms", {}),
        }

    def _bus(self) -> dict:
        """Goal results, the bus's faults, messages and round trips, and every node's dropped messages."""
        sim, coord, controllers, monitor = self.sim, self.coord, self.controllers, self.monitor
        dropped = sim.get("dropped_messages", 0) + coord.get("dropped_messages", 0)
        dropped += sum(c.get("dropped_messages", 0) for c in controllers) + (monitor or {}).get("dropped_messages", 0)
        dropped += (self.perception or {}).get("dropped_messages", 0)
        dropped += self.end.drops.total
        return {
            "goal_results": sim.get("goal_results", {}),
            "network_faults": self._faults(sim.get("network_faults", {}), controllers),
            "bus_messages_per_arm_per_s": sim.get("bus_messages_per_arm_per_s", {}),
            "latency_p50_ms": sim.get("latency_p50_ms"),
            "latency_p99_ms": sim.get("latency_p99_ms"),
            "round_trip_histogram": sim.get("round_trip_histogram"),
            "bus_messages_out": sim.get("messages_out", {}),
            "dropped_messages": dropped,
            "refused_messages": self._refused(),
            "bus_refused": sim.get("bus_refused"),
            "restored_from": sim.get("restored_from"),
            "snapshots": sim.get("snapshots", []),
            "snapshots_failed": sim.get("snapshots_failed", []),
            "snapshots_retaken": sim.get("snapshots_retaken", 0),
            "snapshots_refused": sim.get("snapshots_refused", []),
            "snapshot_stall_ms_max": sim.get("snapshot_stall_ms_max"),
            "snapshot_stall_ms_median": sim.get("snapshot_stall_ms_median"),
            "snapshot_stall_ms_by_stage": sim.get("snapshot_stall_ms_by_stage", {}),
            "snapshot_next_ticks_ms_median": sim.get("snapshot_next_ticks_ms_median"),
            "snapshot_next_ticks_ms_max": sim.get("snapshot_next_ticks_ms_max"),
            "snapshot_bytes_max": sim.get("snapshot_bytes_max"),
            "snapshot_write_ms_max": sim.get("snapshot_write_ms_max"),
            "cameras": sim.get("cameras"),
        }

    def _refused(self) -> dict:
        """Each node's refused messages by kind (`DropCounter.kinds`), only the nodes that refused any."""
        reports = {"sim": self.sim, "coordinator": self.coord, "monitor": self.monitor or {}}
        reports["perception"] = self.perception or {}
        reports |= {c.get("arm", f"controller_{i}"): c for i, c in enumerate(self.controllers)}
        reports["launcher"] = {"refused_messages": self.end.drops.kinds()}
        return {node: r["refused_messages"] for node, r in reports.items() if r.get("refused_messages")}
