"""10,000 seeded wrong messages on every key of a running line (random bytes, truncated messages, well-formed
lies): each is dropped or refused and counted, and the lockstep run comes out exactly as a clean run of the
same seed.

The line is paused (its clock held between ticks, as a user's pause does) while they are poured and resumed once
they are all out: a lockstep line runs as fast as the machine allows and once finished its 18 s before a pour
spread over wall time had reached it (1,864 counted of 10,000 on a clean clone), so the count depended on the
machine's speed. A pause does not change a lockstep run: the clean run is not paused and the two must agree.

An insecure bus (`--insecure`): by default the router refuses wrong messages from a process without the role
before any node hears them (`tests/fleet/test_secure_bus.py`); here every node must stand on its own."""

import threading
import time

import pytest

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import SimControl
from fleet.bus.session import BusEndpoints, open_session
from fleet.run.launcher import Launcher, RunOptions
from robots.registry import get_robot
from tests.fleet.bus_fuzz import BusFuzzer
from tests.fleet.test_bus_lies import COUNTED
from tests.fleet.test_run import QUICK_LINE, assert_nothing_left

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

MESSAGES = 10_000
REFUSED_GOALS = ("goal_results",)  # the sim answers each refused goal with a `rejected` result: counted, not acted on


def run(fuzz: bool) -> tuple[dict, int]:
    sent: list[int] = []
    with Launcher(RunOptions(scene=QUICK_LINE, duration_s=18.0, seed=5, insecure=True)) as launcher:
        arms = [a.name for a in launcher.scene.arms]
        keys = Keys("line")
        fuzzer = BusFuzzer(keys, arms, get_robot(launcher.scene.arms[0].model).arm_dof, seed=11)
        with open_session(BusEndpoints(connect=(launcher.endpoint,))) as session:

            def pour() -> None:
                session.put(keys.control, encode(SimControl("fuzz test", paused=True)))
                for i, (key, payload) in enumerate(fuzzer.messages(MESSAGES)):
                    session.put(key, payload)
                    sent.append(1)
                    if i % 200 == 199:
                        time.sleep(0.02)  # spread over time, as a noisy neighbour would
                time.sleep(0.5)  # the last ones reach their nodes before the clock goes on
                session.put(keys.control, encode(SimControl("fuzz test", paused=False)))

            pourer = threading.Thread(target=pour, daemon=True)

            def start(progress) -> None:
                if fuzz and progress.sim_time_s > 1.0 and not pourer.is_alive() and not sent:
                    pourer.start()

            launcher.on_progress = start
            summary = launcher.run()
            if pourer.is_alive() or sent:
                pourer.join()
    assert_nothing_left(summary, launcher.endpoint)
    return summary, len(sent)


def test_ten_thousand_wrong_messages_on_every_key_change_nothing():
    clean, _ = run(fuzz=False)
    fuzzed, sent = run(fuzz=True)
    assert sent == MESSAGES
    assert fuzzed["status"] == "ok" and fuzzed["parts_completed"] >= 2
    assert fuzzed["dropped_messages"] > MESSAGES / 4, "dropped and counted by whoever received them"
    strip = lambda s: {k: v for k, v in s.items() if k not in COUNTED + REFUSED_GOALS}  # noqa: E731
    diff = {
        k: (clean.get(k), fuzzed.get(k))
        for k in set(strip(clean)) | set(strip(fuzzed))
        if clean.get(k) != fuzzed.get(k)
    }
    assert not diff, "the line ran exactly as without them"
