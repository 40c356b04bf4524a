"""Env episodes that start from a line's snapshot: the env's world is the line's at that tick (every arm's joints,
every part where the line's own messages put them), the episode goes on from there in every action mode of the
line scenario, one seed gives one episode, and a snapshot of another cell is refused naming both."""

from __future__ import annotations

import numpy as np
import pytest
from mcap.reader import make_reader

from coordinator.allocation import make_allocator
from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.messages import ArmState, PartsState
from fleet.env import parallel_env
from fleet.env.allocate_mode import allocator_actions
from fleet.env.snapshot_episode import SnapshotEpisodeError
from fleet.run.launcher import Launcher, RunOptions
from fleet.snapshot.snapshot_file import read_snapshot

pytestmark = pytest.mark.slow  # one line run to take the snapshot from


@pytest.fixture(scope="module")
def line_snapshot(tmp_path_factory) -> tuple[str, dict, PartsState]:
    """A mixed_infeed line's snapshot at 12 s, and its arms' states and the parts as the line sent them then."""
    folder = tmp_path_factory.mktemp("line")
    options = RunOptions(
        scene="mixed_infeed",
        duration_s=14.0,
        snapshot_at=(12.0,),
        snapshot_dir=str(folder),
        record=str(folder / "line.mcap"),
    )
    with Launcher(options) as launcher:
        summary = launcher.run()
    path = summary["snapshots"][0]
    tick = read_snapshot(path).tick
    drops = DropCounter()
    states, parts = {}, None
    with open(folder / "line.mcap", "rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            if channel.topic.endswith("/state") and "/arm/" in channel.topic:
                s = Decoder(ArmState, drops).decode(channel.topic, message.data)
                if s is not None and s.tick == tick:
                    states[s.arm] = s
            elif channel.topic.endswith("world/parts"):
                p = Decoder(PartsState, drops).decode(channel.topic, message.data)
                if p is not None and p.tick == tick:
                    parts = p
    assert states and parts is not None, "the line sent its states and parts at the snapshot's tick"
    return path, states, parts


def world_as_the_line_had_it(env, states: dict, parts: PartsState) -> None:
    for arm, state in states.items():
        assert np.allclose(env.world.arms[arm].qpos()[: len(state.q)], state.q, atol=1e-9, rtol=0), arm
    here = {p.part_id: p.position for p in env.world.active_parts()}
    assert sorted(here) == sorted(parts.part_ids)
    for i, pid in enumerate(parts.part_ids):
        assert np.allclose(here[pid], parts.positions[3 * i : 3 * i + 3], atol=1e-9, rtol=0), pid


def test_an_allocate_episode_starts_where_the_line_was_and_goes_on(line_snapshot):
    path, states, parts = line_snapshot
    env = parallel_env(scene="mixed_infeed", scenario="line", action_mode="allocate", max_cycles=300)
    observations, infos = env.reset(seed=3, options={"snapshot": path})
    world_as_the_line_had_it(env, states, parts)
    assert env.world.sim_time_s == pytest.approx(12.0)
    ledger = env.scenario.book.ledger
    assert ledger.totals()["parts_spawned"] >= 1, "the line's parts and tasks, not an empty ledger"
    busy = [a for a in env.possible_agents if env.chooser.task_of[a] is not None]
    greedy = make_allocator("greedy", env.scene)
    done = ledger.totals()["parts_completed"]
    for _ in range(300):
        actions = allocator_actions(env.chooser, greedy, env._options)
        observations, rewards, terminations, truncations, infos = env.step(actions)
        if not env.agents:
            break
    assert env.world.sim_time_s == pytest.approx(12.0 + 300 * 0.05)
    assert busy, "arms at work at the snapshot go on with their tasks"
    assert ledger.totals()["parts_completed"] > done, "the line goes on: parts are completed from there"
    assert env.world.inter_arm_contacts() == []


def test_one_seed_gives_one_episode_from_a_snapshot(line_snapshot):
    path = line_snapshot[0]
    env = parallel_env(scene="mixed_infeed", scenario="line", action_mode="allocate", max_cycles=30)
    runs = []
    for _ in range(2):
        env.reset(seed=7, options={"snapshot": [path]})
        for _ in range(30):
            env.step({a: 0 for a in env.agents})
        runs.append(env.world.observable_state())
    assert np.array_equal(runs[0], runs[1])


def test_a_joint_level_episode_starts_where_the_line_was(line_snapshot):
    path, states, parts = line_snapshot
    env = parallel_env(scene="mixed_infeed", scenario="line", action_mode="joint_delta", max_cycles=20)
    env.reset(seed=0, options={"snapshot": path})
    world_as_the_line_had_it(env, states, parts)
    for _ in range(20):
        env.step({a: np.full(env.action_space(a).shape, 0.5) for a in env.agents})
    for a in env.possible_agents:  # the actions drive the episode's own world, built afresh from the snapshot
        n = env.world.arms[a].spec.arm_dof
        np.testing.assert_allclose(env.world.arms[a].drive_targets()[:n], env.joint_targets(a), atol=1e-9)


def test_a_snapshot_of_another_cell_or_for_another_scenario_is_refused(line_snapshot, tmp_path):
    path = line_snapshot[0]
    with pytest.raises(SnapshotEpisodeError, match="snapshot of mixed_infeed .* this env runs sorting_line"):
        parallel_env(scene="sorting_line", scenario="line", action_mode="allocate").reset(options={"snapshot": path})
    with pytest.raises(SnapshotEpisodeError, match="needs scenario='line'"):
        parallel_env(scene="mixed_infeed", scenario="reach").reset(options={"snapshot": path})
    with pytest.raises(SnapshotEpisodeError, match="no such snapshot file"):
        parallel_env(scene="mixed_infeed", scenario="line").reset(options={"snapshot": str(tmp_path / "x.clawsnap")})
    with pytest.raises(SnapshotEpisodeError, match="a path or a list of paths"):
        parallel_env(scene="mixed_infeed", scenario="line").reset(options={"snapshot": 5})
