"""Arm geometry: the branch-and-bound distance equals python-fcl over every pair of shapes, and the spheres
that bound each shape really hold it."""

import fcl
import numpy as np
import pytest

from coordinator.geometry import ArmGeometry, link_shapes, separation_m
from robots.frames import yaw_transform
from robots.registry import get_robot


def every_pair_distance_m(a: ArmGeometry, b: ArmGeometry) -> float:
    request = fcl.DistanceRequest()
    return min(
        fcl.distance(a.object(i), b.object(j), request, fcl.DistanceResult())
        for i in range(len(a.shapes))
        for j in range(len(b.shapes))
    )


def test_separation_equals_python_fcl_over_every_shape_pair():
    spec = get_robot("openclaw")
    a = ArmGeometry("arm_0", spec, yaw_transform((0.0, 0.0, 0.0), np.pi / 2))
    b = ArmGeometry("arm_1", spec, yaw_transform((0.45, 0.0, 0.0), np.pi / 2))
    lower, upper = a.km.lower[a.km.arm_q_index], a.km.upper[a.km.arm_q_index]
    rng = np.random.default_rng(0)
    for _ in range(150):
        a.place(rng.uniform(lower, upper))
        b.place(rng.uniform(lower, upper))
        exact = every_pair_distance_m(a, b)
        got = separation_m(a, b)
        if exact > 0:
            assert got == pytest.approx(exact, abs=1e-9)
        else:
            assert got <= 1e-9  # touching: both say so (penetration depths need not agree)


@pytest.mark.parametrize("robot", ["openclaw", "panda"])
def test_each_shape_lies_inside_its_cover_of_spheres(robot):
    """Points sampled in each shape (in its own frame), its corners and rims included, are inside one of its cover
    spheres."""
    rng = np.random.default_rng(1)
    for shape in link_shapes(get_robot(robot)):
        g = shape.geometry
        if isinstance(g, fcl.Box):
            half = np.array(g.side) / 2
            points = np.vstack(
                [
                    rng.uniform(-half, half, size=(400, 3)),
                    half * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]),
                ]
            )
        elif isinstance(g, fcl.Cylinder):
            angle, radius = rng.uniform(0, 2 * np.pi, 400), g.radius * np.sqrt(rng.uniform(0, 1, 400))
            radius[:100] = g.radius  # on the rim
            z = rng.uniform(-g.lz / 2, g.lz / 2, 400)
            z[:50], z[50:100] = -g.lz / 2, g.lz / 2
            points = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), z])
        else:
            continue  # spheres are their own cover; a mesh's cover is built from its vertices
        inside = (
            np.linalg.norm(points[:, None, :] - shape.cover[None, :, :3], axis=2) <= shape.cover[None, :, 3] + 1e-12
        )
        assert inside.any(axis=1).all(), shape.link


@pytest.mark.parametrize("robot", ["openclaw", "so101", "panda"])
def test_no_point_of_the_arm_moves_faster_than_its_joint_levers_allow(robot):
    """Over random configurations and small joint steps dq, every cover sphere's farthest point moves at most
    sum_j |dq_j| * lever_j: the bound the plant's safety layer steps its walk by."""
    arm = ArmGeometry("arm_0", get_robot(robot), yaw_transform((0.2, -0.1, 0.0), 0.7))
    levers = arm.joint_levers_m()
    lower, upper = arm.km.lower[arm.km.arm_q_index], arm.km.upper[arm.km.arm_q_index]
    rng = np.random.default_rng(2)
    worst = 0.0
    for _ in range(300):
        q = rng.uniform(lower, upper)
        dq = rng.normal(0.0, 1e-4, q.size)
        arm.place(q)
        before = arm.cover_centres.copy()
        arm.place(q + dq)
        moved = np.linalg.norm(arm.cover_centres - before, axis=1).max()
        worst = max(worst, moved / (np.abs(dq) @ levers))
    assert worst <= 1.0 + 1e-3, f"a point moved {worst:.3f} times the bound"
    assert worst > 0.3, "the bound is not loose by orders of magnitude"
