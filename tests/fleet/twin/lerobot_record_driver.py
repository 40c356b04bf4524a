"""Run by LeRobot's own Python (its virtualenv), not by pytest: LeRobot's record loop writes a `LeRobotDataset` from
arm_1 of a running line as the `clawfleet` robot (found as a third-party plug-in, as `lerobot-record` finds it),
driven by a scripted teleoperator (the pan swings +-20 degrees about home, the gripper opens and closes), with the
overhead camera's images; the dataset is then loaded back with LeRobot's loader. One JSON line of what it holds.
Usage: python lerobot_record_driver.py ZENOH_CONFIG DATASET_ROOT SECONDS"""

import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from lerobot.datasets.lerobot_dataset import LeRobotDataset
from lerobot.datasets.pipeline_features import aggregate_pipeline_dataset_features, create_initial_features
from lerobot.datasets.utils import combine_feature_dicts
from lerobot.processor import make_default_processors
from lerobot.robots.utils import make_robot_from_config
from lerobot.scripts.lerobot_record import record_loop
from lerobot.teleoperators.config import TeleoperatorConfig
from lerobot.teleoperators.teleoperator import Teleoperator
from lerobot.utils.import_utils import register_third_party_plugins

FPS = 10
HOME = {"shoulder_pan": 0.0, "shoulder_lift": -28.6, "elbow_flex": 28.6, "wrist_flex": 68.8, "wrist_roll": 0.0}


class ScriptedConfig(TeleoperatorConfig):
    pass


class Scripted(Teleoperator):
    """A teleoperator with no device: the home pose with the pan swinging 20 degrees each way every 4 s."""

    config_class = ScriptedConfig
    name = "scripted"

    def __init__(self) -> None:
        super().__init__(ScriptedConfig(id="scripted", calibration_dir=Path(sys.argv[2]) / "teleop"))
        self.started = time.monotonic()

    @property
    def action_features(self) -> dict:
        return {f"{m}.pos": float for m in [*HOME, "gripper"]}

    @property
    def feedback_features(self) -> dict:
        return {}

    @property
    def is_connected(self) -> bool:
        return True

    def connect(self, calibrate: bool = True) -> None:
        pass

    @property
    def is_calibrated(self) -> bool:
        return True

    def calibrate(self) -> None:
        pass

    def configure(self) -> None:
        pass

    def get_action(self) -> dict:
        t = time.monotonic() - self.started
        action = {f"{m}.pos": v for m, v in HOME.items()}
        action["shoulder_pan.pos"] = 20.0 * math.sin(2.0 * math.pi * t / 4.0)
        action["gripper.pos"] = 50.0 + 40.0 * math.cos(2.0 * math.pi * t / 4.0)
        return action

    def send_feedback(self, feedback: dict) -> None:
        pass

    def disconnect(self) -> None:
        pass


def main() -> None:
    zenoh_config, root, seconds = sys.argv[1], Path(sys.argv[2]), float(sys.argv[3])
    register_third_party_plugins()
    from lerobot_robot_clawfleet import ClawfleetConfig

    robot = make_robot_from_config(
        ClawfleetConfig(
            id="arm_1", calibration_dir=root / "calibration", zenoh_config=zenoh_config, line_cameras=["overhead"]
        )
    )
    teleop_processor, robot_action_processor, observation_processor = make_default_processors()
    features = combine_feature_dicts(
        aggregate_pipeline_dataset_features(
            pipeline=teleop_processor,
            initial_features=create_initial_features(action=robot.action_features),
            use_videos=True,
        ),
        aggregate_pipeline_dataset_features(
            pipeline=observation_processor,
            initial_features=create_initial_features(observation=robot.observation_features),
            use_videos=True,
        ),
    )
    dataset = LeRobotDataset.create(
        repo_id="clawfleet/line_arm_1",
        fps=FPS,
        root=root / "dataset",
        robot_type=robot.name,
        features=features,
        use_videos=True,
        image_writer_threads=2,
    )
    robot.connect()
    try:
        record_loop(
            robot=robot,
            events={"exit_early": False, "rerecord_episode": False, "stop_recording": False},
            fps=FPS,
            teleop_action_processor=teleop_processor,
            robot_action_processor=robot_action_processor,
            robot_observation_processor=observation_processor,
            dataset=dataset,
            teleop=Scripted(),
            control_time_s=seconds,
            single_task="swing the pan",
        )
        dataset.save_episode()
        dataset.finalize()
    finally:
        robot.disconnect()
    # PyAV decodes (it carries its own FFmpeg); torchcodec, the default, needs the system FFmpeg libraries
    loaded = LeRobotDataset("clawfleet/line_arm_1", root=root / "dataset", video_backend="pyav")
    frames = [loaded[i] for i in range(len(loaded))]
    print(
        json.dumps(
            {
                "frames": len(loaded),
                "episodes": loaded.num_episodes,
                "features": sorted(loaded.features),
                "names": loaded.features["observation.state"]["names"],
                "state": [np.asarray(f["observation.state"], float).tolist() for f in frames],
                "action": [np.asarray(f["action"], float).tolist() for f in frames],
                "image_shape": list(np.asarray(frames[0]["observation.images.overhead"]).shape),
                "image_std": float(np.asarray(frames[-1]["observation.images.overhead"], float).std()),
            }
        ),
        flush=True,
    )


if __name__ == "__main__":
    main()
