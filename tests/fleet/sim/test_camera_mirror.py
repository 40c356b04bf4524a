"""The render mirror's copies of bodies: a body of several shapes drawn as one mesh looks exactly as its shapes
drawn one by one (one draw instead of several is what makes small frames cheap on a CPU)."""

import numpy as np
import sapien

from fleet.sim.cameras.mirror import merged_visual, shadow_map_px
from fleet.sim.render import render_system

MATERIAL = sapien.render.RenderMaterial(base_color=[0.5, 0.4, 0.3, 1.0])


def some_shapes() -> list:
    """A box, a cylinder, a sphere and a capsule at poses of their own, as a bin's walls and a claw's links are."""
    box = sapien.render.RenderShapeBox([0.1, 0.05, 0.02], MATERIAL)
    box.local_pose = sapien.Pose([0.05, 0.0, 0.0], [0.92, 0.0, 0.38, 0.0])
    cylinder = sapien.render.RenderShapeCylinder(0.03, 0.08, MATERIAL)
    cylinder.local_pose = sapien.Pose([-0.08, 0.06, 0.02], [0.71, 0.0, 0.0, 0.71])
    sphere = sapien.render.RenderShapeSphere(0.04, MATERIAL)
    sphere.local_pose = sapien.Pose([0.0, -0.09, 0.03])
    capsule = sapien.render.RenderShapeCapsule(0.02, 0.05, MATERIAL)
    capsule.local_pose = sapien.Pose([0.1, 0.1, 0.05], [0.92, 0.38, 0.0, 0.0])
    return [box, cylinder, sphere, capsule]


def depth_of(shapes: list) -> np.ndarray:
    """Depth (m) of a body holding `shapes`, seen from above and aside by a small camera."""
    scene = sapien.Scene([render_system()])
    scene.set_ambient_light([0.5] * 3)
    body = sapien.render.RenderBodyComponent()
    for shape in shapes:
        body.attach(shape)
    entity = sapien.Entity()
    entity.add_component(body)
    scene.add_entity(entity)
    entity.set_pose(sapien.Pose([0.0, 0.0, 0.1], [0.98, 0.0, 0.0, 0.2]))
    camera = scene.add_camera("c", 48, 48, 1.0, 0.01, 5.0)
    camera.entity.set_pose(sapien.Pose([-0.35, -0.2, 0.45], [0.88, 0.1, 0.35, 0.3]))
    scene.update_render()
    camera.take_picture()
    return camera.get_picture("PositionSegmentation")[..., 2] * -0.001


def test_a_body_of_several_shapes_merged_into_one_mesh_renders_as_its_shapes():
    apart, merged = depth_of(some_shapes()), depth_of([merged_visual(some_shapes())])
    drawn, both = (apart > 0) | (merged > 0), (apart > 0) & (merged > 0)
    assert drawn.sum() > 200, "the body fills part of the picture"
    assert (drawn & ~both).sum() <= 0.02 * drawn.sum(), "the same silhouette, but for a pixel on an edge here and there"
    off_m = np.abs(apart - merged)[both]
    assert np.quantile(off_m, 0.9) <= 2e-3, "the same surface, to the millimetre the image holds (but where a"
    assert off_m.max() <= 0.02, "pixel is a hair off on a face steep to the camera: 48 px see ~1 cm a pixel)"


def test_the_shadow_map_fits_the_largest_camera_within_its_bounds():
    assert [shadow_map_px(p) for p in (16, 64, 100, 128, 200, 640)] == [128, 128, 256, 256, 512, 512]
