"""`distributed=True`: each arm's action goes through Zenoh to its own process; the same seed and actions give
the same observations as the in-process path, and closing the env leaves no process and no port behind."""

import os
import socket

import numpy as np
import pytest

from fleet.env import parallel_env
from fleet.env.distributed import RemoteArmsError


def _port(endpoint: str) -> int:
    return int(endpoint.rsplit(":", 1)[1])


@pytest.mark.parametrize("mode", ["joint_delta", "ee_delta"])
def test_the_bus_path_gives_the_same_observations_and_rewards_as_in_process(mode):
    remote = parallel_env(scenario="reach", action_mode=mode, n_arms=2, max_cycles=25, distributed=True)
    local = parallel_env(scenario="reach", action_mode=mode, n_arms=2, max_cycles=25)
    try:
        obs_r, _ = remote.reset(seed=3)
        obs_l, _ = local.reset(seed=3)
        rng = np.random.default_rng(0)
        while local.agents:
            actions = {a: rng.uniform(-1, 1, local.action_space(a).shape).astype(np.float32) for a in local.agents}
            obs_r, rew_r, *_ = remote.step(actions)
            obs_l, rew_l, *_ = local.step(actions)
            assert all(np.array_equal(obs_r[a], obs_l[a]) for a in obs_l) and rew_r == rew_l
    finally:
        remote.close()


def test_closing_stops_every_arm_process_frees_the_bus_port_and_leaves_no_log_folder():
    env = parallel_env(scenario="reach", n_arms=2, max_cycles=5, distributed=True)
    env.reset(seed=0)
    procs, port, logs = list(env.actuator.procs.values()), _port(env.actuator.endpoint), env.actuator._logs
    assert len(procs) == 2 and all(p.poll() is None for p in procs) and logs.is_dir()
    env.close()
    assert not logs.exists()
    assert all(p.poll() is not None for p in procs)
    for p in procs:
        with pytest.raises(ProcessLookupError):
            os.kill(p.pid, 0)
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", port))


def test_an_arm_process_that_dies_is_named_in_one_clear_error():
    env = parallel_env(scenario="reach", n_arms=2, max_cycles=5, distributed=True)
    try:
        env.reset(seed=0)
        proc = env.actuator.procs["arm_1"]
        proc.kill()
        proc.wait()
        with pytest.raises(RemoteArmsError, match=r"arm_1 \(exited with -9"):
            env.step({a: env.action_space(a).sample() for a in env.agents})
    finally:
        env.close()


def test_the_allocate_mode_runs_its_skills_in_process_and_says_so():
    with pytest.raises(ValueError, match="skills run in process"):
        parallel_env(scenario="line", action_mode="allocate", n_arms=2, distributed=True)
