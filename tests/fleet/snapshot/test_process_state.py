"""A process's state as bytes and back: everything but its live handles, objects of the process found by name."""

from __future__ import annotations

import threading

import pytest

from fleet.snapshot.process_state import StateError, capture, restore


class World:
    """Stands for what a process has of its own (a physics world): never pickled, found again by name."""


class Tracker:
    def __init__(self, world: World) -> None:
        self.world, self.goals = world, [1, 2]


class Node:
    def __init__(self, world: World) -> None:
        self.world = world
        self.lock = threading.Lock()  # a live handle: does not pickle
        self.tracker = Tracker(world)
        self.counts = {"decisions": 3}


def test_a_state_leaves_live_handles_and_points_at_the_new_process_s_own_objects():
    old_world, new_world = World(), World()
    node = Node(old_world)
    node.tracker.goals.append(3)
    blob = capture(node, keep=("lock", "world"), live={"world": old_world})
    fresh = Node(new_world)
    lock = fresh.lock
    restore(fresh, blob, live={"world": new_world})
    assert fresh.lock is lock and fresh.world is new_world
    assert fresh.tracker.world is new_world, "a reference to the world is to this process's world"
    assert fresh.tracker.goals == [1, 2, 3] and fresh.counts == {"decisions": 3}


def test_an_attribute_that_cannot_be_written_is_named():
    node = Node(World())
    node.callback = lambda: None
    with pytest.raises(StateError, match=r"cannot snapshot Node \(attributes .*callback"):
        capture(node, keep=("lock",), live={"world": node.world})


def test_a_state_that_names_an_object_this_process_lacks_or_is_not_a_state_is_refused():
    node = Node(World())
    blob = capture(node, keep=("lock",), live={"world": node.world})
    with pytest.raises(StateError, match="names 'world', which this process does not have"):
        restore(Node(World()), blob, live={})
    with pytest.raises(StateError, match="cannot read back the state of Node"):
        restore(Node(World()), b"not a pickle", live={})
