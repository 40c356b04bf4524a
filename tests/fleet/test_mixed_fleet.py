"""Arms of three models on one line (mixed_fleet: an OpenClaw, an SO-101 and a Panda): the guard, the allocator's
time costs, the monitor's scene and the env take them side by side; the line runs with zero contacts."""

import pytest

from fleet.run.launcher import Launcher, RunOptions
from robots.registry import is_available
from tests.fleet.test_run import assert_nothing_left

pytestmark = [
    pytest.mark.skipif(not (is_available("so101") and is_available("panda")), reason="needs the models extra"),
    pytest.mark.slow,
]


def test_three_models_share_a_line_in_lockstep_with_zero_contacts():
    with Launcher(RunOptions(scene="mixed_fleet", duration_s=60.0)) as launcher:
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert summary["status"] == "ok" and summary["inter_arm_contacts"] == 0, summary.get("error")
    assert summary["parts_completed"] >= 4 and summary["parts_missed"] == 0, {
        k: summary[k] for k in ("parts_spawned", "parts_completed", "parts_missed")
    }
    assert all(summary["arm_time"][arm]["working"] > 0.05 for arm in ("arm_0", "arm_1", "arm_2")), summary["arm_time"]
    coordinator = next(p for p in summary["processes"] if p["role"] == "coordinator")
    assert coordinator["exit_code"] == 0 and summary["throughput_bound_per_min"] == 6.0, (
        "its figures written in the stop's grace"
    )


def test_the_env_drives_arms_of_different_models_side_by_side():
    from fleet.env import parallel_env

    env = parallel_env(scene="mixed_fleet", scenario="reach")
    observations, _ = env.reset(seed=0)
    assert set(observations) == {"arm_0", "arm_1", "arm_2"}
    spaces = {agent: env.action_space(agent).shape for agent in env.agents}
    assert spaces["arm_0"] != spaces["arm_2"]  # 6 joints and 7: each arm acts with its own model's joints
    for _ in range(20):
        observations, *_ = env.step({agent: env.action_space(agent).sample() for agent in env.agents})
    env.close()


def test_the_monitor_draws_arms_of_different_models_from_their_own_urdfs():
    import numpy as np
    import viser

    from fleet.common.scene_loading import load_checked_scene
    from fleet.monitor.cell_view import CellView
    from robots.registry import get_robot

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        view = CellView(server, load_checked_scene("mixed_fleet"))
        for name, model in (("arm_0", "openclaw"), ("arm_1", "so101"), ("arm_2", "panda")):
            arm, spec = view.arms[name], get_robot(model)
            assert sorted(arm.urdf.get_actuated_joint_names()) == sorted((*spec.arm_joints, *spec.gripper_joints))
            # each moves with its own joints
            arm.update_cfg(np.asarray(spec.home_q) * 0.5, np.asarray(spec.gripper_closed))
    finally:
        server.stop()
