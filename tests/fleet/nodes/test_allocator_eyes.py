"""An allocator that sees is handed the overhead camera's frames at its own rate: the newest frame usable at the
decision, each look once, what cannot be a frame dropped and counted."""

from fleet.bus.codec import DropCounter, encode
from fleet.nodes.allocator_eyes import AllocatorEyes
from tests.fleet.nodes.test_perception_feed import KEY, SCENE, drawn_frame  # pick_cell: 100 Hz, overhead at 5 Hz


def show(eyes: AllocatorEyes, tick: int) -> None:
    rgb, depth = drawn_frame(tick)
    eyes.take(KEY.format("rgb"), encode(rgb))
    eyes.take(KEY.format("depth"), encode(depth))


def test_each_look_sees_the_newest_usable_frame_once_at_the_allocators_rate():
    eyes, handed = AllocatorEyes(SCENE, 2.0, DropCounter()), []
    assert eyes.look_due(4) is None, "no frame is usable before 50 ms have passed"
    assert eyes.look_due(5) == 0 and not eyes.ready(0)
    show(eyes, 0)
    assert eyes.ready(0)
    eyes.hand(handed.append, 0)
    (frames,) = handed
    assert [f.camera for f in frames] == ["overhead"] and frames[0].rgb.shape == (60, 60, 3)
    assert eyes.look_due(30) is None and eyes.look_due(64) is None, "the frames of this half second: seen"
    assert eyes.look_due(65) == 60, "the next look: the frame at 0.6 s, the first usable of the next half second"
    assert eyes.report() == {"looks": 1, "frames_handed": 1, "looks_without_all_frames": 0}


def test_a_look_on_its_deadline_without_its_frame_is_counted_and_a_lie_dropped():
    drops = DropCounter()
    eyes, handed = AllocatorEyes(SCENE, 2.0, drops), []
    eyes.take(KEY.format("rgb"), b"\x93not an image")
    eyes.hand(handed.append, 0)
    assert handed == [[]] and eyes.report()["looks_without_all_frames"] == 1 and drops.total == 1
