"""Parts found in one RGB-D frame: pixels of a part's colour (`PartLook`), grouped into blobs, each blob
back-projected through the depth into the world: where its top face lies, which way it turns, how sure the blob
is of being that part."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from perception.looks import PartLook, coloured, hue_distance_deg
from perception.rgbd import RGBDFrame

MIN_PIXELS = 3  # a blob smaller than this is noise (a part's edge, a reflection)
FULL_PIXELS = 12  # a blob this large is seen whole enough to be sure of its size
TOP_FACE_M = 0.006  # the blob's points this close below its highest are its top face


@dataclass(frozen=True)
class Detection:
    """A part seen by `camera` at `sim_time_s`: of `kind` (a `PartLook.kind`), its top face's centre
    `top_centre_m` (world), the direction of its longer side `yaw_rad` (world, in [-pi/2, pi/2): a box turned
    half a turn looks the same), from `pixels` pixels, with `confidence` in 0-1."""

    camera: str
    sim_time_s: float
    kind: int
    top_centre_m: tuple[float, float, float]
    yaw_rad: float
    pixels: int
    confidence: float


def detect_parts(
    frame: RGBDFrame,
    looks: list[PartLook],
    z_range_m: tuple[float, float] = (-np.inf, np.inf),
    min_pixels: int = MIN_PIXELS,
) -> list[Detection]:
    """The parts of `looks` seen in `frame` whose top faces lie within `z_range_m` (world heights: keep out what
    stands above the surfaces parts lie on), each pixel given to the look whose hue is nearest."""
    if not looks:
        return []
    hue, bright = coloured(frame.rgb)
    distances = np.stack([hue_distance_deg(hue, look.hue_deg) for look in looks])
    nearest = np.argmin(distances, axis=0)
    found = []
    for index, look in enumerate(looks):
        closeness = 1.0 - distances[index] / look.hue_tolerance_deg
        mask = bright & (nearest == index) & (closeness > 0) & (frame.depth_m > 0)
        count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
        for blob in range(1, count):
            if stats[blob, cv2.CC_STAT_AREA] < min_pixels:
                continue
            pixels = labels == blob
            detection = _blob(frame, look, pixels, float(closeness[pixels].mean()))
            if detection is not None and z_range_m[0] <= detection.top_centre_m[2] <= z_range_m[1]:
                found.append(detection)
    return found


def _blob(frame: RGBDFrame, look: PartLook, pixels: np.ndarray, closeness: float) -> Detection | None:
    """One blob of a look's colour, back-projected: its top face's centre and its turn; None where it is too long
    to be one of the look's parts."""
    points = frame.points_in_world(pixels)
    top = points[points[:, 2] >= points[:, 2].max() - TOP_FACE_M]
    yaw_rad, longer_side_m = _rectangle(points[:, :2])
    pixel_m = float(np.median(frame.depth_m[pixels])) / float(frame.intrinsics[0, 0])
    if not look.fits(longer_side_m, pixel_m):
        return None
    count = int(pixels.sum())
    confidence = closeness * min(1.0, count / FULL_PIXELS)
    centre = top.mean(axis=0)
    return Detection(frame.camera, frame.sim_time_s, look.kind, tuple(map(float, centre)), yaw_rad, count, confidence)


def _rectangle(xy_m: np.ndarray) -> tuple[float, float]:
    """The smallest rectangle about the points (world x-y): the direction of its longer side, in [-pi/2, pi/2), and
    that side's length (m)."""
    if len(xy_m) < 3:
        return 0.0, 0.0
    (_, _), (width, height), angle_deg = cv2.minAreaRect((xy_m * 1000.0).astype(np.float32))
    yaw = np.deg2rad(angle_deg + (90.0 if width < height else 0.0))
    return float((yaw + np.pi / 2) % np.pi - np.pi / 2), max(width, height) / 1000.0
