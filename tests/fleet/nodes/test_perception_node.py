"""`fleet run --perception cameras`: a perception process sees a running line through its overhead camera and
publishes the parts it tracks, each where the sim's own parts message of that tick holds a part; images that cannot
be a frame are dropped and counted, never a crash."""

import threading
import time

import numpy as np
import pytest

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.message_checks import detections_problem
from fleet.bus.messages import CameraImage, PartDetections, PartsState
from fleet.bus.session import BusEndpoints, open_session
from fleet.common.scene_loading import load_checked_scene
from fleet.record.mcap_file import Recording
from fleet.run.launcher import Launcher, RunOptions
from fleet.sim.cameras.part_looks import part_looks
from tests.fleet.test_run import assert_nothing_left

pytestmark = pytest.mark.slow


def wait_for(seen: list, timeout_s: float = 60.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not seen and time.monotonic() < deadline:
        time.sleep(0.02)
    return bool(seen)


def run_seen(options: RunOptions, meddle=None) -> tuple[dict, list[PartDetections], dict[int, PartsState]]:
    """The run's summary, every `PartDetections` heard and the sim's parts messages by tick (a listening login)."""
    keys, drops = Keys(options.run_id), DropCounter()
    seen, parts = [], {}
    with Launcher(options) as launcher:
        login = BusEndpoints(config_file=launcher.bus.config_for("recorder")) if launcher.bus else None
        with open_session(login or BusEndpoints(connect=(launcher.endpoint,))) as session:
            detections, states = Decoder(PartDetections, drops), Decoder(PartsState, drops)
            subs = [
                session.declare_subscriber(
                    keys.detections("overhead"), lambda s: seen.append(detections.decode("d", s.payload.to_bytes()))
                ),
                session.declare_subscriber(
                    keys.parts, lambda s: (m := states.decode("p", s.payload.to_bytes())) and parts.update({m.tick: m})
                ),
            ]
            if meddle is not None:  # once the perception node has published (it listens by then)
                threading.Thread(target=lambda: wait_for(seen) and meddle(session, keys), daemon=True).start()
            summary = launcher.run()
            for sub in subs:
                sub.undeclare()
    assert_nothing_left(summary, launcher.endpoint)
    assert drops.total == 0, drops.kinds()
    return summary, seen, parts


@pytest.mark.lockstep
def test_the_perception_node_publishes_tracks_where_the_sims_parts_are_and_the_recording_keeps_them(tmp_path):
    options = RunOptions(
        scene="pick_cell",
        duration_s=8.0,
        seed=0,
        perception="cameras",
        cameras="overhead",
        record=str(tmp_path / "r.mcap"),
    )
    summary, seen, parts = run_seen(options)
    assert summary["status"] == "ok", summary["error"]
    report = summary["perception"]
    assert report["cameras"] == ["overhead"] and report["frames"] >= 35 and report["dropped_messages"] == 0, report
    assert len(seen) == report["frames"] and sum(len(d.track_ids) for d in seen) == report["tracks_published"]
    kinds = len(part_looks(load_checked_scene("pick_cell"))[0])
    assert all(detections_problem(d, kinds) == "" for d in seen)
    recorded = [m.payload for m in Recording(tmp_path / "r.mcap").raw_messages([Keys("line").detections("overhead")])]
    by_tick = {d.tick: d for d in (Decoder(PartDetections, DropCounter()).decode("r", p) for p in recorded)}
    assert all(by_tick.get(d.tick) == d for d in seen), "the recording holds every frame's detections as heard"
    errors_m = []
    for d in seen:
        truth = parts.get(d.tick)
        if truth is None:
            continue
        where = np.asarray(truth.positions).reshape(-1, 3)
        for k, seen_s in enumerate(d.seen_s):
            if seen_s != d.sim_time_s or not len(where):
                continue  # a track not seen in this frame keeps the spot it was last seen at
            top = np.asarray(d.top_centres_m[3 * k : 3 * k + 2])
            errors_m.append(np.min(np.linalg.norm(where[:, :2] - top, axis=1)))
    # most lie within a few mm; a part in a claw shows in part between the fingers and strays further (8-23 mm
    # seen for about a third of them), never beyond the tracks' gate
    errors_mm = sorted(np.round(np.asarray(errors_m) * 1000, 1))
    assert len(errors_mm) >= 30 and np.median(errors_mm) < 5.0 and errors_mm[-1] < 30.0, errors_mm


def test_images_that_cannot_be_a_frame_are_dropped_and_counted():
    def lie(session, keys) -> None:
        """Two lies refused as they arrive, whatever the line's own frames do meanwhile (a half-frame lie would be
        paired, or not, with the sim's next half: `test_perception_feed.py` covers those alone)."""
        rgb = session.declare_publisher(keys.camera("overhead", "rgb"))
        rgb.put(b"\x93not an image")
        rgb.put(encode(CameraImage("wrist", "rgb", 0, 0.0, 4, 4, "raw", b"\x00" * 48, (1.0,) * 9, (0,) * 3, (1,) * 4)))

    options = RunOptions(
        scene="pick_cell", duration_s=6.0, seed=0, perception="cameras", cameras="overhead", insecure=True
    )
    summary, _, _ = run_seen(options, lie)
    assert summary["status"] == "ok", summary["error"]
    refused = summary["refused_messages"]["perception"]
    assert sum(refused.values()) >= 2, refused
