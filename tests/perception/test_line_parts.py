"""The line's parts bound to tracks: a released part is seen once a track of its kind appears near where it was set
down, follows its track, is unseen when the track ends, and is seen again where the line put it."""

import numpy as np

from perception.detect import Detection
from perception.line_parts import LineParts
from perception.tracks import PartTracks, Track
from tests.perception.test_tracks import FRAME_S, belt_under


def seen(x: float, y: float, t: float, kind: int = 0) -> Detection:
    """A part of `kind` seen whole at (x, y), turned 0.3 rad."""
    return Detection("overhead", t, kind, (x, y, 0.1), 0.3, 12, 0.9)


def frames(line: LineParts, tracks: PartTracks, detections_at, start: int, stop: int) -> None:
    for k in range(start, stop):
        t = k * FRAME_S
        line.update("overhead", tracks.update(detections_at(t), t), t)


def test_a_released_part_is_unseen_until_a_track_of_its_kind_appears_near_its_drop_spot_then_follows_it():
    line, tracks = LineParts(belt_under), PartTracks(belt_under)
    line.arrived(7, kind=0, spot_m=np.array([0.0, 0.0, 0.1]), time_s=0.0)
    line.arrived(8, kind=1, spot_m=np.array([0.0, 0.0, 0.1]), time_s=0.0)
    assert line.seen(0.0) == [], "released, not yet seen: no pose"
    frames(line, tracks, lambda t: [seen(0.1 * t, 0.0, t)], 0, 6)
    (part, top_m), *others = line.seen(1.0)
    assert part.part_id == 7 and not others, "the track is of kind 0: part 8 (kind 1) stays unseen"
    assert np.allclose(top_m, [0.1, 0.0, 0.1]) and part.yaw_rad == 0.3


def test_a_track_far_from_where_the_line_expects_a_part_binds_to_none():
    line, tracks = LineParts(belt_under), PartTracks(belt_under)
    line.arrived(7, kind=0, spot_m=np.array([0.0, 0.0, 0.1]), time_s=0.0)
    frames(line, tracks, lambda t: [seen(0.6, 0.5, t)], 0, 4)  # a part of its colour off the belt, far away
    assert line.seen(0.8) == []


def test_a_part_whose_track_ends_is_unseen_and_seen_again_where_the_line_put_it():
    line, tracks = LineParts(belt_under), PartTracks(belt_under, keep_s=0.5)
    line.arrived(7, kind=0, spot_m=np.array([0.0, 0.0, 0.1]), time_s=0.0)
    frames(line, tracks, lambda t: [seen(0.1 * t, 0.0, t)], 0, 5)
    frames(line, tracks, lambda t: [], 5, 10)  # picked: gone from the belt, its track dropped
    assert line.seen(2.0) == []
    line.moved(7, np.array([0.5, 0.5, 0.1]), 2.0, spread_m=0.08)  # the line says it lies in a bin there
    frames(line, tracks, lambda t: [seen(0.55, 0.52, t)], 10, 13)
    (part, top_m), *_ = line.seen(2.4)
    assert part.part_id == 7 and np.allclose(top_m, [0.55, 0.52, 0.1])


def test_two_parts_released_one_after_another_keep_their_order_along_the_belt():
    line, tracks = LineParts(belt_under), PartTracks(belt_under)
    line.arrived(1, kind=0, spot_m=np.array([0.0, 0.0, 0.1]), time_s=0.0)
    frames(line, tracks, lambda t: [seen(0.1 * t, 0.0, t)], 0, 5)
    line.arrived(2, kind=0, spot_m=np.array([0.0, 0.0, 0.1]), time_s=1.0)
    frames(line, tracks, lambda t: [seen(0.1 * t, 0.0, t), seen(0.1 * (t - 1.0), 0.0, t)], 5, 10)
    where = {part.part_id: top_m[0] for part, top_m in line.seen(2.0)}
    assert np.isclose(where[1], 0.2) and np.isclose(where[2], 0.1)


def test_a_part_gone_from_the_line_is_forgotten():
    line, tracks = LineParts(belt_under), PartTracks(belt_under)
    line.arrived(7, kind=0, spot_m=np.array([0.0, 0.0, 0.1]), time_s=0.0)
    frames(line, tracks, lambda t: [seen(0.1 * t, 0.0, t)], 0, 3)
    line.gone(7)
    assert line.seen(0.6) == [] and 7 not in line.parts


def test_look_alike_parts_in_one_bin_are_bound_in_the_order_the_line_put_them_there():
    line = LineParts(belt_under)
    bin_centre = np.array([0.5, 0.5, 0.1])
    line.arrived(2, kind=0, spot_m=bin_centre, time_s=0.0, spread_m=0.08)
    line.arrived(3, kind=0, spot_m=bin_centre, time_s=0.4, spread_m=0.08)
    older = Track(11, 0, np.array([0.52, 0.46, 0.1]), 0.0, seen_s=0.8, first_s=0.2, hits=4, confidence=0.9)
    newer = Track(12, 0, np.array([0.49, 0.53, 0.1]), 0.0, seen_s=1.0, first_s=0.6, hits=3, confidence=0.9)
    line.update("overhead", [older, newer], 1.0)  # the older track hidden in this frame: both are free to bind
    assert line.parts[2].track == ("overhead", 11) and line.parts[3].track == ("overhead", 12)


def test_a_part_the_line_puts_where_its_track_already_shows_it_keeps_its_track():
    line, tracks = LineParts(belt_under), PartTracks(belt_under)
    line.arrived(7, kind=0, spot_m=np.array([0.5, 0.5, 0.1]), time_s=0.0, spread_m=0.08)
    frames(line, tracks, lambda t: [seen(0.52, 0.48, t)], 0, 3)
    track = line.parts[7].track
    line.moved(7, np.array([0.5, 0.5, 0.1]), 0.6, spread_m=0.08)  # the line says it rests in that bin
    assert line.parts[7].track == track
