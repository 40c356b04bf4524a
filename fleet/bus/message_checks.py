"""Well-formed lies: what a receiver checks before it believes a message that decoded fine.

Decoding proves shape; these checks are about meaning: finite numbers, lengths that fit,
and ticks or sequence numbers not far ahead of what the receiver has seen from the sender
(a message from the future is refused, not adopted, so it cannot make every true message
look stale). Each check returns the reason to refuse, or "" to accept; receivers drop
refused messages and count them by reason, as they do malformed ones.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from robots.saved_state import SavedState

MAX_AHEAD_S = 2.0  # a sender's tick may run this far (sim seconds) ahead of the newest one believed
MAX_SEQ_JUMP = 1000  # an order count may jump this far ahead of the newest one believed


def not_finite(values: Iterable[float]) -> bool:
    return not all(math.isfinite(v) for v in values)


class TickClock:
    """The newest tick believed from one sender; the first message sets it, later ones may run at most
    `max_ahead_ticks` past it."""

    def __init__(self, control_hz: float, max_ahead_s: float = MAX_AHEAD_S) -> None:
        self.max_ahead_ticks = max(1, round(control_hz * max_ahead_s))
        self.newest: int | None = None

    def problem(self, tick: int) -> str:
        if tick < 0:
            return "a negative tick"
        if self.newest is not None and tick > self.newest + self.max_ahead_ticks:
            return f"tick {tick} is far ahead of the sender's clock ({self.newest})"
        return ""

    def believe(self, tick: int) -> None:
        self.newest = tick if self.newest is None else max(self.newest, tick)


def seq_problem(seq: int, newest: int | None) -> str:
    if seq < 0:
        return "a negative sequence number"
    if newest is not None and seq > newest + MAX_SEQ_JUMP:
        return f"sequence number {seq} jumps far ahead of {newest}"
    return ""


def arm_state_problem(state, arm: str, n_joints: int) -> str:
    """An `ArmState` that cannot be the sim's report of `arm`."""
    if state.arm != arm:
        return f"a state of {state.arm!r} on {arm}'s key"
    if len(state.q) != n_joints or len(state.dq) != n_joints:
        return f"a state with {len(state.q)} joints (the arm has {n_joints})"
    if not_finite(
        (
            state.sim_time_s,
            *state.q,
            *state.dq,
            *state.gripper_q,
            *state.tool_position,
            *state.request_q_to,
            state.request_duration_s,
            *state.desired_q,
            *state.desired_dq,
        )
    ):
        return "a state with NaN or infinite values"
    return request_problem(state, n_joints)


def request_problem(msg, n_joints: int) -> str:
    """A motion request (in a `ControllerStep` or echoed in an `ArmState`) the guard could not check."""
    if msg.request_seq < 0 or len(msg.request_q_to) not in (0, n_joints):
        return f"a motion request with {len(msg.request_q_to)} joints (the arm has {n_joints}) or a negative seq"
    if not_finite((*msg.request_q_to, msg.request_duration_s)) or not 0.0 <= msg.request_duration_s <= 600.0:
        return "a motion request with a duration that is not 0..600 s or non-finite joints"
    then_q, then_s = msg.request_then_q, msg.request_then_after_s
    if len(then_q) != len(then_s) * n_joints or not_finite((*then_q, *then_s)):
        return (
            f"a motion request whose local stage has {len(then_q)} joint values for {len(then_s)} times, "
            "or non-finite ones"
        )
    if any(b <= a for a, b in zip((0.0, *then_s), then_s)) or (then_s and then_s[-1] > 60.0):
        return "a motion request whose local stage times do not increase within 0..60 s"
    return ""


def parts_problem(parts) -> str:
    """A `PartsState` whose arrays do not fit its part ids, or with non-finite values."""
    k = len(parts.part_ids)
    sizes = (
        len(parts.feeders),
        len(parts.type_indices),
        len(parts.positions) // 3,
        len(parts.quaternions_wxyz) // 4,
        len(parts.velocities) // 3,
        len(parts.sizes_m) // 3,
    )
    if any(s != k for s in sizes) or len(parts.positions) != 3 * k:
        return "parts whose arrays do not fit their ids"
    if not_finite((parts.sim_time_s, *parts.positions, *parts.velocities, *parts.sizes_m)):
        return "parts with NaN or infinite values"
    return ""


class IncarnationsState(SavedState, frozen=True):
    """What `Incarnations` saves: the starts believed of each node."""

    started: dict[str, int]
    newest: dict[str, int]


class Incarnations:
    """Which incarnation of each node to believe. On a line the launcher started (`from_roster`), a node's
    incarnation is the one the launcher's latest `Roster` names (1 until it names another): it changes only through
    a start the launcher did. Without a launcher, the newest heard, never going back (a replaced node's late
    messages are ghosts)."""

    def __init__(self, from_roster: bool) -> None:
        self.from_roster = from_roster
        self.started: dict[str, int] = {}
        self.newest: dict[str, int] = {}

    def state(self) -> IncarnationsState:
        return IncarnationsState(started=dict(self.started), newest=dict(self.newest))

    def restore(self, state: IncarnationsState) -> None:
        self.started, self.newest = dict(state.started), dict(state.newest)

    def roster_problem(self, roster) -> str:
        """A roster that takes a node back to an earlier start, or names one with a start below 1."""
        if len(roster.nodes) != len(roster.incarnations) or min(roster.incarnations, default=1) < 1:
            return "a roster whose nodes and incarnations do not pair up, or with one below 1"
        back = [n for n, i in zip(roster.nodes, roster.incarnations) if i < self.started.get(n, 1)]
        return f"a roster that takes {', '.join(back)} back to an earlier start" if back else ""

    def hear_roster(self, roster) -> None:
        self.started.update(zip(roster.nodes, roster.incarnations))

    def problem(self, node: str, incarnation: int) -> str:
        if self.from_roster:
            started = self.started.get(node, 1)
            if incarnation != started:
                return f"incarnation {incarnation} of {node}, which the launcher started as {started}"
            return ""
        newest = self.newest.get(node)
        if newest is not None and incarnation < newest:
            return f"incarnation {incarnation} of {node} after {newest} spoke (a replaced node)"
        return ""

    def believe(self, node: str, incarnation: int) -> None:
        self.newest[node] = max(self.newest.get(node, incarnation), incarnation)


END_SLACK_S = 30.0  # a line may report this far past its end (it settles its last parts after the duration)


def progress_problem(p, arms: int, end_s: float = math.inf) -> str:
    """A `Progress` that cannot be the coordinator's: a line of `arms` arms that ends at `end_s` sim seconds."""
    counts = (p.parts_spawned, p.parts_completed, p.parts_missed, p.busy_arms, p.parts_failed, p.grants_denied)
    if not_finite((p.sim_time_s, p.min_separation_m)):
        return "progress with NaN or infinite values"
    if min(counts) < 0 or p.min_separation_m < -1.0:
        return "progress with negative counts"
    if not 0.0 <= p.sim_time_s <= end_s + END_SLACK_S:
        return f"progress at {p.sim_time_s:g} s of a line that ends at {end_s:g} s"
    if p.parts_completed + p.parts_missed + p.parts_failed > p.parts_spawned or p.busy_arms > arms:
        return "progress with more parts done than spawned, or more arms busy than the line has"
    return ""


def sim_status_problem(
    s, arms: list[str], mode: str | None = None, control_hz: float | None = None, end_s: float = math.inf
) -> str:
    """A `SimStatus` that cannot be the sim's: a line of `arms` (in `mode`, at `control_hz`, ending at `end_s`:
    each checked where the receiver knows it)."""
    if not_finite((s.sim_time_s, s.speed, s.latency_p99_ms, s.last_contact_s, *s.utilisation)):
        return "a sim status with NaN or infinite values"
    if s.tick < 0 or s.contact_ticks < 0 or not 0.0 <= s.sim_time_s <= end_s + END_SLACK_S:
        return f"a sim status at tick {s.tick}, {s.sim_time_s:g} s, of a line that ends at {end_s:g} s"
    if control_hz is not None and abs(s.tick / control_hz - s.sim_time_s) > 1.5 / control_hz:
        return f"a sim status whose tick {s.tick} is not its sim time {s.sim_time_s:g} s"
    if mode not in (None, s.mode) or len(s.utilisation) != len(arms) or not set(s.arms_lost) <= set(arms):
        return "a sim status of another line (its mode, its arms)"
    return ""


def heartbeat_problem(s) -> str:
    """An `ArmStatus` with numbers no controller sends."""
    # a controller that has answered no state yet beats at sim time -1
    if not_finite((s.sim_time_s, s.progress, s.busy_s, *s.place_xyz)) or s.sim_time_s < -1.0 or s.seq < 0:
        return "a heartbeat with NaN, infinite or negative values"
    return ""


def detections_problem(d, kinds: int) -> str:
    """A `PartDetections` that cannot be perception's of a line with `kinds` kinds of part ("": it can)."""
    n = len(d.track_ids)
    lengths = (len(d.kinds), len(d.yaws_rad), len(d.confidences), len(d.seen_s), len(d.top_centres_m) // 3)
    if any(length != n for length in lengths) or len(d.top_centres_m) != 3 * n:
        return "detections whose lists differ in length"
    if not_finite((d.sim_time_s, *d.top_centres_m, *d.yaws_rad, *d.confidences, *d.seen_s)):
        return "detections with NaN or infinite values"
    if d.tick < 0 or any(k < 0 or k >= kinds for k in d.kinds) or any(not 0.0 <= c <= 1.0 for c in d.confidences):
        return "detections of an unknown kind, a negative tick or a confidence outside 0-1"
    if any(s > d.sim_time_s + 1e-9 for s in d.seen_s) or len(set(d.track_ids)) != n:
        return "detections seen after their frame, or a track twice"
    return ""
