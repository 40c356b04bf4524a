"""The physics world repeats itself exactly: same scene and seed, same states; restore then step equals stepping on."""

import numpy as np
import pytest

from fleet.sim.world import World
from scenes import load_scene


def drive(world: World, ticks: int) -> None:
    """Move every arm along a smooth pattern so the drives, contacts and the belt all matter."""
    for _ in range(ticks):
        t = world.sim_time_s
        for i, arm in enumerate(world.arms.values()):
            q = np.array(arm.spec.home_q) + 0.3 * np.sin(2 * t + i)
            arm.set_targets(q, np.zeros(arm.spec.arm_dof), arm.spec.gripper_targets(0.5 + 0.5 * np.sin(t)))
        world.step()


@pytest.fixture(scope="module")
def scene():
    return load_scene("sorting_line", arms=4)


def test_same_seed_gives_bit_identical_states_after_2000_steps(scene):
    ticks = 2000 // scene.substeps
    first, second = World(scene), World(scene)
    drive(first, ticks)
    drive(second, ticks)
    assert len(first.active_parts()) >= 2, "parts must be on the belt for this test to mean anything"
    assert first.pack_state().physx == second.pack_state().physx
    assert np.array_equal(first.observable_state(), second.observable_state())


def test_another_seed_gives_another_run(scene):
    a, b = World(scene), World(scene.model_copy(update={"seed": 1}))
    drive(a, 400)
    drive(b, 400)
    assert not np.array_equal(a.observable_state(), b.observable_state())


def test_restore_then_step_equals_uninterrupted_stepping(scene):
    """Restored worlds replay bit for bit; against the never-restored world they agree to float32 rounding.

    SAPIEN's PhysX pack does not carry the articulation solver's internal caches, so the first
    step after any restore differs from an uninterrupted one in the last float32 bits (about 1e-6).
    """
    original = World(scene)
    drive(original, 300)
    snapshot = original.pack_state()
    drive(original, 300)
    fresh = World(scene)
    fresh.restore_state(snapshot)
    drive(fresh, 300)
    np.testing.assert_allclose(fresh.observable_state(), original.observable_state(), rtol=0, atol=1e-5)
    original.restore_state(snapshot)
    drive(original, 300)
    assert np.array_equal(original.observable_state(), fresh.observable_state())


def test_conveyor_carries_parts_at_its_speed(scene):
    world = World(scene)
    part_id = world.spawn_now("mixed")
    world.step(50)
    x0 = world.part_info(part_id).position[0]
    world.step(100)
    speed = (world.part_info(part_id).position[0] - x0) / 1.0
    assert speed == pytest.approx(scene.conveyor.speed_m_per_s, rel=0.05)


def test_drive_targets_read_back_as_written_across_a_restore(scene):
    """set_targets skips writes that repeat the last ones; a restore in between must not fool it."""
    world = World(scene)
    arm = next(iter(world.arms.values()))
    n = arm.spec.arm_dof
    snapshot = world.pack_state()  # velocity targets zero, gripper open
    q, moving, half = np.array(arm.spec.home_q) + 0.1, np.full(n, 0.2), arm.spec.gripper_targets(0.5)
    arm.set_targets(q, moving, half)
    world.restore_state(snapshot)
    arm.set_targets(q, moving, half)  # the same values again: after the restore they differ from the drives
    assert np.allclose(arm.drive_velocity_targets()[:n], moving)
    assert np.allclose(arm.drive_targets(), np.concatenate([q, half]))


def test_a_scene_sets_its_solver_iterations():
    grasping = World(load_scene("pick_cell"))
    light = World(load_scene("pick_cell").model_copy(update={"solver_position_iterations": 4}))
    assert {a.articulation.get_solver_position_iterations() for a in grasping.arms.values()} == {20}
    assert {a.articulation.get_solver_position_iterations() for a in light.arms.values()} == {4}


def test_a_grasps_effort_is_part_of_the_state(scene):
    """A gripper's force limit (a goal's max effort) is the drive's, not in PhysX's pack: the world's state keeps it."""
    world = World(scene)
    arm = next(iter(world.arms))
    world.arms[arm].set_gripper_effort(3.5)
    fresh = World(scene)
    fresh.restore_state(world.pack_state())
    assert fresh.arms[arm].gripper_force_limit() == pytest.approx(3.5)


def test_a_world_built_beside_a_stepping_one_changes_none_of_its_steps(scene):
    """A snapshot's spare world is built on a thread while the line steps: the line's steps stay bit for bit."""
    import threading

    def stepped(beside: bool) -> np.ndarray:
        world = World(scene)
        for _ in range(5):
            builder = threading.Thread(target=lambda: World(scene)) if beside else None
            if builder is not None:
                builder.start()
            drive(world, 60)
            if builder is not None:
                builder.join()
        return world.observable_state()

    assert np.array_equal(stepped(False), stepped(True))
