"""Plug-in allocators that go wrong, each in one way, loaded by `package.module:Name` as a user's would be."""

from __future__ import annotations

import time

from coordinator.allocation import GreedyNearest


class Raises:
    """Raises on every decision."""

    name = "raises"

    def __init__(self, scene) -> None:
        self.scene = scene

    def allocate(self, tasks, arms, parts, busy_stations):
        raise ZeroDivisionError("division by zero in the plug-in")


class GivesBusyArms:
    """Gives the oldest task to an arm that is not free."""

    name = "gives_busy_arms"

    def __init__(self, scene) -> None:
        self.scene = scene

    def allocate(self, tasks, arms, parts, busy_stations):
        busy = [a for a in arms if not a.free]
        return [(tasks[0].task_id, busy[0].name)] if tasks and busy else [("one", 2)]


class Slow:
    """Greedy's answer, after a sleep longer than any budget."""

    name = "slow"

    def __init__(self, scene) -> None:
        self.greedy = GreedyNearest(scene)

    def allocate(self, tasks, arms, parts, busy_stations):
        time.sleep(0.2)
        return self.greedy.allocate(tasks, arms, parts, busy_stations)


class RaisesEveryThird:
    """Greedy, but every third decision raises: a plug-in with a bug on some inputs."""

    name = "raises_every_third"

    def __init__(self, scene) -> None:
        self.greedy, self.calls = GreedyNearest(scene), 0

    def allocate(self, tasks, arms, parts, busy_stations):
        self.calls += 1
        if self.calls % 3 == 0:
            raise KeyError("a part it did not expect")
        return self.greedy.allocate(tasks, arms, parts, busy_stations)


def not_an_allocator(scene):
    """Makes something without `allocate`."""
    return object()


class SearchesNewSpots:
    """Greedy's answer, after asking each arm's reach about spots no one asked before (clawfleet's IK searches, not
    the plug-in's own time): a sound plug-in whose first look at a spot is slow."""

    name = "searches_new_spots"

    def __init__(self, scene) -> None:
        self.greedy, self.calls = GreedyNearest(scene), 0

    def allocate(self, tasks, arms, parts, busy_stations):
        self.calls += 1
        for arm in arms:
            out = 0.9 * arm.reach.top_down.reach_m  # inside its reach_m, 30 cm up: an SO-101 leans and
            for k in range(2):  # reaches none of these, each a full search of every tilt (~85 ms)
                arm.reach((arm.base_xyz[0] + out, arm.base_xyz[1] + 0.01 * (2 * self.calls + k), 0.3))
        return self.greedy.allocate(tasks, arms, parts, busy_stations)


class SeesTooFast(GreedyNearest):
    """Asks to look at the cameras 30 times a sim second: a controller's rate, not a brain's."""

    name = "sees_too_fast"
    frames_hz = 30.0

    def see(self, frames) -> None:
        pass


class SeesWithoutEyes(GreedyNearest):
    """Asks for frames but has nothing to take them with."""

    name = "sees_without_eyes"
    frames_hz = 2.0


class RaisesOnSight(GreedyNearest):
    """Looks at the cameras and raises on every look."""

    name = "raises_on_sight"
    frames_hz = 2.0

    def see(self, frames) -> None:
        raise ValueError("cannot stand the sight")
