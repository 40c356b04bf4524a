"""The sim scores perception's parts against the truth of the frame they were seen in. When the line stops,
perception's answer to the last frame is still on its way: the score waits for it, so the same run scores the
same frames every time."""

import threading
import time

from fleet.bus.codec import encode
from fleet.bus.messages import PartsState
from fleet.bus.session import Inbox
from fleet.common.scene_loading import load_checked_scene
from fleet.sim.cameras.rig import CameraRig
from fleet.sim.cameras.seen_score import SeenScore
from fleet.sim.world import World


def answer(inbox: Inbox, tick: int, world: World) -> None:
    """Perception's parts for frame `tick`, as its node would put them: every part where the world holds it."""
    parts = world.active_parts()
    msg = PartsState(
        tick,
        tick / 1000.0,
        tuple(p.part_id for p in parts),
        tuple(p.feeder for p in parts),
        tuple(p.type_index for p in parts),
        tuple(float(v) for p in parts for v in p.position),
        tuple(float(v) for p in parts for v in p.quaternion_wxyz),
        tuple(0.0 for p in parts for _ in range(3)),
        tuple(float(v) for p in parts for v in p.size_m),
    )
    inbox.items.append(("seen/parts", encode(msg)))
    inbox.wake.set()


def test_the_answer_to_the_last_frame_is_awaited_when_the_line_stops():
    scene = load_checked_scene("pick_cell")
    world = World(scene)
    world.step(1500)
    rig, inbox = CameraRig(world), Inbox()
    score = SeenScore(inbox, scene.stations)
    for tick in (1500, 1550):
        score.frame(tick, world, rig.frames())
    answer(inbox, 1500, world)
    score.take()
    assert score.frames_scored == 1
    late = threading.Timer(0.3, answer, (inbox, 1550, world))  # the last frame's answer, on its way
    late.start()
    start = time.monotonic()
    assert score.settle(timeout_s=5.0), "the last frame's answer came"
    late.join()
    assert score.frames_scored == 2 and time.monotonic() - start < 4.0
    report = score.report()
    assert report["frames_scored"] == 2 and report["position_error_p95_mm"] == 0.0 and report["precision"] == 1.0


def test_a_perception_that_never_answers_holds_the_end_only_as_long_as_asked():
    scene = load_checked_scene("pick_cell")
    world = World(scene)
    score = SeenScore(Inbox(), scene.stations)
    score.frame(0, world, CameraRig(world).frames())
    start = time.monotonic()
    assert not score.settle(timeout_s=0.2)
    assert 0.2 <= time.monotonic() - start < 2.0 and score.frames_scored == 0
