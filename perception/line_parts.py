"""The line's parts as its cameras show them: each part the line knows of (a feeder released it, the line put it at a
station) is bound to the track of its kind that appears nearest where the line expects it; from then on its pose is
that track's. A part no track is bound to is not seen: the line has no pose for it."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from perception.tracks import Track

BIND_GATE_M = 0.12  # a new track this close to where the line expects an unseen part of its kind is that part
RANK_TIE_M = 0.001  # between tracks as near an unseen part's expected spot, the oldest track goes to the oldest part
FAR = 1e6


@dataclass
class LinePart:
    """One part the line knows of, `kind` as perception tells kinds apart. Unseen (`track` None): expected at
    `expected_m` (a top face's centre, world) as of `expected_s`, carried by the surface under it since. Seen: its
    track's (camera, track id), where its top face was seen (`top_centre_m` at `seen_s`) and its turn."""

    part_id: int
    kind: int
    expected_m: np.ndarray
    expected_s: float
    gate_m: float = BIND_GATE_M  # how far from its expected spot a new track may be and still be this part
    spread_m: float = 0.0  # within this of its expected spot it is as likely anywhere (a bin: any of its spots)
    track: tuple[str, int] | None = None
    top_centre_m: np.ndarray | None = None
    yaw_rad: float = 0.0
    seen_s: float = -1.0
    confidence: float = 0.0


class LineParts:
    """Binds tracks (`perception.tracks`) to the line's parts. `velocity_at` gives the velocity (m/s, world) of the
    surface under a point, as the tracks use it."""

    def __init__(self, velocity_at: Callable[[np.ndarray], np.ndarray], gate_m: float = BIND_GATE_M) -> None:
        self.velocity_at, self.gate_m = velocity_at, gate_m
        self.parts: dict[int, LinePart] = {}
        self.first_seen_s: dict[int, float] = {}  # by part: when it was first bound (never: absent)

    def arrived(self, part_id: int, kind: int, spot_m: np.ndarray, time_s: float, spread_m: float = 0.0) -> None:
        """A part the line released at `time_s`, expected with its top face's centre at `spot_m`, give or take
        `spread_m` (a feeder's jitter, a bin's size)."""
        gate = max(self.gate_m, spread_m + 0.02)
        self.parts[part_id] = LinePart(part_id, kind, np.asarray(spot_m, float), time_s, gate, spread_m)

    def moved(self, part_id: int, spot_m: np.ndarray, time_s: float, spread_m: float = 0.0) -> None:
        """The line put a part at `spot_m` (a station, give or take `spread_m`): expected there, seen again only by
        a track found there (a part whose track already shows it there keeps it)."""
        part = self.parts.get(part_id)
        if part is None:
            return
        spot = np.asarray(spot_m, float)
        there = part.top_centre_m is not None and np.hypot(*(part.top_centre_m - spot)[:2]) <= spread_m + 0.02
        if part.track is not None and there:
            return
        part.track, part.expected_m, part.expected_s = None, spot, time_s
        part.gate_m, part.spread_m = max(self.gate_m, spread_m + 0.02), spread_m

    def gone(self, part_id: int) -> None:
        """A part that left the line (lost, retired)."""
        self.parts.pop(part_id, None)

    def expected_at(self, part: LinePart, time_s: float) -> np.ndarray:
        """Where an unseen part is expected at `time_s`: its expected spot carried by the surface under it."""
        velocity = np.asarray(self.velocity_at(part.expected_m), float)
        return part.expected_m + velocity * (time_s - part.expected_s)

    def update(self, camera: str, tracks: list[Track], time_s: float) -> None:
        """One frame's believed tracks of `camera` (at `time_s`): bound parts follow their tracks, a part whose
        track ended is unseen (expected where it was last seen), and the tracks no part follows bind to the unseen
        parts of their kind expected nearest them, the pairs chosen together (`_bind`)."""
        live = {t.track_id: t for t in tracks}
        bound = set()
        for part in self.parts.values():
            if part.track is None or part.track[0] != camera:
                continue
            track = live.get(part.track[1])
            if track is None:
                part.track, part.expected_m, part.expected_s = None, part.top_centre_m, part.seen_s
                part.spread_m = 0.0  # it was seen just there
            else:
                self._follow(part, camera, track)
                bound.add(track.track_id)
        self._bind(camera, [t for t in tracks if t.track_id not in bound], time_s)

    def _bind(self, camera: str, free: list[Track], time_s: float) -> None:
        """Pair the tracks no part follows with the unseen parts: of one kind, within the part's gate, the least
        total distance beyond each part's spread; where that ties (look-alike parts in one bin), the oldest track
        with the part the line released or put there first (`RANK_TIE_M`)."""
        unseen = sorted((p for p in self.parts.values() if p.track is None), key=lambda p: (p.expected_s, p.part_id))
        free = sorted(free, key=lambda t: (t.first_s, t.track_id))
        if not free or not unseen:
            return
        cost = np.full((len(free), len(unseen)), FAR)
        for i, track in enumerate(free):
            at = track.top_centre_m + np.asarray(self.velocity_at(track.top_centre_m)) * (time_s - track.seen_s)
            for j, part in enumerate(unseen):
                gap_m = float(np.hypot(*(at - self.expected_at(part, time_s))[:2]))
                if track.kind == part.kind and gap_m <= part.gate_m:
                    cost[i, j] = max(0.0, gap_m - part.spread_m) + RANK_TIE_M * abs(i - j)
        for i, j in zip(*linear_sum_assignment(cost)):
            if cost[i, j] < FAR:
                self._follow(unseen[j], camera, free[i])
                self.first_seen_s.setdefault(unseen[j].part_id, time_s)

    def _follow(self, part: LinePart, camera: str, track: Track) -> None:
        part.track, part.top_centre_m, part.yaw_rad = (camera, track.track_id), track.top_centre_m, track.yaw_rad
        part.seen_s, part.confidence = track.seen_s, track.confidence

    def seen(self, time_s: float) -> list[tuple[LinePart, np.ndarray]]:
        """The parts seen, in part order, each with its top face's centre at `time_s` (carried by its surface
        since it was last seen)."""
        out = []
        for part_id in sorted(self.parts):
            part = self.parts[part_id]
            if part.track is not None:
                velocity = np.asarray(self.velocity_at(part.top_centre_m), float)
                out.append((part, part.top_centre_m + velocity * (time_s - part.seen_s)))
        return out
