"""`fleet run` with real processes on loopback Zenoh: parts get done, runs repeat for a seed, faults are survived.

Every test checks that no process of the run is left and that the sim's port is free again.
"""

import contextlib
import functools
import json
import os
import signal
import socket
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmStatus
from fleet.bus.session import BusEndpoints, Inbox, free_loopback_port, loopback_endpoint, open_session
from fleet.run.launcher import Launcher, RunOptions

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

QUICK_LINE = str(Path(__file__).parent / "scenes_data" / "quick_line.yaml")
# wall-clock figures, and the bus message counts (samples sent while processes start may find no subscriber yet)
# re-sends and status follow the wall clock
WALL_FIGURES = (
    "wall_seconds",
    "loop_wall_seconds",
    "wall_s_by_stage",
    "decision_wall_ms",
    "latency_p50_ms",
    "latency_p99_ms",
    "processes",
    "lockstep_timeouts",
    "bus_messages_per_arm_per_s",
    "round_trip_histogram",
    "bus_messages_out",
)


def assert_nothing_left(summary: dict, endpoint: str) -> None:
    """No process of the run left, its port free, and every part it spawned counted once."""
    fates = ("parts_completed", "parts_missed", "parts_failed", "parts_in_progress")
    assert summary["parts_spawned"] == sum(summary[k] for k in fates), {
        k: summary[k] for k in ("parts_spawned", *fates)
    }
    for p in summary["processes"]:
        with pytest.raises(ProcessLookupError):
            os.kill(p["pid"], 0)
    port = int(endpoint.rsplit(":", 1)[1])
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # closed connections may linger in TIME_WAIT
        s.bind(("127.0.0.1", port))  # fails with EADDRINUSE if anything still listens there
        s.listen()


def run_line(on_progress=None, **options) -> tuple[dict, Launcher]:
    with Launcher(RunOptions(**{"scene": QUICK_LINE, **options}), on_progress) as launcher:
        summary = launcher.run()
    return summary, launcher


def run_lines_together(*options: dict) -> list[tuple[dict, Launcher]]:
    """Several quick lines at once, each run from a thread of its own: a lockstep run's outcome does not depend on
    how loaded the machine is, so two that must agree may as well share it."""
    with ThreadPoolExecutor(len(options)) as pool:
        return list(pool.map(lambda o: run_line(**o), options))


@functools.cache
def clean_line_30s_seed_5() -> dict:
    """The quick line, 30 s, seed 5, nothing done to it: what runs that lost a node must still come to (run once)."""
    summary, launcher = run_line(duration_s=30.0, seed=5)
    assert_nothing_left(summary, launcher.endpoint)
    return summary


@pytest.mark.lockstep  # a lockstep line: no clock against the wall
def test_two_lockstep_runs_with_one_seed_complete_parts_identically():
    (first, launcher), (second, second_launcher) = run_lines_together(*[{"duration_s": 18.0, "seed": 5}] * 2)
    assert_nothing_left(first, launcher.endpoint)
    assert first["status"] == "ok" and first["sim_seconds"] == pytest.approx(18.0)
    assert first["parts_completed"] >= 2, first["unfinished_parts"]
    assert first["inter_arm_contacts"] == 0
    assert first["grants_given"] > 0, "every free move went through the collision guard"
    assert all(waited < 1.0 for waited in first["grant_requests_open"].values()), "nobody left waiting for a grant"
    assert first["dropped_messages"] == 0
    assert 0 < first["parts_finishable"] <= first["parts_spawned"], "parts in time to be finished, of those released"
    assert first["parts_completed"] <= first["run_bound_per_min"] * 18.0 / 60.0 + 1e-6, (
        "no run beats the bound of its own arrivals"
    )
    assert first["parts_completed"] <= first["parts_completable"] <= first["parts_finishable"]
    assert first["run_bound_fraction"] == pytest.approx(
        first["throughput_per_min"] / first["run_bound_per_min"], rel=1e-3
    )
    assert {p["role"] for p in first["processes"]} == {"sim", "coordinator", "controller"}
    assert all(p["exit_code"] == 0 for p in first["processes"])
    assert_nothing_left(second, second_launcher.endpoint)
    strip = lambda s: {k: v for k, v in s.items() if k not in WALL_FIGURES}  # noqa: E731
    assert strip(first) == strip(second)


def test_a_controller_killed_mid_run_is_noticed_its_task_reassigned_and_respawned():
    killed = []

    def kill_arm_0(progress):
        if not killed and progress.sim_time_s > 3.0:
            node = next(n for n in launcher_ref[0].nodes if n.name == "arm_0")
            killed.append((node.proc.pid, time.monotonic()))
            os.kill(node.proc.pid, signal.SIGKILL)

    launcher_ref = []
    # the respawned process takes seconds to start
    options = RunOptions(scene=QUICK_LINE, duration_s=30.0, seed=5, respawn=True)
    with Launcher(options, kill_arm_0) as launcher:
        launcher_ref.append(launcher)
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert killed and summary["status"] == "ok"
    assert summary["respawns"] == 1
    dead = [p for p in summary["processes"] if p["pid"] == killed[0][0]]
    assert dead == [{"role": "controller", "name": "arm_0", "pid": killed[0][0], "exit_code": -9}]
    events = [e for e in summary["arm_events"] if e["arm"] == "arm_0"]
    assert events, (summary["arm_events"], summary["arms_lost"], killed)
    assert [e["event"] for e in events] == ["lost", "rejoined"], events  # one loss, one rejoin: nothing counted twice
    assert events[0]["silent_for_s"] < 1.0
    assert summary["parts_completed"] >= 1, {
        k: summary[k]
        for k in (
            "parts_spawned",
            "parts_missed",
            "parts_failed",
            "parts_in_progress",
            "arm_events",
            "arm_time",
            "tasks_reassigned",
            "unfinished_parts",
        )
    }


def test_a_hung_coordinator_ends_a_lockstep_run_with_one_clear_message_instead_of_stalling_it():
    stopped = []

    def freeze_coordinator(progress):
        coordinator = launcher_ref[0].nodes[1]
        if not stopped and progress.sim_time_s > 1.0:
            stopped.append(progress.sim_time_s)
            os.kill(coordinator.proc.pid, signal.SIGSTOP)  # alive, silent: the sim gives up on it after 3 s

    launcher_ref = []
    with Launcher(RunOptions(scene=QUICK_LINE, duration_s=30.0), freeze_coordinator) as launcher:
        launcher_ref.append(launcher)
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert stopped and summary["status"] == "error"
    assert (
        summary["error"].startswith("the sim stopped: the coordinator did not answer") and "\n" not in summary["error"]
    )
    # the sim does not step while it waits
    assert summary["sim_seconds"] < stopped[0] + 3.0, (stopped, summary["sim_seconds"])


@pytest.mark.parametrize(
    "index, says",
    [
        (1, "the coordinator crashed (exit -9)"),
        (0, "the sim server crashed (exit -9)"),
        (None, "the node factory exited (exit -9); every node it forked died with it"),
    ],
    ids=["coordinator", "sim", "node factory"],
)
def test_a_crashed_node_ends_the_run_with_one_clear_message_and_every_part_accounted_for(index, says):
    """A dead coordinator, sim or node factory (and with it every node): one line why, and the counts from what the
    launcher last heard."""

    def kill(progress):
        launcher = launcher_ref[0]
        if progress.sim_time_s <= 3.0:
            return
        if index is None and launcher.factory.proc.poll() is None:
            os.kill(launcher.factory.proc.pid, signal.SIGKILL)
        elif index is not None and launcher.nodes[index].alive:
            os.kill(launcher.nodes[index].proc.pid, signal.SIGKILL)

    launcher_ref = []
    with Launcher(RunOptions(scene=QUICK_LINE, duration_s=30.0), kill) as launcher:
        launcher_ref.append(launcher)
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert summary["status"] == "error" and summary["error"].startswith(says)
    assert "\n" not in summary["error"]
    fates = ("parts_completed", "parts_missed", "parts_failed", "parts_in_progress")
    assert summary["sim_seconds"] > 1.0 and summary["parts_spawned"] > 0, summary
    assert summary["parts_spawned"] == sum(summary[k] for k in fates), {
        k: summary[k] for k in ("parts_spawned", *fates)
    }


def test_a_coordinator_killed_with_respawn_is_replaced_and_takes_over_the_line_with_nothing_lost():
    """kill -9 of the coordinator while an arm works on a part: a lockstep sim holds the line, the launcher starts
    another coordinator, which rebuilds its ledger from the sim's event log, adopts the arm's task, and the line
    ends as a clean run does."""
    killed = []
    # phases in which the part is not about to rest at its target
    WORKING = ("approach", "descend", "close", "lift", "transfer")

    # on Zenoh's thread: the moment a heartbeat (every 0.2 s of wall time) says an arm works on a part
    def kill_when_carrying(sample):
        beat = Decoder(ArmStatus, DropCounter()).decode(str(sample.key_expr), sample.payload.to_bytes())
        coordinator = launcher_ref[0].nodes[1]
        if (
            not killed
            and beat is not None
            and beat.phase in WORKING
            and beat.part_id >= 0
            and beat.sim_time_s > 3.0
            and coordinator.alive
        ):
            killed.append((coordinator.proc.pid, beat))
            os.kill(coordinator.proc.pid, signal.SIGKILL)

    def listen(progress):  # once the run is up: a session of the test's own on the run's bus
        if not launcher_ref[1:]:
            launcher_ref.append("listening")
            session = listening.enter_context(open_session(launcher_ref[0].client_endpoints()))
            listening.callback(
                session.declare_subscriber(Keys("line").all_arms("status"), kill_when_carrying).undeclare
            )

    launcher_ref = []
    with contextlib.ExitStack() as listening:
        with Launcher(RunOptions(scene=QUICK_LINE, duration_s=30.0, seed=5, respawn=True), listen) as launcher:
            launcher_ref.append(launcher)
            summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert killed and summary["status"] == "ok", (summary["error"], killed)
    assert summary["respawns"] == 1
    dead = [p for p in summary["processes"] if p["pid"] == killed[0][0]]
    assert dead == [{"role": "coordinator", "name": "coordinator", "pid": killed[0][0], "exit_code": -9}]
    takeover = summary["coordinator_takeover"]
    assert (
        takeover["incarnation"] == 2
        and takeover["events_replayed"] >= 1
        and takeover["sim_time_s"] >= killed[0][1].sim_time_s
    )
    assert takeover["arms_heard"] == summary["arm_ids"]
    carrying = killed[0][1]
    assert (carrying.arm, carrying.part_id) in [(t["arm"], t["part_id"]) for t in takeover["tasks_adopted"]], takeover
    fates = ("parts_completed", "parts_missed", "parts_failed", "parts_in_progress")
    assert summary["parts_spawned"] == sum(summary[k] for k in fates), {
        k: summary[k] for k in ("parts_spawned", *fates)
    }
    assert summary["inter_arm_contacts"] == 0 and summary["dropped_messages"] == 0
    clean = clean_line_30s_seed_5()
    assert [summary[k] for k in ("parts_spawned", *fates)] == [clean[k] for k in ("parts_spawned", *fates)], (
        "nothing lost"
    )


def test_a_hung_coordinator_with_respawn_is_replaced_and_the_line_goes_on():
    """Alive but silent (SIGSTOP): with `--respawn` the launcher replaces it once it has said nothing for
    `hung_after_s` (10 s unless told; 3 s here), and the new coordinator takes over the line, which ends as a clean
    run does."""
    stopped = []

    def freeze_coordinator(progress):
        coordinator = launcher_ref[0].nodes[1]
        if not stopped and progress.sim_time_s > 5.0:
            stopped.append(coordinator.proc.pid)
            os.kill(coordinator.proc.pid, signal.SIGSTOP)

    launcher_ref, said = [], []
    with Launcher(
        RunOptions(scene=QUICK_LINE, duration_s=30.0, seed=5, respawn=True, hung_after_s=3.0),
        freeze_coordinator,
        on_message=said.append,
    ) as launcher:
        launcher_ref.append(launcher)
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert stopped and summary["status"] == "ok", summary["error"]
    assert "the coordinator said nothing for 3 s; replacing it" in said
    assert [p["exit_code"] for p in summary["processes"] if p["pid"] == stopped[0]] == [-9]
    assert summary["coordinator_takeover"]["incarnation"] == 2
    clean = clean_line_30s_seed_5()
    fates = ("parts_spawned", "parts_completed", "parts_missed", "parts_failed", "parts_in_progress")
    assert [summary[k] for k in fates] == [clean[k] for k in fates], "nothing lost"


def test_garbage_on_every_command_key_is_counted_and_ctrl_c_stops_everything(tmp_path):
    endpoint = loopback_endpoint(free_loopback_port())
    summary_file = tmp_path / "summary.json"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "fleet",
            "run",
            QUICK_LINE,
            "--duration",
            "600",
            "--listen",
            endpoint,
            "--run-id",
            "garbage",
            "--summary",
            str(summary_file),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        keys = Keys("garbage")
        sent = 0
        with open_session(BusEndpoints(connect=(endpoint,))) as session:
            status = Inbox()
            # the sim's own status: it is sent from its loop, once it listens on every key (the coordinator may report
            # progress before the sim has built its world and declared them: garbage sent then reaches nobody)
            sub = session.declare_subscriber(keys.sim_status, status)
            running_by = time.monotonic() + 60
            while not status.items and time.monotonic() < running_by:  # wait for the line to run
                status.wait(0.1)
            sub.undeclare()
            assert status.items, "the sim never said it runs"
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and sent < 200:
                for arm in ("arm_0", "arm_1"):
                    session.put(keys.arm_step(arm), os.urandom(int.from_bytes(os.urandom(1), "little") % 64))
                    sent += 1
                time.sleep(0.02)
            time.sleep(3.0)  # the line keeps running after the garbage
            assert proc.poll() is None, proc.stderr.read().decode()[-2000:] if proc.poll() is not None else ""
        start = time.monotonic()
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=10)
        stopped_in_s = time.monotonic() - start
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    summary = json.loads(summary_file.read_text())
    assert code == 130 and summary["status"] == "interrupted"
    assert stopped_in_s < 2.5
    assert summary["dropped_messages"] >= sent
    assert summary["sim_seconds"] > 0
    assert_nothing_left(summary, endpoint)


def test_realtime_mode_paces_the_sim_on_the_wall_clock():
    summary, launcher = run_line(duration_s=6.0, mode="realtime", speed=2.0)
    assert_nothing_left(summary, launcher.endpoint)
    assert summary["status"] == "ok" and summary["mode"] == "realtime"
    assert 2.7 < summary["loop_wall_seconds"] < 4.5  # 6 sim s at 2x real time: 3 s of wall clock
    assert summary["inter_arm_contacts"] == 0
    # the clock, measured: 2 sim seconds a wall second within 5% (a slow moment of a busy machine), every tick's
    # lateness, each controller's answers and the coordinator's decisions timed
    clock = summary["realtime_clock"]
    assert clock["speed"] == 2.0 and abs(clock["rtf_error"]) < 0.05 and clock["rtf"] == pytest.approx(2.0, rel=0.05)
    assert clock["paced_sim_s"] > 5.0 and clock["sim_scheduling"] == "normal"
    for figure in ("sim_tick_late_ms", "controller_answer_ms", "coordinator_decision_ms"):
        assert 0 <= clock[figure]["p50"] <= clock[figure]["p99"] <= clock[figure]["worst"], (figure, clock)


def test_a_respawn_request_on_the_bus_restarts_a_dead_controller_and_is_refused_for_a_live_one():
    """What the monitor's Respawn button sends: the launcher obeys it only for a controller that died or went silent."""
    from fleet.bus.codec import encode
    from fleet.bus.messages import RespawnRequest

    steps, messages = [], []
    launcher_ref = []

    def drive(progress):
        launcher = launcher_ref[0]
        arm_0 = next(n for n in launcher.nodes if n.name == "arm_0")
        if not steps and progress.sim_time_s > 2.0:
            steps.append("asked for a live one")
            session.put(keys.respawn, encode(RespawnRequest("arm_0", "test")))
        elif len(steps) == 1 and launcher.supervision.respawn_requests:
            steps.append("killed")
            os.kill(arm_0.proc.pid, signal.SIGKILL)
            arm_0.proc.wait()
            session.put(keys.respawn, encode(RespawnRequest("arm_0", "test")))

    keys = Keys("line")
    with Launcher(RunOptions(scene=QUICK_LINE, duration_s=30.0, seed=5), drive, on_message=messages.append) as launcher:
        launcher_ref.append(launcher)
        with open_session(launcher.client_endpoints("monitor")) as session:  # the monitor may ask for a respawn
            summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert steps == ["asked for a live one", "killed"]
    assert [(r["done"], r["reason"]) for r in summary["respawn_requests"]] == [
        (False, "its controller is alive and heard"),
        (True, ""),
    ]
    assert summary["respawns"] == 1
    assert any("refused" in m for m in messages) and any("respawned arm_0" in m for m in messages)
    assert [p["exit_code"] for p in summary["processes"] if p["name"] == "arm_0"] == [-9, 0]


def test_a_controller_killed_for_good_makes_exactly_its_arm_lost_and_the_line_goes_on():
    killed = []

    def kill_arm_1(progress):
        if not killed and progress.sim_time_s > 4.0:
            node = next(n for n in launcher_ref[0].nodes if n.name == "arm_1")
            killed.append(progress.sim_time_s)
            os.kill(node.proc.pid, signal.SIGKILL)

    launcher_ref = []
    with Launcher(RunOptions(scene="sorting_line", arms=4, duration_s=40.0, seed=3), kill_arm_1) as launcher:
        launcher_ref.append(launcher)
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert killed and summary["status"] == "ok"
    assert summary["arms_lost"] == ["arm_1"], "the sim stopped hearing exactly the dead controller"
    assert [e["arm"] for e in summary["arm_events"] if e["event"] == "lost"] == ["arm_1"], "healthy arms kept beating"
    assert summary["parts_completed"] >= 3, "the other arms went on completing parts"


@pytest.mark.lockstep  # a lockstep line: no clock against the wall
def test_a_randomised_line_repeats_for_its_seed_and_lists_what_was_drawn(tmp_path):
    import yaml

    data = yaml.safe_load(Path(QUICK_LINE).read_text()) | {
        "randomise": {
            "part_friction": {"uniform": [0.7, 1.1]},
            "belt_speed_scale": {"uniform": [0.8, 1.2]},
            "arm_gain_scale": {"uniform": [0.9, 1.1]},
            "part_pose_noise_m": {"uniform": [0.0005, 0.002]},
        }
    }
    scene = tmp_path / "randomised_line.yaml"
    scene.write_text(yaml.safe_dump(data))
    runs = run_lines_together(*[{"scene": str(scene), "duration_s": 15.0, "seed": 9}] * 2)
    for summary, launcher in runs:
        assert_nothing_left(summary, launcher.endpoint)
    (first, _), (second, _) = runs
    assert first["status"] == "ok" and set(first["randomised"]) == {
        "part_friction",
        "belt_speed_scale",
        "arm_gain_scale",
        "part_pose_noise_m",
    }
    assert first["parts_completed"] >= 1, first["unfinished_parts"]
    strip = lambda s: {k: v for k, v in s.items() if k not in WALL_FIGURES}  # noqa: E731
    assert strip(first) == strip(second), "every process drew the same values from the seed, and the noise repeats"


@pytest.mark.lockstep  # a lockstep line: no clock against the wall
def test_a_line_with_bus_faults_repeats_for_its_seed_and_says_what_was_injected():
    faults = {"latency_ms": 50.0, "jitter_ms": 10.0, "loss": 0.05}
    (first, launcher), (second, _) = run_lines_together(*[{"duration_s": 15.0, "seed": 5, **faults}] * 2)
    assert_nothing_left(first, launcher.endpoint)
    assert first["status"] == "ok" and first["arms_lost"] == [] and first["inter_arm_contacts"] == 0
    links = first["network_faults"]["links"]
    assert set(links) == {*first["arm_ids"], "coordinator"}
    assert all(link["latency_ms"] == 50.0 and link["down"]["lost"] > 0 for link in links.values())
    assert first["parts_completed"] >= 1, first["unfinished_parts"]
    strip = lambda s: {k: v for k, v in s.items() if k not in WALL_FIGURES}  # noqa: E731
    assert strip(first) == strip(second), "lockstep faults act in sim time: the same losses, delays and run"


def test_a_recorder_killed_mid_run_still_leaves_the_whole_run_recorded(tmp_path):
    """The sim's spool holds every message: a new recorder writes it all, summary included."""
    from mcap.reader import make_reader

    out = tmp_path / "run.mcap"

    def kill(progress):
        recorder = launcher_ref[0].recorder
        if progress.sim_time_s > 3.0 and recorder.alive:
            os.kill(recorder.proc.pid, signal.SIGKILL)

    launcher_ref = []
    with Launcher(RunOptions(scene=QUICK_LINE, duration_s=12.0, record=str(out)), kill) as launcher:
        launcher_ref.append(launcher)
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert summary["status"] == "ok" and summary["recording"]["file"] == str(out), summary.get("error")
    with open(out, "rb") as f:
        reader = make_reader(f)
        stats = reader.get_summary().statistics
        topics = {channel.topic for _, channel, _ in reader.iter_messages(topics=["/line/summary"])}
    assert stats.message_end_time / 1e9 >= summary["sim_seconds"] - 0.1
    assert topics == {"/line/summary"}


def test_an_estop_held_3_s_mid_line_loses_no_part_and_the_line_carries_on():
    """Every goal the e-stop ends or refuses is no attempt: once released, each arm plans again from where it stands,
    and the line finishes as many parts as one that was never stopped (given the 3 s back). Realtime (at 3x), so
    that the e-stop lasts what it should: a held lockstep line races through sim time between progress messages."""
    from fleet.bus.codec import encode
    from fleet.bus.messages import EStop

    baseline, _ = run_line(duration_s=21.0)
    said: dict = {}

    def estop(progress):
        launcher = launcher_ref[0]
        if "session" not in said:
            said["opened"] = open_session(launcher.client_endpoints("monitor"))  # the monitor's login may e-stop
            said["session"] = said["opened"].__enter__()
        key = Keys(launcher.options.run_id).estop
        if "engaged_s" not in said and progress.sim_time_s >= 8.0:
            said["session"].put(key, encode(EStop(True, "test")))
            said["engaged_s"] = progress.sim_time_s
        elif "released_s" not in said and "engaged_s" in said and progress.sim_time_s >= said["engaged_s"] + 3.0:
            said["session"].put(key, encode(EStop(False, "test")))
            said["released_s"] = progress.sim_time_s

    launcher_ref = []
    try:
        options = RunOptions(scene=QUICK_LINE, duration_s=24.0, mode="realtime", speed=3.0)
        with Launcher(options, estop) as launcher:
            launcher_ref.append(launcher)
            stopped = launcher.run()
    finally:
        if "opened" in said:
            said["opened"].__exit__(None, None, None)
    assert_nothing_left(stopped, launcher.endpoint)
    assert "released_s" in said and said["released_s"] - said["engaged_s"] < 5.0, said
    assert stopped["status"] == "ok" and stopped["parts_failed"] == 0, stopped["unfinished_parts"]
    assert not any("emergency stop" in p["reason"] for p in stopped["unfinished_parts"])
    # realtime runs vary by a part; without the fix 2-3 parts failed and fewer were done
    assert stopped["parts_completed"] >= baseline["parts_completed"] - 1, (stopped["parts_completed"], baseline)
