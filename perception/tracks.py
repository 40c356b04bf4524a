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
PARTIAL_SHARE = 0.7  # a blob with fewer pixels than this share of its track's fullest is a part half hidden...
PARTIAL_RISE_M = 0.01  # ...unless its top face rose this far above where its track had it (lifted, in a claw)


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
    pixels: int = 0  # the most pixels it showed in a frame


class PartTracks:
    """Tracks over a stream of frames' detections (`update`, in time order). `velocity_at` gives the velocity (m/s,
    world) of the surface under a point: the conveyor's on the belt, zero elsewhere; a track is carried by it.
    `rests_at` says whether a part whose top face is at a point can lie there (on the belt, in a bin: not in the
    air); None: anywhere."""

    def __init__(
        self,
        velocity_at: Callable[[np.ndarray], np.ndarray],
        gate_m: float = GATE_M,
        keep_s: float = KEEP_S,
        confirm_hits: int = CONFIRM_HITS,
        rests_at: Callable[[np.ndarray], bool] | None = None,
    ) -> None:
        self.velocity_at, self.gate_m, self.keep_s, self.confirm_hits = velocity_at, gate_m, keep_s, confirm_hits
        self.rests_at = rests_at
        self.tracks: list[Track] = []
        self._next_id = 1

    def predicted_m(self, track: Track, time_s: float) -> np.ndarray:
        """Where `track`'s part is at `time_s`, carried by its surface since it was seen."""
        return track.top_centre_m + np.asarray(self.velocity_at(track.top_centre_m), float) * (time_s - track.seen_s)

    def update(self, detections: list[Detection], time_s: float) -> list[Track]:
        """Take one frame's detections (of `time_s`): each joins the nearest track of its kind within the gate, the
        pairs chosen together; the others start tracks; tracks unseen for `keep_s` are dropped (one last seen where
        no part can rest, in the air in a claw, as soon as it is unseen: it moves, it is not hidden). A detection
        showing much less of its part than the track has seen (`PARTIAL_SHARE`), and no higher, is taken as seen
        where the track's motion carried it. The believed tracks (`believed`)."""
        self.tracks = [t for t in self.tracks if time_s - t.seen_s <= (self.keep_s if self.rests(t) else 0.0)]
        joined = self._pairs(detections, time_s)
        for d_index, detection in enumerate(detections):
            track = joined.get(d_index)
            if track is None:
                track = Track(self._next_id, detection.kind, np.zeros(3), 0.0, time_s, time_s, 0, 0.0)
                self._next_id += 1
                self.tracks.append(track)
            carried = self.predicted_m(track, time_s)
            lifted = track.hits > 0 and detection.top_centre_m[2] - carried[2] > PARTIAL_RISE_M
            if lifted or detection.pixels >= PARTIAL_SHARE * track.pixels:
                track.top_centre_m = np.asarray(detection.top_centre_m, float)
                track.yaw_rad, track.confidence = detection.yaw_rad, detection.confidence
            else:  # half hidden (a claw over it): its blob's centre is off; its motion says better where it is
                track.top_centre_m = carried
            track.pixels = max(track.pixels, detection.pixels)
            track.seen_s = time_s
            track.hits += 1
        return self.believed()

    def rests(self, track: Track) -> bool:
        """Whether `track`'s part was last seen where a part can lie."""
        return self.rests_at is None or bool(self.rests_at(track.top_centre_m))

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
