"""The coordinator's view of the controllers' lives, driven by hand on the wall clock: an arm that stops beating
while the line runs is lost; a line that stalls (a lockstep line waits for its slowest node) costs no arm."""

import time

from coordinator.dispatcher import Dispatcher
from fleet.bus.codec import DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmStatus
from fleet.nodes.controller_lives import ControllerLives
from scenes import load_scene

TIMEOUT_S = 0.3
KEYS = Keys("lives")


def lives_of_two_arms(silence_loses: bool = True) -> tuple[ControllerLives, Dispatcher]:
    scene = load_scene("handover")
    dispatcher = Dispatcher(scene)
    arms = [a.name for a in scene.arms]
    drops, seqs = DropCounter(), {a: 0 for a in arms}
    return ControllerLives(arms, dispatcher, drops, seqs, roster=False, silence_loses=silence_loses), dispatcher


def beat(lives: ControllerLives, arm: str, seq: int, incarnation: int = 1) -> None:
    lives.on_status(KEYS.arm_status(arm), ArmStatus(arm, seq, 0.0, "idle", None, 0.0, incarnation=incarnation))


def run_for(lives: ControllerLives, seconds: float, beating: tuple[str, ...], until=lambda: False) -> None:
    """The line runs for `seconds` (or `until` holds): frames every 10 ms, heartbeats from `beating` every 50 ms,
    checks as it goes."""
    end, seq = time.monotonic() + seconds, 0
    while time.monotonic() < end and not until():
        lives.frame_read()
        seq += 1
        if seq % 5 == 0:
            for arm in beating:
                beat(lives, arm, seq)
        lives.check(TIMEOUT_S)
        time.sleep(0.01)


def test_an_arm_silent_while_the_line_runs_is_lost_and_its_silence_said():
    lives, dispatcher = lives_of_two_arms()
    beat(lives, "arm_0", 1), beat(lives, "arm_1", 1)
    run_for(lives, 10.0, beating=("arm_1",), until=lambda: dispatcher.losses)  # a busy machine may stall the loop
    assert set(dispatcher.lost) == {"arm_0"}, "lost, and no heartbeat brought it back"
    (loss,) = dispatcher.losses
    assert loss["why"] == f"no heartbeat for {TIMEOUT_S} s" and loss["silent_for_s"] >= TIMEOUT_S  # to the ms


def test_a_stalled_line_costs_no_arm_whose_heartbeats_come_back_with_it():
    lives, dispatcher = lives_of_two_arms()
    run_for(lives, 0.2, beating=("arm_0", "arm_1"))
    time.sleep(2 * TIMEOUT_S)  # no frame and no heartbeat: the whole line is held up
    run_for(lives, 0.1, beating=())  # frames come back first, the heartbeats a little after
    run_for(lives, 2 * TIMEOUT_S, beating=("arm_0", "arm_1"))
    assert dispatcher.losses == [], "the line's silence is no arm's"


def test_an_arm_that_stays_silent_after_a_stall_is_lost_a_timeout_after_the_line_came_back():
    lives, dispatcher = lives_of_two_arms()
    run_for(lives, 0.2, beating=("arm_0", "arm_1"))
    time.sleep(2 * TIMEOUT_S)
    came_back = time.monotonic()
    run_for(lives, 0.8 * TIMEOUT_S, beating=("arm_1",))
    assert dispatcher.losses == [], "judged only a timeout after the line came back"
    run_for(lives, 10.0, beating=("arm_1",), until=lambda: dispatcher.losses)
    assert [loss["arm"] for loss in dispatcher.losses] == ["arm_0"]
    assert dispatcher.losses[0]["silent_for_s"] > time.monotonic() - came_back > TIMEOUT_S


def test_a_line_that_falls_silent_with_its_arms_costs_no_arm_whose_last_beat_came_a_little_before_its_last_frame():
    lives, dispatcher = lives_of_two_arms()
    run_for(lives, 0.2, beating=("arm_0", "arm_1"))
    run_for(lives, 0.8 * TIMEOUT_S, beating=())  # the run ends: the arms stop, the sim's last frames still come
    for _ in range(40):  # then nothing arrives while the coordinator checks on, until it is stopped itself
        lives.check(TIMEOUT_S)
        time.sleep(0.01)
    assert dispatcher.losses == [], "silent together with the line, never for a timeout while it ran"


def test_frames_read_late_are_judged_by_when_they_arrived():
    lives, dispatcher = lives_of_two_arms()
    beat(lives, "arm_0", 1), beat(lives, "arm_1", 1)
    for _ in range(20):  # frames arrive every 10 ms; the heartbeats stop (the run ends) as the last ones do
        lives.frame_arrived()
        time.sleep(0.01)
    for _ in range(60):  # a busy coordinator reads the queued frames a while later, checking as it goes
        lives.frame_read()
        lives.check(TIMEOUT_S)
        time.sleep(0.01)
    assert dispatcher.losses == [], "the frames arrived while the arms still beat"


def test_on_a_lockstep_line_a_late_heartbeat_costs_no_arm_the_sim_and_a_restart_still_do():
    """A lockstep run repeats: a heartbeat thread a starved CPU runs late (its controller still answering every
    state, or the sim would wait) must not lose the arm. Only the sim's barrier or a new incarnation says it."""
    lives, dispatcher = lives_of_two_arms(silence_loses=False)
    beat(lives, "arm_0", 1), beat(lives, "arm_1", 1)
    run_for(lives, 3 * TIMEOUT_S, beating=("arm_1",))
    assert dispatcher.losses == [], "silent for three timeouts while the line ran, and not lost"
    assert lives.on_sim_state("arm_0", lost=True), "the sim no longer hears it: lost"
    beat(lives, "arm_1", 2, incarnation=2)
    lost = [(e["arm"], e["why"]) for e in dispatcher.losses if e["event"] == "lost"]
    assert lost == [("arm_1", "its controller restarted")], "and its new controller rejoins at once"
