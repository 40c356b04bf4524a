"""Arms as python-fcl geometry: each link's URDF collision shapes, placed by Pinocchio forward kinematics.

Primitives become FCL primitives (a URDF cylinder's axis is z, as FCL's); meshes
become BVH models. The broadphase is one matrix for the whole cell, the gaps
between every two shapes' bounding spheres (`CellBounds`), which orders the pairs
of arms. Within a pair, each shape is covered by a row of smaller spheres (a long
link's bound stays tight) and the distance is a branch and bound over their gaps,
with python-fcl measuring only the shape pairs that can still be the nearest.
(python-fcl's broadphase managers call back into Python for every candidate pair:
4x slower here, same distances.) An FCL object's pose is set only when a query
needs that shape.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import fcl
import numpy as np
from scipy.spatial.distance import cdist

from coordinator.claw_sweep import ClawSpan, ClawSweeps
from robots.kinematics import KinematicModel, PlacedFrames
from robots.spec import RobotSpec


@dataclass(frozen=True)
class LinkShape:
    """One collision shape of a link: its FCL geometry and where it sits in the link frame."""

    link: str
    geometry: fcl.CollisionGeometry
    transform_shape_to_link: np.ndarray
    radius_m: float  # a sphere about the shape's origin holding all of it
    cover: np.ndarray  # (k, 4): spheres (centre x, y, z in the shape frame, radius) that together hold all of it
    vertices: np.ndarray  # (n, 3): points in the shape frame whose convex hull holds all of it


def _rpy_matrix(r: float, p: float, y: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def _origin(element: ET.Element | None) -> np.ndarray:
    T = np.eye(4)
    if element is not None:
        T[:3, 3] = [float(v) for v in element.get("xyz", "0 0 0").split()]
        T[:3, :3] = _rpy_matrix(*[float(v) for v in element.get("rpy", "0 0 0").split()])
    return T


MAX_COVER_SPHERES = 4


def _row_cover(length_m: float, width_m: float, axis: int) -> np.ndarray:
    """Spheres in a row along `axis` holding a box or cylinder `length_m` long and at most `width_m` across
    (about one sphere per 1.5 widths of length, so a long link gets a tight bound)."""
    k = int(min(MAX_COVER_SPHERES, max(1, math.ceil(length_m / (1.5 * width_m)))))
    piece = length_m / k
    cover = np.zeros((k, 4))
    cover[:, axis] = -length_m / 2 + piece * (np.arange(k) + 0.5)
    cover[:, 3] = 0.5 * math.hypot(piece, width_m)
    return cover


def _box_cover(size: tuple[float, float, float]) -> np.ndarray:
    axis = int(np.argmax(size))
    others = [v for i, v in enumerate(size) if i != axis]
    return _row_cover(size[axis], math.hypot(*others), axis)


def _mesh_geometry(filename: str, scale: list[float]) -> tuple[fcl.CollisionGeometry, float, np.ndarray, np.ndarray]:
    import trimesh

    # The mesh's convex hull: what the physics collides with (SAPIEN makes each collision mesh convex), and FCL
    # measures convex shapes by GJK, in microseconds, where a triangle model of an SO-101 or Panda link took up to
    # tens of milliseconds a pair (a mixed line's coordinator missed its lockstep deadline on them).
    mesh = trimesh.load(Path(filename.removeprefix("file://")), force="mesh").convex_hull
    vertices = np.asarray(mesh.vertices) * np.asarray(scale)
    faces = np.asarray(mesh.faces)
    bvh = fcl.Convex(vertices, len(faces), np.hstack([np.full((len(faces), 1), 3), faces]).ravel())
    centre = (vertices.min(axis=0) + vertices.max(axis=0)) / 2  # about the mesh's box: tighter than about its origin
    cover = np.array([[*centre, np.linalg.norm(vertices - centre, axis=1).max()]])
    return bvh, float(np.linalg.norm(vertices, axis=1).max()), cover, vertices


_CORNERS = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
_OCTAGON = 8  # a cylinder's hull points: an octagon about each end, its sides touching the circle


def _cylinder_points(r: float, length: float) -> np.ndarray:
    angles = 2 * math.pi * np.arange(_OCTAGON) / _OCTAGON
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=1) * r / math.cos(math.pi / _OCTAGON)
    return np.concatenate([np.column_stack([ring, np.full(_OCTAGON, z)]) for z in (-length / 2, length / 2)])


def _geometry(
    element: ET.Element, inflate_m: float
) -> tuple[fcl.CollisionGeometry, float, np.ndarray, np.ndarray] | None:
    """An FCL geometry for a URDF <geometry> element (grown by `inflate_m` on every side), its radius, its cover of
    spheres and points whose convex hull holds it."""
    shape = next(iter(element), None)
    if shape is None:
        return None
    if shape.tag == "box":
        sx, sy, sz = (float(v) + 2 * inflate_m for v in shape.get("size").split())
        radius = 0.5 * math.sqrt(sx * sx + sy * sy + sz * sz)
        return fcl.Box(sx, sy, sz), radius, _box_cover((sx, sy, sz)), _CORNERS * [sx, sy, sz]
    if shape.tag == "cylinder":
        r, length = float(shape.get("radius")) + inflate_m, float(shape.get("length")) + 2 * inflate_m
        cylinder = fcl.Cylinder(r, length)
        return cylinder, math.hypot(r, length / 2), _row_cover(length, 2 * r, 2), _cylinder_points(r, length)
    if shape.tag == "sphere":
        r = float(shape.get("radius")) + inflate_m
        return fcl.Sphere(r), r, np.array([[0.0, 0.0, 0.0, r]]), _CORNERS * 2 * r
    if shape.tag == "mesh":
        scale = [float(v) for v in shape.get("scale", "1 1 1").split()]
        return _mesh_geometry(shape.get("filename"), scale)
    raise ValueError(f"unsupported URDF collision geometry <{shape.tag}>")


def link_shapes(spec: RobotSpec, inflate_m: float = 0.0) -> list[LinkShape]:
    """Every collision shape of the robot's URDF, by link."""
    root = ET.fromstring(spec.urdf_text())
    shapes = []
    for link in root.iter("link"):
        for collision in link.findall("collision"):
            found = _geometry(collision.find("geometry"), inflate_m)
            if found is not None:
                shapes.append(
                    LinkShape(link.get("name"), found[0], _origin(collision.find("origin")), found[1], *found[2:])
                )
    return shapes


_SHAPES: dict[int, tuple[RobotSpec, list[LinkShape], ClawSweeps]] = {}  # by the id of a declaration held here


def _shapes_of(spec: RobotSpec) -> tuple[list[LinkShape], ClawSweeps]:
    """The robot's collision shapes and its claw's sweeps, read from its URDF once per process (FCL shapes are
    fixed: arms share them)."""
    entry = _SHAPES.get(id(spec))
    if entry is None or entry[0] is not spec:
        if len(_SHAPES) >= 64:  # robot variants tried one after another (`fleet tune`): keep the newest
            _SHAPES.clear()
        shapes = link_shapes(spec)
        entry = _SHAPES[id(spec)] = (spec, shapes, ClawSweeps(spec, KinematicModel(spec), shapes))
    return entry[1], entry[2]


def _fcl_transform(T: np.ndarray) -> fcl.Transform:
    return fcl.Transform(T[:3, :3], T[:3, 3])


_REACH_BOUND_M: dict[str, float] = {}  # robot model -> radius about its base holding every link


class ArmGeometry:
    """One arm's collision objects in the world; `place(q, claw)` moves them to a configuration of the arm's joints
    with its claw anywhere in a span of openings (`coordinator.claw_sweep`; by default its whole travel)."""

    def __init__(
        self, name: str, spec: RobotSpec, transform_base_to_world: np.ndarray, model: KinematicModel | None = None
    ) -> None:
        self.name, self.spec = name, spec
        self.km = model or KinematicModel(spec)
        self.base_to_world = np.asarray(transform_base_to_world, float)
        self.shapes, self.claw = _shapes_of(spec)
        claw_at = {i: k for k, i in enumerate(self.claw.indices)}  # link shape -> claw shape
        self._claw_objects: dict[tuple[int, int], list[fcl.CollisionObject]] = {}
        self._claw_key: tuple[int, int] | None = None
        self._objects = [
            None if i in claw_at else fcl.CollisionObject(s.geometry, fcl.Transform())
            for i, s in enumerate(self.shapes)
        ]
        frames, radii, covers = [], [], []
        for i, s in enumerate(self.shapes):
            if i in claw_at:  # held by the palm: its sweep over the claw's whole travel bounds it
                points = self.claw.full_points[claw_at[i]]
                centre = (points.min(axis=0) + points.max(axis=0)) / 2
                frames.append((self.claw.palm, np.eye(4)))
                radii.append(float(np.linalg.norm(points, axis=1).max()))
                covers.append(np.array([[*centre, np.linalg.norm(points - centre, axis=1).max()]]))
            else:
                frames.append((s.link, s.transform_shape_to_link))
                radii.append(s.radius_m)
                covers.append(s.cover)
        self._placed = PlacedFrames(self.km, self.base_to_world, frames)
        self.radii_m = np.array(radii)
        cover = np.concatenate(covers)
        # each sphere's shape
        self.cover_shape = np.repeat(np.arange(len(self.shapes)), [len(c) for c in covers])
        self._cover_local = np.concatenate([cover[:, :3], np.ones((len(cover), 1))], axis=1)
        self.cover_radii_m = cover[:, 3]
        self.transforms = np.tile(np.eye(4), (len(self.shapes), 1, 1))  # each shape in the world, as placed
        self._posed = [False] * len(self.shapes)  # whether the FCL object carries the current transform
        self._cover_centres: np.ndarray | None = None
        self._placed_key = b""  # the joints and claw span last placed, as bytes
        self._q_key = b""
        if spec.uid not in _REACH_BOUND_M:  # a property of the model: drawn once per process
            _REACH_BOUND_M[spec.uid] = self._reach_bound_m()
        self.reach_bound_m = _REACH_BOUND_M[spec.uid]
        self.place(np.asarray(spec.home_q, float))

    def __getstate__(self) -> dict:
        """What the arm is built from (its FCL objects do not pickle): a run's snapshot holds its guards."""
        built = {"name": self.name, "spec": self.spec, "base_to_world": self.base_to_world, "km": self.km}
        return built | {"placed": self._placed_as}

    def __setstate__(self, state: dict) -> None:
        """Built again from the robot and its base, and placed as it was."""
        self.__init__(state["name"], state["spec"], state["base_to_world"], state["km"])
        self.place(*state["placed"])

    def joint_levers_m(self) -> np.ndarray:
        """For each arm joint (spec order), how far from its origin any shape it carries can be, in any
        configuration: the chain's fixed offsets from it to the shape's link, plus the shape's offset and radius.
        A point of the arm moves at most sum_j |dq_j| * lever_j (prismatic joints: |dq_j|)."""
        model = self._placed.model
        levers = np.zeros(model.njoints)
        for fid, radius in zip(self._placed.frame_ids, self.radii_m):
            frame = model.frames[fid]
            chain = list(model.supports[frame.parentJoint])  # joint ids from the root down to the shape's joint
            reach = float(np.linalg.norm(frame.placement.translation)) + float(radius)
            for i in reversed(chain[1:]):  # from the shape's joint up: each joint carries the shape this far
                levers[i] = max(levers[i], reach)
                reach += float(np.linalg.norm(model.jointPlacements[i].translation))
        out = []
        for name in self.spec.arm_joints:
            joint = model.joints[model.getJointId(name)]
            prismatic = "P" in joint.shortname().replace("JointModel", "")[:2]
            out.append(1.0 if prismatic else levers[model.getJointId(name)])
        return np.array(out)

    def _reach_bound_m(self, samples: int = 300, seed: int = 0) -> float:
        """A radius about the base holding every link in any configuration: over random configurations,
        the farthest shape origin plus that shape's radius, and 5 cm to spare for configurations not drawn."""
        rng = np.random.default_rng(seed)
        lower, upper = self.km.lower[self.km.arm_q_index], self.km.upper[self.km.arm_q_index]
        base = self.base_to_world[:3, 3]
        far = 0.0
        for _ in range(samples):
            origins = self._placed.poses(self.km.full_q(rng.uniform(lower, upper)))[:, :3, 3]
            far = max(far, float((np.linalg.norm(origins - base, axis=1) + self.radii_m).max()))
        return far + 0.05

    def place(self, q_arm: np.ndarray, claw: ClawSpan | None = None) -> None:
        """Put every link where forward kinematics says it is for these arm joints, the claw's shapes swept over
        the openings of `claw` (None: the claw's whole travel, wherever it may be)."""
        q_arm = np.asarray(q_arm, float)
        q_key = q_arm.tobytes()  # comparing bytes costs a tenth of np.array_equal
        claw_key = self.claw.key(claw or self.claw.full)
        if q_key == self._q_key and claw_key == self._claw_key:
            return
        self._placed_as = (q_arm.copy(), claw)
        if q_key != self._q_key:
            self.transforms = self._placed.poses(self.km.full_q(q_arm))
            self._posed = [False] * len(self._objects)
            self._cover_centres = None
            self._q_key = q_key
        if claw_key != self._claw_key:
            objects = self._claw_objects.get(claw_key)
            if objects is None:
                if len(self._claw_objects) >= 256:
                    self._claw_objects.clear()
                hulls = self.claw.geometries(claw or self.claw.full)[1]
                objects = self._claw_objects[claw_key] = [fcl.CollisionObject(h, fcl.Transform()) for h in hulls]
            for i, obj in zip(self.claw.indices, objects):
                self._objects[i], self._posed[i] = obj, False
            self._claw_key = claw_key
        self._placed_key = q_key + bytes(f"|{claw_key[0]},{claw_key[1]}", "ascii")

    @property
    def placed_key(self) -> bytes:
        """The arm joints and claw span last placed, as bytes: two placements with the same key are the same."""
        return self._placed_key

    @property
    def centres(self) -> np.ndarray:
        """Each shape's origin in the world (the centre of its bounding sphere), as placed."""
        return self.transforms[:, :3, 3]

    @property
    def cover_centres(self) -> np.ndarray:
        """The centres of the spheres covering the shapes, in the world, as placed (grouped by shape)."""
        if self._cover_centres is None:
            self._cover_centres = np.einsum("kij,kj->ki", self.transforms[self.cover_shape, :3, :], self._cover_local)
        return self._cover_centres

    def sphere_gaps(self, other: ArmGeometry) -> np.ndarray:
        """The gap between each cover sphere of this arm (rows) and each of `other`'s: a lower bound on the
        distance between the shapes they belong to (`cover_shape`)."""
        return (
            cdist(self.cover_centres, other.cover_centres) - self.cover_radii_m[:, None] - other.cover_radii_m[None, :]
        )

    def object(self, i: int) -> fcl.CollisionObject:
        """Shape i as an FCL object at its current pose."""
        if not self._posed[i]:
            self._objects[i].setTransform(_fcl_transform(self.transforms[i]))
            self._posed[i] = True
        return self._objects[i]


_PLAIN = fcl.DistanceRequest()
_POINTS = fcl.DistanceRequest(enable_nearest_points=True)


class CellBounds:
    """Lower bounds on the distance between the arms of one cell, as placed: per pair of arms (rows, columns in
    the order given) the least gap between their shapes' single bounding spheres, one `cdist` for the whole
    cell (the radii and each arm's block of shapes are fixed at construction). Loose, but enough to order and
    skip pairs; a pair that is measured gets the tight bounds of its cover spheres (`ArmGeometry.sphere_gaps`)."""

    def __init__(self, arms: list[ArmGeometry]) -> None:
        self.arms = arms
        radii = np.concatenate([a.radii_m for a in arms])
        self._radius_sums = radii[:, None] + radii[None, :]
        self._starts = np.cumsum([0] + [len(a.radii_m) for a in arms[:-1]])

    def gaps_m(self) -> np.ndarray:
        """The arm-by-arm matrix of lower bounds, for the arms as placed now (the diagonal is meaningless)."""
        centres = np.concatenate([a.centres for a in self.arms])
        shapes = cdist(centres, centres) - self._radius_sums
        return np.minimum.reduceat(np.minimum.reduceat(shapes, self._starts, axis=0), self._starts, axis=1)


def _nearest(
    a: ArmGeometry, b: ArmGeometry, request: fcl.DistanceRequest, below_m: float = math.inf
) -> tuple[float, fcl.DistanceResult | None]:
    """Branch and bound: shape pairs in order of their cover spheres' gap (a pair first comes up at its least
    gap); stop once no gap can beat the best (or `below_m`: then a pair farther apart than that answers inf
    without being measured). One FCL result object keeps the running minimum (and its nearest points) across
    the pairs measured."""
    gaps = a.sphere_gaps(b).ravel()
    candidates = np.flatnonzero(gaps < below_m)
    if candidates.size == 0:
        return math.inf, None
    result = fcl.DistanceResult(min_distance_=below_m if math.isfinite(below_m) else np.finfo(float).max)
    n_b, found, measured = len(b.cover_radii_m), False, set()
    for k in candidates[np.argsort(gaps[candidates], kind="stable")]:
        if gaps[k] >= result.min_distance:
            break
        pair = (int(a.cover_shape[k // n_b]), int(b.cover_shape[k % n_b]))
        if pair in measured:
            continue
        measured.add(pair)
        before = result.min_distance
        fcl.distance(a.object(pair[0]), b.object(pair[1]), request, result)
        found = found or result.min_distance < before
    return (float(result.min_distance), result) if found else (math.inf, None)


def neighbours(arms: dict[str, ArmGeometry], arm: str, margin_m: float) -> list[str]:
    """The other arms whose bases stand close enough that their links could come within `margin_m` of `arm`'s
    (each arm's reach bound about its base, on the floor plan)."""
    me = arms[arm]
    return [
        name
        for name, g in arms.items()
        if name != arm
        and np.linalg.norm(g.base_to_world[:2, 3] - me.base_to_world[:2, 3])
        <= g.reach_bound_m + me.reach_bound_m + margin_m
    ]


def separation_m(a: ArmGeometry, b: ArmGeometry, below_m: float = math.inf) -> float:
    """The smallest distance between two arms as placed (<= 0 when they touch); inf if it is not below `below_m`."""
    return _nearest(a, b, _PLAIN, below_m)[0]


def closest_points(a: ArmGeometry, b: ArmGeometry) -> tuple[float, np.ndarray, np.ndarray]:
    """The distance between two arms as placed and the nearest point of each (world frame, metres)."""
    return closest_points_below(a, b, math.inf)


def closest_points_below(a: ArmGeometry, b: ArmGeometry, below_m: float) -> tuple[float, np.ndarray, np.ndarray] | None:
    """`closest_points`, or None where the arms are not nearer than `below_m` (nothing is measured past it)."""
    d, result = _nearest(a, b, _POINTS, below_m)
    if result is None:
        return None
    p_a, p_b = result.nearest_points
    return d, np.asarray(p_a, float), np.asarray(p_b, float)
