"""`render_mode="human"`: the env's cell on the browser monitor's 3D view (Viser), drawn from the world in process.

The same `CellView` as `fleet monitor`, fed with the same messages the sim server
publishes (`fleet.sim.world_messages`), without a bus. Binds 127.0.0.1 by default.
"""

from __future__ import annotations

import viser

from coordinator.guard import CollisionGuard
from fleet.bus.messages import separations_from_pairs
from fleet.bus.session import LOOPBACK
from fleet.monitor.cell_view import CellView
from fleet.monitor.feed import LineSight
from fleet.sim.world import World
from fleet.sim.world_messages import arm_state, parts_state
from scenes.schema import Scene


class EnvMonitor:
    """A Viser server showing one env's cell; `update(world, guard)` redraws it, `close()` frees the port."""

    def __init__(self, scene: Scene, port: int = 8080, host: str = LOOPBACK) -> None:
        self.host = host
        self.server = viser.ViserServer(host=host, port=port, label=f"clawfleet env · {scene.name}", verbose=False)
        try:
            self.view = CellView(self.server, scene)
        except BaseException:
            self.server.stop()
            raise
        self.frames = 0

    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def update(self, world: World, guard: CollisionGuard | None = None) -> None:
        """Draw the arms, the parts and (with a guard holding the arms' states) each arm's nearest neighbour."""
        snap = LineSight(
            arms={name: arm_state(world, name) for name in world.arms},
            parts=parts_state(world, world.active_parts()),
        )
        if guard is not None and len(world.arms) > 1:
            snap.separations = separations_from_pairs(world.sim_time_s, guard.nearest_pairs(), guard.margin_m)
        with self.server.atomic():
            self.view.show(snap)
        self.frames += 1

    def close(self) -> None:
        self.server.stop()
