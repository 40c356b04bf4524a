"""The cell and the parts as Foxglove scene entities (`foxglove.SceneUpdate`), from the same boxes and cylinders as
the ROS markers (`LineToRos`: the shapes the physics collides with). Each topic's update replaces the last (its
first deletion clears the topic), as each marker message does."""

from __future__ import annotations

from foxglove.messages import (
    Color,
    CubePrimitive,
    CylinderPrimitive,
    Pose,
    Quaternion,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    Timestamp,
    Vector3,
)

CELL, PARTS = "/scene/cell", "/scene/parts"  # the belt and stations once; the parts as they go


def _pose(marker) -> Pose:
    p, q = marker.pose.position, marker.pose.orientation
    return Pose(position=Vector3(x=p.x, y=p.y, z=p.z), orientation=Quaternion(x=q.x, y=q.y, z=q.z, w=q.w))


def _entity(marker, cylinder_type: int) -> SceneEntity:
    """One marker (a box or a cylinder) as one entity, `<namespace>/<id>` in the marker's frame."""
    size = Vector3(x=marker.scale.x, y=marker.scale.y, z=marker.scale.z)
    color = Color(r=marker.color.r, g=marker.color.g, b=marker.color.b, a=marker.color.a)
    stamp = Timestamp(marker.header.stamp.sec, marker.header.stamp.nanosec)
    shape = {"pose": _pose(marker), "size": size, "color": color}
    if marker.type == cylinder_type:
        shapes = {"cylinders": [CylinderPrimitive(**shape, bottom_scale=1.0, top_scale=1.0)]}
    else:
        shapes = {"cubes": [CubePrimitive(**shape)]}
    return SceneEntity(timestamp=stamp, frame_id=marker.header.frame_id, id=f"{marker.ns}/{marker.id}", **shapes)


def scene_update(markers, delete_all: int, cylinder_type: int) -> SceneUpdate:
    """A `visualization_msgs/MarkerArray` as one update: its DELETEALL clears the topic, each shape an entity."""
    cleared = any(m.action == delete_all for m in markers.markers)
    deletions = [SceneEntityDeletion(type=SceneEntityDeletionType.All)] if cleared else []
    entities = [_entity(m, cylinder_type) for m in markers.markers if m.action != delete_all]
    return SceneUpdate(deletions=deletions, entities=entities)
