"""Cameras in the scene format: each mistake is one line naming the file, the field and the reason."""

from pathlib import Path

import pytest
import yaml

from fleet.common.scene_loading import load_checked_scene
from scenes.loader import BUNDLED_DIR, SceneError, bundled_scene_names
from scenes.schema import MAX_CAMERA_PIXELS_PER_S

OVERHEAD = {
    "name": "top",
    "pose": {"xyz": [0.2, 0.1, 1.0], "look_at": [0.2, 0.1, 0.0], "up": [0.0, 1.0, 0.0]},
    "width_px": 64,
    "height_px": 48,
    "rate_hz": 5,
    "images": ["rgb", "depth"],
}


def pick_cell_with(tmp_path: Path, *cameras: dict) -> Path:
    data = yaml.safe_load((BUNDLED_DIR / "pick_cell.yaml").read_text())
    data["cameras"] = list(cameras)
    path = tmp_path / "cell.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize("name", bundled_scene_names())
def test_every_bundled_scene_has_an_overhead_camera(name):
    cameras = {c.name: c for c in load_checked_scene(name).cameras}
    assert cameras["overhead"].mount == "world"
    assert {"rgb", "depth", "segmentation"} <= set(cameras["overhead"].images)


def test_a_bundled_scene_has_a_wrist_camera_on_its_arm():
    wrist = load_checked_scene("pick_cell").camera("wrist")
    assert (wrist.arm, wrist.link) == ("arm_0", "tool_link")


def test_a_well_formed_camera_loads(tmp_path):
    scene = load_checked_scene(pick_cell_with(tmp_path, OVERHEAD))
    assert scene.camera("top").pixels_per_s == 64 * 48 * 5


@pytest.mark.parametrize(
    "change, field, says",
    [
        ({"mount": "arm_7/tool_link"}, "cameras.0.mount", "no arm 'arm_7'; arms: arm_0"),
        ({"mount": "arm_0/elbow"}, "cameras.0.mount", "openclaw has no link 'elbow'; links: base_link"),
        ({"mount": "arm_0"}, "cameras.0.mount", "should match pattern"),
        ({"near_m": 5.0, "far_m": 2.0}, "cameras.0", "near_m 5 must be below far_m 2"),
        ({"images": ["rgb", "rgb"]}, "cameras.0", "at most once"),
        ({"images": ["infrared"]}, "cameras.0.images.0", "'rgb', 'depth' or 'segmentation'"),
        ({"images": []}, "cameras.0.images", "at least 1 item"),
        ({"width_px": 4000}, "cameras.0.width_px", "less than or equal to 1920"),
        ({"rate_hz": 0}, "cameras.0.rate_hz", "greater than 0"),
        ({"pose": {"xyz": [0, 0, 1], "look_at": [0, 0, 1]}}, "cameras.0.pose", "at least 1 mm from xyz"),
        ({"pose": {"xyz": [0, 0, 1], "look_at": [0, 0, 0]}}, "cameras.0.pose", "up lies along the view"),
        ({"lens": "wide"}, "cameras.0.lens", "Extra inputs are not permitted"),
    ],
)
def test_a_wrong_camera_is_one_line_naming_the_field(tmp_path, change, field, says):
    path = pick_cell_with(tmp_path, OVERHEAD | change)
    with pytest.raises(SceneError) as err:
        load_checked_scene(path)
    line = str(err.value)
    assert line.startswith(f"{path}: {field}: ") and says in line and "\n" not in line, line


def test_the_pixel_budget_is_refused_with_the_total_and_the_limit(tmp_path):
    big = OVERHEAD | {"width_px": 1920, "height_px": 1080, "rate_hz": 2}
    path = pick_cell_with(tmp_path, big, big | {"name": "other"})
    with pytest.raises(SceneError, match=f"cameras: 8,294,400 pixels/s .* budget is {MAX_CAMERA_PIXELS_PER_S:,}"):
        load_checked_scene(path)


def test_camera_names_differ(tmp_path):
    with pytest.raises(SceneError, match="cameras: camera names must differ: top, top"):
        load_checked_scene(pick_cell_with(tmp_path, OVERHEAD, OVERHEAD))
