"""Parts followed across frames: a detection joins the track its part's motion has carried nearest to it, so a part
hidden for a few frames (under an arm) keeps its track and its identity."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from perception.detect import Detection
from perception.matching import nearest_pairs

GATE_M = 0.03  # a detection farther than this from every track's predicted spot starts a track of its own
KEEP_S = 1.0  # a track unseen this long is dropped (its part picked, or gone)
CONFIRM_HITS = 2  # seen in this many frames before a track is believed


@dataclass
class Track:
    """One part as followed: of `kind`, last seen at `top_centre_m` at `seen_s` (sim seconds), turned `yaw_rad`."""

    track_id: int
    kind: int
    top_centre_m: np.ndarray
    yaw_rad: float
    seen_s: float
    first_s: float
    hits: int
    confidence: float


class PartTracks:
    """Tracks over a stream of frames' detections (`update`, in time order). `velocity_at` gives the velocity (m/s,
    world) of the surface under a point: the conveyor's on the belt, zero elsewhere; a track is carried by it."""

    def __init__(
        self,
        velocity_at: Callable[[np.ndarray], np.ndarray],
        gate_m: float = GATE_M,
        keep_s: float = KEEP_S,
        confirm_hits: int = CONFIRM_HITS,
    ) -> None:
        self.velocity_at, self.gate_m, self.keep_s, self.confirm_hits = velocity_at, gate_m, keep_s, confirm_hits
        self.tracks: list[Track] = []
        self._next_id = 1

    def predicted_m(self, track: Track, time_s: float) -> np.ndarray:
        """Where `track`'s part is at `time_s`, carried by its surface since it was seen."""
        return track.top_centre_m + np.asarray(self.velocity_at(track.top_centre_m), float) * (time_s - track.seen_s)

    def update(self, detections: list[Detection], time_s: float) -> list[Track]:
        """Take one frame's detections (of `time_s`): each joins the nearest track of its kind within the gate, the
        pairs chosen together; the others start tracks; tracks unseen for `keep_s` are dropped. The believed
        tracks (`believed`)."""
        self.tracks = [t for t in self.tracks if time_s - t.seen_s <= self.keep_s]
        joined = self._pairs(detections, time_s)
        for d_index, detection in enumerate(detections):
            track = joined.get(d_index)
            if track is None:
                track = Track(self._next_id, detection.kind, np.zeros(3), 0.0, time_s, time_s, 0, 0.0)
                self._next_id += 1
                self.tracks.append(track)
            track.top_centre_m = np.asarray(detection.top_centre_m, float)
            track.yaw_rad, track.seen_s, track.confidence = detection.yaw_rad, time_s, detection.confidence
            track.hits += 1
        return self.believed()

    def believed(self) -> list[Track]:
        """The tracks seen in `confirm_hits` frames or more."""
        return [t for t in self.tracks if t.hits >= self.confirm_hits]

    def _pairs(self, detections: list[Detection], time_s: float) -> dict[int, Track]:
        """Detection index -> the track it joins (`nearest_pairs` with the tracks carried to `time_s`)."""
        if not detections or not self.tracks:
            return {}
        pairs = nearest_pairs(
            np.array([d.top_centre_m for d in detections]),
            [d.kind for d in detections],
            np.array([self.predicted_m(t, time_s) for t in self.tracks]),
            [t.kind for t in self.tracks],
            self.gate_m,
        )
        return {i: self.tracks[j] for i, j, _ in pairs}
