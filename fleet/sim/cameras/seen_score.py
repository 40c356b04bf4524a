"""How well the line saw (`fleet run --perception cameras`): perception's parts (`seen/parts`) scored against the
world's truth at each frame they were seen in. The truth never leaves the sim: it only scores."""

from __future__ import annotations

import time

import numpy as np
from scipy.spatial.transform import Rotation

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.messages import PartsState
from fleet.bus.session import Inbox
from fleet.sim.cameras import labels
from fleet.sim.cameras.frames import CameraFrame
from fleet.sim.line_watch import station_containing
from fleet.sim.world import PartInfo, World
from scenes.schema import Station

RIGHT_M = 0.03  # a seen part within this of its part's true centre is seen right
KEEP_FRAMES = 64  # frames' truth kept for perception's answers still on their way
SETTLE_S = 2.0  # after the last tick, how long perception's answer to the last frame is awaited


def top_face_yaw(part: PartInfo) -> tuple[float, bool]:
    """The world direction of the longer side of the part's face that looks up (a box lying on its side shows
    another face than its top), and whether that face is square."""
    w, x, y, z = part.quaternion_wxyz
    axes = Rotation.from_quat([x, y, z, w]).as_matrix().T  # rows: the body's x, y, z in the world
    up = int(np.argmax(np.abs(axes[:, 2])))  # the body axis nearest the vertical: the face across it looks up
    sides = [i for i in range(3) if i != up]
    longer = max(sides, key=lambda i: part.size_m[i])
    square = abs(part.size_m[sides[0]] - part.size_m[sides[1]]) < 1e-6
    return float(np.arctan2(axes[longer, 1], axes[longer, 0])), square


def yaw_error_deg(part: PartInfo, seen_yaw_rad: float) -> float | None:
    """How far a seen turn (its longer side's direction) is from the part's longer side, in degrees, modulo the
    part's symmetry (None: round)."""
    if part.round:
        return None
    yaw, square = top_face_yaw(part)
    period = np.pi / 2 if square else np.pi
    d = (seen_yaw_rad - yaw) % period
    return float(np.degrees(min(d, period - d)))


class SeenScore:
    """Truth taken at each frame (`frame`), perception's parts taken off `inbox` (`take`) and scored against the
    truth of their frame: position and yaw error, recall of the parts visible in the frame, precision."""

    def __init__(self, inbox: Inbox, stations: list[Station] = ()) -> None:
        """`stations`: the line's, so that errors of parts at rest in them are told from those on their way."""
        self.inbox, self.stations = inbox, list(stations)
        self.drops = DropCounter()
        self._decoder = Decoder(PartsState, self.drops)
        self.truth: dict[int, tuple[dict[int, PartInfo], set[int]]] = {}  # by frame tick: parts, ids visible
        self.errors_mm: list[float] = []
        self.errors_at_stations_mm: list[float] = []  # of parts lying in a station (bins, trays, fixtures)
        self.yaw_errors_deg: list[float] = []
        self.visible = self.visible_seen = self.seen = self.seen_right = self.frames_scored = 0
        self.ever_seen: set[int] = set()
        self.ever_visible: set[int] = set()
        self.newest_answered = -1  # the newest frame tick perception answered

    def frame(self, tick: int, world: World, frames: dict[str, CameraFrame]) -> None:
        """The truth at a frame tick: every active part, and the ids some camera shows a pixel of."""
        visible = set()
        for frame in frames.values():
            if frame.segmentation is not None:
                ids = np.unique(frame.segmentation)
                visible |= {int(v) - labels.PART_BASE for v in ids if v >= labels.PART_BASE}
        self.truth[tick] = ({p.part_id: p for p in world.active_parts()}, visible)
        self.ever_visible |= visible
        while len(self.truth) > KEEP_FRAMES:
            del self.truth[min(self.truth)]

    def take(self) -> None:
        for key, payload in self.inbox.drain():
            msg = self._decoder.decode(key, payload)
            if msg is not None:
                self.newest_answered = max(self.newest_answered, msg.tick)
            if msg is not None and msg.tick in self.truth:
                self._score(msg, *self.truth.pop(msg.tick))

    def settle(self, timeout_s: float = SETTLE_S) -> bool:
        """After the last tick: perception's answers up to the last frame taken, awaited up to `timeout_s` (they
        are on their way when the line stops; scoring whichever arrived in time would not repeat). Whether they came."""
        last = max(self.truth, default=-1)
        deadline = time.monotonic() + timeout_s
        self.take()
        while self.newest_answered < last and time.monotonic() < deadline:
            self.inbox.wait(0.02)
            self.take()
        return self.newest_answered >= last

    def _score(self, msg: PartsState, parts: dict[int, PartInfo], visible: set[int]) -> None:
        self.frames_scored += 1
        right = set()
        for i, pid in enumerate(msg.part_ids):
            self.seen += 1
            part = parts.get(pid)
            if part is None:
                continue
            gap_m = float(np.linalg.norm(np.asarray(msg.positions[3 * i : 3 * i + 3]) - part.position))
            self.errors_mm.append(1000.0 * gap_m)
            if station_containing(self.stations, part.position) is not None:
                self.errors_at_stations_mm.append(1000.0 * gap_m)
            w, _, _, z = msg.quaternions_wxyz[4 * i : 4 * i + 4]
            body_yaw = 2.0 * np.arctan2(z, w)
            seen_yaw = body_yaw if part.size_m[0] >= part.size_m[1] else body_yaw + np.pi / 2
            if (yaw := yaw_error_deg(part, seen_yaw)) is not None:
                self.yaw_errors_deg.append(yaw)
            if gap_m <= RIGHT_M:
                right.add(pid)
        self.seen_right += len(right)
        self.visible += len(visible)
        self.visible_seen += len(visible & right)
        self.ever_seen |= right

    def report(self) -> dict:
        """The figures for the run summary's `perception` row."""

        def pct(values: list[float], q: float) -> float | None:
            return round(float(np.percentile(values, q)), 1) if values else None

        elsewhere = sorted(self.errors_mm)  # on the belt or in the air: all but those at stations
        for e in self.errors_at_stations_mm:
            elsewhere.remove(e)

        return {
            "frames_scored": self.frames_scored,
            "position_error_p50_mm": pct(self.errors_mm, 50),
            "position_error_p95_mm": pct(self.errors_mm, 95),
            "position_error_at_stations_p95_mm": pct(self.errors_at_stations_mm, 95),
            "position_error_elsewhere_p95_mm": pct(elsewhere, 95),
            "yaw_error_p50_deg": pct(self.yaw_errors_deg, 50),
            "yaw_error_p95_deg": pct(self.yaw_errors_deg, 95),
            "recall": round(self.visible_seen / self.visible, 3) if self.visible else None,
            "precision": round(self.seen_right / self.seen, 3) if self.seen else None,
            "parts_visible": len(self.ever_visible),
            "parts_never_seen": len(self.ever_visible - self.ever_seen),
        }
