"""Tracks of parts over frames' detections: carried by the belt while hidden, kept apart side by side, dropped once
gone."""

import numpy as np

from perception.detect import Detection
from perception.tracks import PartTracks

BELT_M_PER_S = np.array([0.1, 0.0, 0.0])
FRAME_S = 0.2  # 5 Hz


def belt_under(point: np.ndarray) -> np.ndarray:
    return BELT_M_PER_S if abs(point[1]) < 0.1 else np.zeros(3)


def seen(x: float, y: float, t: float, kind: int = 0) -> Detection:
    return Detection("overhead", t, kind, (x, y, 0.1), 0.0, 12, 0.9)


def test_a_part_hidden_for_a_few_frames_keeps_its_track():
    tracks = PartTracks(belt_under)
    ids = []
    for k in range(15):
        t = k * FRAME_S
        hidden = 5 <= k < 9  # under an arm for 4 frames (0.8 s)
        believed = tracks.update([] if hidden else [seen(0.1 * t, 0.0, t)], t)
        ids += [tr.track_id for tr in believed]
    assert set(ids) == {1}, "one part, one track, through the frames it was hidden"
    assert np.allclose(tracks.predicted_m(tracks.tracks[0], 3.0)[:2], [0.3, 0.0], atol=1e-9)


def test_two_parts_side_by_side_keep_their_own_tracks_and_a_part_of_another_kind_starts_its_own():
    tracks = PartTracks(belt_under)
    for k in range(10):
        t = k * FRAME_S
        tracks.update([seen(0.1 * t, 0.0, t), seen(0.1 * t + 0.04, 0.0, t), seen(0.1 * t, 0.0, t, kind=1)], t)
    by_id = {tr.track_id: tr for tr in tracks.believed()}
    assert len(by_id) == 3
    assert by_id[1].top_centre_m[0] + 0.04 == by_id[2].top_centre_m[0] and by_id[3].kind == 1


def test_a_track_unseen_longer_than_it_is_kept_is_dropped_and_a_part_seen_once_is_not_believed():
    tracks = PartTracks(belt_under, keep_s=1.0)
    assert tracks.update([seen(0.0, 0.0, 0.0)], 0.0) == [], "seen once: not yet believed"
    assert [tr.track_id for tr in tracks.update([seen(0.02, 0.0, 0.2)], 0.2)] == [1]
    assert tracks.update([], 1.3) == [], "unseen 1.1 s: dropped"
    assert tracks.update([seen(0.15, 0.0, 1.5)], 1.5) == [] and tracks.tracks[0].track_id == 2, "a new track"


def test_a_part_off_the_belt_is_not_carried():
    tracks = PartTracks(belt_under)
    tracks.update([seen(0.5, 0.5, 0.0)], 0.0)
    assert np.allclose(tracks.predicted_m(tracks.tracks[0], 10.0), [0.5, 0.5, 0.1])
