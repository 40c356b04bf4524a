"""Cameras over a real world, rendered by SAPIEN (on the CPU through Mesa's lavapipe where no GPU is): images that
mean what they say, the same bytes for the same run, and nothing rendered where nothing asked."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fleet.common.scene_loading import load_checked_scene
from fleet.sim.cameras import labels
from fleet.sim.cameras.rig import CameraMountError, CameraRig
from fleet.sim.world import World
from scenes.schema import Camera


def world_with_parts(scene_name: str = "pick_cell", ticks: int = 500) -> World:
    world = World(load_checked_scene(scene_name))
    world.step(ticks)
    assert world.active_parts(), "parts have arrived"
    return world


def camera_above(xyz, height_m: float = 0.4, size_px: int = 128) -> Camera:
    x, y, z = xyz
    return Camera(
        name="close",
        pose={"xyz": (x, y, z + height_m), "look_at": (x, y, z), "up": (0.0, 1.0, 0.0)},
        width_px=size_px,
        height_px=size_px,
        fov_deg=40,
        images=["rgb", "depth", "segmentation"],
    )


def test_a_world_without_cameras_has_no_renderer():
    world = World(load_checked_scene("pick_cell"))
    with pytest.raises(RuntimeError, match="no system with name \\[render\\]"):
        world.scene.get_render_system()


def test_the_same_run_gives_the_same_image_bytes():
    first, second = (CameraRig(world_with_parts()).frames() for _ in range(2))
    for name in first:
        for image in ("rgb", "depth_m", "segmentation"):
            a, b = getattr(first[name], image), getattr(second[name], image)
            assert a.tobytes() == b.tobytes(), (name, image)
        assert first[name].rgb.std() > 10, f"{name}: the image shows something (not one flat colour)"


def test_depth_back_projects_onto_the_parts_top_face_within_5_mm():
    world = world_with_parts()
    part = world.active_parts()[0]
    frame = CameraRig(world, [camera_above(part.position)]).frames()["close"]
    points = frame.points_in_world(frame.segmentation == labels.part_label(part.part_id))
    top_z = part.position[2] + part.height_m / 2
    top_face = points[points[:, 2] > top_z - 0.003]
    assert len(top_face) > 50
    assert np.linalg.norm(top_face[:, :2].mean(axis=0) - part.position[:2]) < 0.005
    assert abs(top_face[:, 2].mean() - top_z) < 0.005


def test_segmentation_names_parts_by_id_arms_by_index_and_stations():
    world = world_with_parts()
    frame = CameraRig(world).frames()["overhead"]
    seen = [labels.read_label(int(v)) for v in np.unique(frame.segmentation)]
    kinds = {label.kind for label in seen}
    assert {"floor", "belt", "station", "arm", "part"} <= kinds
    assert {label.index for label in seen if label.kind == "part"} <= {p.part_id for p in world.active_parts()}
    assert {label.index for label in seen if label.kind == "arm"} == {0}
    assert {label.index for label in seen if label.kind == "station"} <= set(range(len(world.scene_model.stations)))


def test_a_parts_centre_projects_through_the_optical_frame_onto_its_own_pixels():
    world = world_with_parts()
    part = world.active_parts()[0]
    frame = CameraRig(world).frames()["overhead"]
    w, x, y, z = frame.quaternion_wxyz
    optical = Rotation.from_quat([x, y, z, w]).inv().apply(part.position - frame.position_m)
    assert optical[2] > 0, "the optical frame's +z looks at the part"
    column, row = (frame.intrinsics @ (optical / optical[2]))[:2]
    assert frame.segmentation[int(row), int(column)] == labels.part_label(part.part_id)


def test_a_wrist_camera_rides_on_its_link():
    world = world_with_parts()
    rig = CameraRig(world)
    before = rig.frames(["wrist"])["wrist"].position_m
    arm = world.arms["arm_0"]
    arm.set_qpos(np.asarray(arm.qpos()) + 0.3)
    after = rig.frames(["wrist"])["wrist"].position_m
    assert np.linalg.norm(after - before) > 0.02


def test_a_mount_on_a_missing_link_is_refused_by_name():
    world = World(load_checked_scene("pick_cell"))
    wrong = load_checked_scene("pick_cell").camera("wrist").model_copy(update={"mount": "arm_0/elbow"})
    with pytest.raises(CameraMountError, match="camera 'wrist': arm_0 has no link 'elbow'; links: base_link"):
        CameraRig(world, [wrong])


@pytest.mark.parametrize("rate_hz, frames_in_one_s", [(5, 5), (10, 10), (30, 30), (7, 7)])
def test_a_camera_is_due_at_its_rate_in_sim_time(rate_hz, frames_in_one_s):
    world = World(load_checked_scene("pick_cell"))
    rig = CameraRig(world, [load_checked_scene("pick_cell").camera("overhead").model_copy(update={"rate_hz": rate_hz})])
    hz = int(world.scene_model.control_hz)
    assert sum(bool(rig.due(tick)) for tick in range(hz)) == frames_in_one_s


def test_visual_randomisation_changes_what_cameras_see_and_nothing_else(tmp_path):
    import yaml

    from scenes.loader import BUNDLED_DIR

    data = yaml.safe_load((BUNDLED_DIR / "pick_cell.yaml").read_text())
    data["randomise"] = {
        "light_yaw_deg": {"uniform": [-180, 180]},
        "light_intensity_scale": {"uniform": [0.5, 1.5]},
        "belt_grey": {"uniform": [0.0, 0.6]},
        "part_shade": {"uniform": [0.5, 1.5]},
        "camera_jitter_m": {"uniform": [0.01, 0.03]},
    }
    (tmp_path / "looks.yaml").write_text(yaml.safe_dump(data))
    plain = load_checked_scene("pick_cell")
    one, two = (load_checked_scene(tmp_path / "looks.yaml", seed=s) for s in (1, 2))
    assert one.appearance != two.appearance and one.camera("overhead").pose != plain.camera("overhead").pose
    assert set(one.randomised) == set(data["randomise"])
    assert one.feeders == plain.feeders and one.conveyor == plain.conveyor, "the physics is the scene's own"
    frames = []
    for scene in (one, two):
        world = World(scene)
        world.step(500)
        frames.append(CameraRig(world, [scene.camera("overhead")]).frames()["overhead"])
    assert frames[0].rgb.tobytes() != frames[1].rgb.tobytes()


def test_the_optical_frame_ros_tools_get_is_the_one_the_images_were_made_in():
    """`/tf_static`'s optical frame of a fixed camera (worked out from the scene alone) is where the frames' own
    optical pose says the camera stood."""
    from fleet.record.camera_to_ros import optical_in_mount

    world = world_with_parts()
    frame = CameraRig(world).frames(["overhead"])["overhead"]
    position, (qx, qy, qz, qw) = optical_in_mount(world.scene_model.camera("overhead").pose)
    assert np.allclose(position, frame.position_m, atol=1e-6)
    w, x, y, z = frame.quaternion_wxyz
    assert abs(abs(np.dot([qx, qy, qz, qw], [x, y, z, w])) - 1.0) < 1e-6, "the same rotation"


def test_shadows_by_default_where_a_gpu_renders_and_none_on_a_cpu_renderer():
    from fleet.sim.render import renders_on_cpu

    scene = load_checked_scene("pick_cell")
    colours = {}
    for shadows in ("auto", True, False):
        looks = scene.model_copy(update={"appearance": scene.appearance.model_copy(update={"shadows": shadows})})
        world = World(looks)  # the arms at home cast shadows enough
        colours[shadows] = CameraRig(world, [looks.camera("overhead")]).frames()["overhead"].rgb.tobytes()
    assert colours[True] != colours[False], "the arms and parts cast shadows where asked"
    assert colours["auto"] == colours[not renders_on_cpu()]
