"""The claw as it is: its shapes swept over a span of openings, as convex hulls in the frame of the link it hangs from.

A claw's fingers move with its own joints, not the arm's. Collision checks that placed them closed missed an open
claw by up to the fingers' travel. Here a span of openings (0 closed, 1 open, as `RobotSpec.gripper_targets` maps
them; the joints' limits may reach past either end) becomes, for each shape the claw's joints carry, the convex hull
of that shape at every opening of the span on a grid of `SPAN_STEPS` steps over the claw's whole travel. A shape
sliding on a prismatic joint sweeps exactly that hull; one turning on a revolute joint is short of its arc by the
chord's sagitta between two grid points (under 0.01 mm for the bundled robots). The hulls are placed with the link
the claw hangs from (the palm), so where the claw is depends on the arm's joints only, and how far it reaches on
the span. Hulls are built once per span and robot in a process.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import fcl
import numpy as np
import trimesh
from scipy.spatial import HalfspaceIntersection

from robots.kinematics import KinematicModel
from robots.spec import RobotSpec

SPAN_STEPS = 64  # the grid a span's ends are rounded out to, over the claw's whole travel


@dataclass(frozen=True)
class ClawSpan:
    """The openings a claw may take over some stretch of time: from `low` to `high` (0 closed, 1 open)."""

    low: float
    high: float

    @classmethod
    def at(cls, opening: float) -> ClawSpan:
        """A claw known to stand at one opening."""
        return cls(float(opening), float(opening))

    def union(self, *openings: float) -> ClawSpan:
        """This span widened to hold `openings` too."""
        return ClawSpan(min(self.low, *openings), max(self.high, *openings))

    def holds(self, other: ClawSpan) -> bool:
        """Whether every opening of `other` is in this span."""
        return self.low <= other.low and other.high <= self.high


def _parents(root: ET.Element) -> tuple[dict[str, tuple[str, str]], dict[str, list[str]]]:
    """Each joint's (parent link, child link), and each link's child links."""
    joints, children = {}, {}
    for joint in root.findall("joint"):
        parent, child = joint.find("parent").get("link"), joint.find("child").get("link")
        joints[joint.get("name")] = (parent, child)
        children.setdefault(parent, []).append(child)
    return joints, children


def claw_links(spec: RobotSpec) -> tuple[str, frozenset[str]]:
    """The link the claw's joints hang from (the palm) and every link those joints carry."""
    joints, children = _parents(ET.fromstring(spec.urdf_text()))
    palms = {joints[name][0] for name in spec.gripper_joints}
    if len(palms) != 1:
        raise ValueError(f"{spec.uid}: the gripper joints hang from {sorted(palms)}; one palm link was expected")
    carried, todo = set(), [joints[name][1] for name in spec.gripper_joints]
    while todo:
        link = todo.pop()
        if link not in carried:
            carried.add(link)
            todo.extend(children.get(link, []))
    return palms.pop(), frozenset(carried)


class ClawSweeps:
    """A robot's claw shapes swept over spans of openings: `geometries(span)` gives one FCL convex per claw shape
    (`indices`: which of the robot's link shapes), in the palm's frame; `full` is the span of the claw joints'
    limits, `full_points` each claw shape's points over all of it."""

    def __init__(self, spec: RobotSpec, km: KinematicModel, shapes: list) -> None:
        """`shapes`: the robot's link shapes (`coordinator.geometry.LinkShape`: link, transform_shape_to_link,
        vertices); those on links the claw's joints carry are swept."""
        self.spec, self.km = spec, km
        self.palm, carried = claw_links(spec)
        self.indices = [i for i, s in enumerate(shapes) if s.link in carried]
        self._shapes = [
            (shapes[i].link, shapes[i].transform_shape_to_link, _few_points(shapes[i].vertices)) for i in self.indices
        ]
        lower, upper = km.lower[km.gripper_q_index], km.upper[km.gripper_q_index]
        closed, opened = np.asarray(spec.gripper_closed, float), np.asarray(spec.gripper_open, float)
        run = np.where(np.abs(opened - closed) > 1e-12, opened - closed, 1.0)
        self._closed, self._run = closed, opened - closed
        ends = np.sort(np.stack([(lower - closed) / run, (upper - closed) / run]), axis=0)
        # every joint within its limits: the openings where the first joint reaches a limit
        self.full = ClawSpan(float(ends[0].max()), float(ends[1].min()))
        self._step = (self.full.high - self.full.low) / SPAN_STEPS
        self._hulls: dict[tuple[int, int], list[fcl.Convex]] = {}
        self._steps: dict[int, list[np.ndarray]] = {}
        self._sliding = all(_prismatic(km, name) for name in spec.gripper_joints)
        self.full_points = self._points(0, SPAN_STEPS)

    def key(self, span: ClawSpan) -> tuple[int, int]:
        """The grid steps a span is rounded out to (clipped to the claw's travel)."""
        low = (min(max(span.low, self.full.low), self.full.high) - self.full.low) / self._step
        high = (min(max(span.high, self.full.low), self.full.high) - self.full.low) / self._step
        return math.floor(low + 1e-9), math.ceil(high - 1e-9)

    def _at_step(self, k: int) -> list[np.ndarray]:
        """Each claw shape's points at grid opening k, in the palm's frame (computed once)."""
        points = self._steps.get(k)
        if points is None:
            opening = self.full.low + k * self._step
            poses = self.km.link_poses(
                self.km.full_q(np.asarray(self.spec.home_q, float), self._closed + opening * self._run)
            )
            palm_inverse = np.linalg.inv(poses[self.palm])
            points = []
            for link, shape_to_link, vertices in self._shapes:
                T = palm_inverse @ poses[link] @ shape_to_link
                points.append(vertices @ T[:3, :3].T + T[:3, 3])
            self._steps[k] = points
        return points

    def _points(self, k0: int, k1: int) -> list[np.ndarray]:
        """Each claw shape's points at every grid opening from step k0 to k1, in the palm's frame (the two ends
        only where every claw joint slides: a shape moved along a line sweeps the hull of its two ends)."""
        steps = sorted({k0, k1}) if self._sliding else range(k0, k1 + 1)
        at = [self._at_step(k) for k in steps]
        return [np.concatenate([a[i] for a in at]) for i in range(len(self._shapes))]

    def geometries(self, span: ClawSpan) -> tuple[tuple[int, int], list[fcl.Convex]]:
        """The grid key of `span` and one FCL convex per claw shape holding it over the whole span (palm frame)."""
        key = self.key(span)
        hulls = self._hulls.get(key)
        if hulls is None:
            hulls = self._hulls[key] = [_convex(points) for points in self._points(*key)]
        return key, hulls


DOP_DIRECTIONS = 64  # a mesh with more hull points is swept as the polytope of its extent along this many directions


def _few_points(vertices: np.ndarray) -> np.ndarray:
    """Points whose hull holds `vertices`' hull: themselves where few, else the corners of the polytope bounding them
    along `DOP_DIRECTIONS` directions spread over the sphere (a mesh's hull of thousands of points swept over
    dozens of openings made hulls too slow to build; the polytope is looser by about 2% of the shape's size)."""
    if len(vertices) <= DOP_DIRECTIONS:
        return vertices
    k = np.arange(DOP_DIRECTIONS) + 0.5
    polar, azimuth = np.arccos(1 - 2 * k / DOP_DIRECTIONS), math.pi * (1 + 5**0.5) * k
    normals = np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1)
    offsets = (vertices @ normals.T).max(axis=0)
    inside = vertices.mean(axis=0)
    return HalfspaceIntersection(np.column_stack([normals, -offsets]), inside).intersections


def _prismatic(km: KinematicModel, joint: str) -> bool:
    return "P" in km.model.joints[km.model.getJointId(joint)].shortname().replace("JointModel", "")[:2]


def _convex(points: np.ndarray) -> fcl.Convex:
    hull = trimesh.convex.convex_hull(points)
    vertices, faces = np.asarray(hull.vertices, float), np.asarray(hull.faces)
    return fcl.Convex(vertices, len(faces), np.hstack([np.full((len(faces), 1), 3), faces]).ravel())
