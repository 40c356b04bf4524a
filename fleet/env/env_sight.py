"""The env's line as its fixed cameras show it (`parallel_env(..., perception="cameras")`): the allocate mode's
skills and dispatcher get the parts perception sees, as `fleet run --perception cameras` gives its coordinator and
controllers: each frame rendered, seen (`fleet.sight.Seer`) and bound to the parts the line's events name, and each
tick acting on the newest frame usable then, carried to it."""

from __future__ import annotations

from collections import deque

from coordinator.allocation import PartView
from fleet.bus.codec import DropCounter
from fleet.bus.messages import LineEvent, PartsState
from fleet.sight.line_sight import carried_to, newest_up_to, seen_ticks_of
from fleet.sight.part_views import part_views, parts_from_message
from fleet.sight.seer import Seer
from fleet.sim.cameras.rig import CameraRig
from fleet.sim.line_watch import Event
from fleet.sim.world import World
from robots.skills.interface import PartObservation
from scenes.schema import Scene

KEEP_FRAMES = 16  # frames' parts kept (the newest usable is at most a frame or two back)


class EnvSight:
    """Renders the fixed cameras of `world` when a frame is due (`after_tick`, told the line's events so far), and
    gives the parts of the newest frame usable at a tick (`views`, `observations`)."""

    def __init__(self, world: World, scene: Scene) -> None:
        cameras = [c.model_copy(update={"images": ["rgb", "depth"]}) for c in scene.cameras if c.arm is None]
        self.ticks = seen_ticks_of(scene)  # a scene without a fixed camera: a ValueError naming it
        self.scene, self.rig = scene, CameraRig(world, cameras)
        self.names = sorted(c.name for c in cameras)
        self.drops = DropCounter()
        self.reset()

    def reset(self) -> None:
        """A new episode: nothing seen, no event heard."""
        self.seer = Seer(self.scene, self.names)
        self.frames: deque[PartsState] = deque(maxlen=KEEP_FRAMES)
        self.heard = 0

    def use_world(self, world: World) -> None:
        self.rig.use_world(world)

    def after_tick(self, world: World, events: list[Event]) -> None:
        """After a control tick: the events since the last call heard; a frame due now rendered and seen."""
        for e in events[self.heard :]:
            self.seer.sight.event(
                "env/events", LineEvent(e.kind, e.part_id, e.tick, e.detail, e.type_index), self.drops
            )
        self.heard = len(events)
        due = self.rig.due(world.tick)
        if not due:
            return
        self.seer.sight.apply_events(world.tick)
        for name, frame in sorted(self.rig.frames(due).items()):
            self.seer.frame(name, frame.rgbd())
        self.frames.append(self.seer.sight.message(world.tick, world.sim_time_s))

    def _usable(self, tick: int) -> PartsState | None:
        newest = newest_up_to(self.frames, self.ticks.usable_at(tick))
        return carried_to(newest, tick, self.scene.control_hz) if newest is not None else None

    def views(self, tick: int) -> dict[int, PartView]:
        """The allocators' view of the parts seen, as of `tick`."""
        msg = self._usable(tick)
        return part_views(msg) if msg is not None else {}

    def observations(self, tick: int) -> dict[int, PartObservation]:
        """The skills' view of the parts seen, as of `tick`."""
        msg = self._usable(tick)
        return parts_from_message(msg, self.scene.round_part_types()) if msg is not None else {}
