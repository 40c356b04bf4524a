"""A brain that sees (`docs/allocators.md`, "An allocator that sees"): an allocator that declares `frames_hz` is
handed the fixed cameras' RGB-D frames before a decision, at most at that rate: the frames of the newest camera
tick usable at the decision's tick (`perception.seen_ticks`), so every run of a lockstep line hands it the same
frames at the same decisions."""

from __future__ import annotations

from fleet.bus.codec import DropCounter
from fleet.nodes.rgbd_pairs import RGBDPairs
from fleet.sight.line_sight import seen_ticks_of
from perception.rgbd import RGBDFrame
from perception.seen_ticks import frame_due, frame_index
from scenes.schema import Scene

KEEP_TICKS = 8  # camera ticks' frames kept for a look still to come


class AllocatorEyes:
    """The fixed cameras' frames (`take`) for an allocator that looks at `frames_hz`: `look_due(tick)` names the
    camera tick a decision at `tick` should see (None: no look due), `ready` whether its frames are all in,
    `hand` gives them to the allocator's `see`."""

    def __init__(self, scene: Scene, frames_hz: float, drops: DropCounter) -> None:
        self.scene, self.frames_hz = scene, frames_hz
        self.cameras = [c for c in scene.cameras if c.arm is None]
        if not self.cameras:
            raise ValueError(f"the scene {scene.name} has no fixed camera for an allocator that asks for frames")
        self.ticks = seen_ticks_of(scene)
        self.pairs = RGBDPairs([c.name for c in self.cameras], drops)
        self.frames: dict[int, dict[str, RGBDFrame]] = {}
        self.last_look = -1  # the frame number (at `frames_hz`) of the last look
        self.looks = self.frames_handed = self.looks_short = 0

    def take(self, key: str, payload: bytes) -> None:
        paired = self.pairs.take(key, payload)
        if paired is not None and paired[1] is not None:
            rgb, frame = paired
            self.frames.setdefault(rgb.tick, {})[rgb.camera] = frame
            for old in sorted(self.frames)[:-KEEP_TICKS]:
                del self.frames[old]

    def look_due(self, tick: int) -> int | None:
        """The camera tick a decision at `tick` sees, if a look is due then (one per period of `frames_hz`)."""
        shown = self.ticks.usable_at(tick)
        if shown < 0 or frame_index(shown, self.frames_hz, self.scene.control_hz) <= self.last_look:
            return None
        return shown

    def ready(self, shown: int) -> bool:
        due = [c.name for c in self.cameras if frame_due(shown, c.rate_hz, self.scene.control_hz)]
        return all(name in self.frames.get(shown, {}) for name in due)

    def hand(self, see, shown: int) -> None:
        """`see` the frames of camera tick `shown` (those in: a look on its deadline may lack some), by camera."""
        frames = self.frames.get(shown, {})
        self.last_look = frame_index(shown, self.frames_hz, self.scene.control_hz)
        self.looks += 1
        self.looks_short += not self.ready(shown)
        self.frames_handed += len(frames)
        see([frames[name] for name in sorted(frames)])

    def report(self) -> dict:
        return {"looks": self.looks, "frames_handed": self.frames_handed, "looks_without_all_frames": self.looks_short}
