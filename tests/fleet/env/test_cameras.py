"""The env sees: `parallel_env(cameras=...)` gives Dict observations with each agent's state and the images of the
cameras it sees, rendered by SAPIEN, and passes PettingZoo's own tests with them."""

import numpy as np
import pytest

from fleet.env import conformance, parallel_env

SMALL = {  # small images keep the tests quick; the bundled cameras are 160x120
    "name": "top",
    "pose": {"xyz": [0.3, -0.2, 1.6], "look_at": [0.3, -0.2, 0.0], "up": [0.0, 1.0, 0.0]},
    "width_px": 32,
    "height_px": 24,
    "images": ["rgb", "depth", "segmentation"],
}
WRIST_1 = {
    "name": "wrist_1",
    "mount": "arm_1/tool_link",
    "pose": {"xyz": [0.05, 0.0, -0.06], "look_at": [0.0, 0.0, 0.12], "up": [1.0, 0.0, 0.0]},
    "width_px": 16,
    "height_px": 16,
    "images": ["rgb", "depth"],
}


def test_pettingzoo_parallel_aec_seed_and_max_cycles_tests_pass_with_cameras():
    conformance.check("reach", "joint_delta", cycles=10, cameras=[SMALL, WRIST_1])


def test_an_agent_sees_the_fixed_cameras_and_its_own_wrist_only():
    env = parallel_env(n_arms=2, scenario="reach", cameras=[SMALL, WRIST_1])
    observations, _ = env.reset(seed=0)
    assert set(observations["arm_0"]) == {"state", "top_rgb", "top_depth", "top_segmentation"}
    assert set(observations["arm_1"]) == {
        "state",
        "top_rgb",
        "top_depth",
        "top_segmentation",
        "wrist_1_rgb",
        "wrist_1_depth",
    }
    for agent, observation in observations.items():
        assert env.observation_space(agent).contains(observation)
    assert observations["arm_0"]["top_rgb"].shape == (24, 32, 3)
    assert observations["arm_0"]["top_rgb"].std() > 5, "the image shows the cell, not one flat colour"


def test_the_same_seed_and_actions_give_the_same_image_bytes():
    a, b = (parallel_env(n_arms=2, scenario="reach", cameras=[SMALL]) for _ in range(2))
    a.reset(seed=3)
    b.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(5):
        actions = {x: rng.uniform(-1, 1, a.action_space(x).shape).astype(np.float32) for x in a.agents}
        seen_a, *_ = a.step(actions)
        seen_b, *_ = b.step(actions)
    assert seen_a["arm_1"]["top_rgb"].tobytes() == seen_b["arm_1"]["top_rgb"].tobytes()
    assert seen_a["arm_1"]["top_depth"].tobytes() == seen_b["arm_1"]["top_depth"].tobytes()


def test_rgb_array_renders_the_overhead_camera():
    env = parallel_env(scene="pick_cell", scenario="reach", render_mode="rgb_array")
    observations, _ = env.reset(seed=0)
    assert isinstance(observations["arm_0"], np.ndarray), "rgb_array alone puts no images in the observations"
    picture = env.render()
    camera = env.scene.camera("overhead")
    assert picture.shape == (camera.height_px, camera.width_px, 3) and picture.dtype == np.uint8


def test_cameras_on_a_scene_without_any_are_refused_with_what_to_do(tmp_path):
    from scenes.loader import BUNDLED_DIR

    text = (BUNDLED_DIR / "pick_cell.yaml").read_text().split("\ncameras:")[0]
    (tmp_path / "blind.yaml").write_text(text)
    with pytest.raises(ValueError, match="the scene declares no cameras: give cameras="):
        parallel_env(scene=str(tmp_path / "blind.yaml"), scenario="reach", cameras=True)


def test_a_vector_of_cells_carries_the_images():
    pytest.importorskip("supersuit", reason="the rl extra (supersuit) is not installed")
    from fleet.env.vector import vector_env

    venv = vector_env(2, num_cpus=0, n_arms=2, scenario="reach", max_cycles=10, cameras=[SMALL])
    try:
        observations, _ = venv.reset(seed=1)
        assert observations["top_rgb"].shape == (4, 24, 32, 3) and observations["state"].shape[0] == 4
        observations, *_ = venv.step(np.zeros((4, *venv.action_space.shape), np.float32))
        assert observations["top_depth"].shape == (4, 24, 32) and observations["top_rgb"].std() > 5
    finally:
        venv.close()
