"""The line's cameras in the sim process: at each tick, the cameras due render (one pass) and their images go on
the bus as `CameraImage`s, one per camera and kind (`fleet run --cameras`)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import zenoh

from fleet.bus.codec import encode
from fleet.bus.images import encode_image, encodings_for
from fleet.bus.keys import Keys
from fleet.bus.messages import CameraImage
from fleet.bus.session import Inbox
from fleet.sim.cameras.frames import CameraFrame
from fleet.sim.cameras.rig import CameraRig
from fleet.sim.cameras.seen_score import SeenScore
from scenes.schema import Camera


@dataclass
class CameraCounts:
    """What the cameras cost the line: frames made, images put and their bytes, wall time rendering and encoding."""

    frames: int = 0
    images: int = 0
    bytes_out: int = 0
    render_s: float = 0.0
    encode_s: float = 0.0
    first_frame_s: float = 0.0  # the renderer's set-up, paid by the run's first frame
    by_camera: dict[str, int] = field(default_factory=dict)

    def report(self) -> dict:
        return {
            "frames": self.frames,
            "images": self.images,
            "bytes_out": self.bytes_out,
            "render_s": round(self.render_s, 3),
            "encode_s": round(self.encode_s, 3),
            "first_frame_s": round(self.first_frame_s, 3),
            "frames_by_camera": dict(sorted(self.by_camera.items())),
        }


def cameras_named(cameras: list[Camera], names: str) -> list[Camera]:
    """The cameras `--cameras` names: `all`, or names joined by commas; an unknown name is a ValueError naming the
    scene's cameras."""
    if not cameras:
        raise ValueError("--cameras: this scene declares no cameras (docs/cameras.md)")
    if names == "all":
        return list(cameras)
    by_name = {c.name: c for c in cameras}
    chosen = [n.strip() for n in names.split(",") if n.strip()]
    unknown = [n for n in chosen if n not in by_name]
    if unknown or not chosen:
        raise ValueError(f"--cameras {names!r}: the scene's cameras are {', '.join(by_name)} (or all)")
    return [by_name[n] for n in dict.fromkeys(chosen)]


def image_messages(
    frame: CameraFrame, tick: int, encodings: dict[str, str], events_published: int = 0
) -> list[CameraImage]:
    """A frame's images as bus messages, each packed as `encodings` says for its kind; `events_published`: the line
    events the sim had published by then."""
    width, height = frame.size_px
    intrinsics = tuple(float(v) for v in frame.intrinsics.ravel())
    position_m = tuple(float(v) for v in frame.position_m)
    quaternion_wxyz = tuple(float(v) for v in frame.quaternion_wxyz)
    return [
        CameraImage(
            camera=frame.camera,
            kind=kind,
            tick=tick,
            sim_time_s=frame.sim_time_s,
            width_px=width,
            height_px=height,
            encoding=encodings[kind],
            data=encode_image(kind, image, encodings[kind]),
            intrinsics=intrinsics,
            position_m=position_m,
            quaternion_wxyz=quaternion_wxyz,
            events_published=events_published,
        )
        for kind, image in frame.images().items()
    ]


class LineCameras:
    """Renders the cameras due at a tick and puts their images on the bus, counting what it costs."""

    def __init__(
        self,
        rig: CameraRig,
        session: zenoh.Session,
        keys: Keys,
        rgb_encoding: str = "png",
        scored: bool = False,
        every_frame: bool = False,
    ) -> None:
        """`scored`: the line works from what perception sees; its parts are scored against the truth here.
        `every_frame` (lockstep, a node working from the frames): an image waits for room on a full link rather
        than being dropped (Zenoh's default drops a large message when the link's queue stays full a moment, as it
        does on a busy machine); otherwise the first waits and those after it are dropped until it is out (a live
        line sends fresh frames; a slow viewer holds no line). Images go at a lower priority than the line's
        messages, in a queue of their own."""
        self.rig = rig
        self.encodings = encodings_for(rgb_encoding)
        self.counts = CameraCounts()
        congestion = zenoh.CongestionControl.BLOCK if every_frame else zenoh.CongestionControl.BLOCK_FIRST
        below_the_line = zenoh.Priority.DATA_LOW  # queued apart: a large image never holds up the line's messages
        self._pubs = {
            (name, kind): session.declare_publisher(
                keys.camera(name, kind), congestion_control=congestion, priority=below_the_line
            )
            for name, camera in rig.cameras.items()
            for kind in camera.model.images
        }
        self.score: SeenScore | None = None
        self._seen_sub = None
        if scored:
            inbox = Inbox()
            self._seen_sub = session.declare_subscriber(keys.seen_parts, inbox)
            self.score = SeenScore(inbox, rig.world.scene_model.stations)

    def warm_up(self) -> None:
        """Render every camera once, unsent: the renderer's set-up is paid here (counted as the first frame's)."""
        start = time.perf_counter()
        self.rig.frames()
        self.counts.first_frame_s = time.perf_counter() - start

    def tick(self, tick: int, events_published: int = 0) -> None:
        """The frames due at `tick` (the world standing at it), rendered and put; `events_published`: the line
        events the sim had published by then."""
        if self.score is not None:
            self.score.take()
        due = self.rig.due(tick)
        if not due:
            return
        start = time.perf_counter()
        frames = self.rig.frames(due)
        rendered = time.perf_counter()
        if self.score is not None:
            self.score.frame(tick, self.rig.world, frames)
        self.counts.render_s += rendered - start
        for name, frame in frames.items():
            self.counts.frames += 1
            self.counts.by_camera[name] = self.counts.by_camera.get(name, 0) + 1
            for message in image_messages(frame, tick, self.encodings, events_published):
                data = encode(message)
                self._pubs[(name, message.kind)].put(data)
                self.counts.images += 1
                self.counts.bytes_out += len(data)
        self.counts.encode_s += time.perf_counter() - rendered

    def settle(self) -> None:
        """After the last tick: perception's answers to the last frames scored (awaited a little: see `SeenScore`)."""
        if self.score is not None:
            self.score.settle()

    def close(self) -> None:
        for pub in self._pubs.values():
            pub.undeclare()
        if self._seen_sub is not None:
            self._seen_sub.undeclare()
