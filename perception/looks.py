"""What a kind of part looks like to a camera: its colour's hue, and how far a lit pixel's hue and saturation may
stray from it. Lighting scales a colour and washes it towards grey; its hue stays."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

MIN_SATURATION = 0.25  # greyer than this is belt, floor, a light grey arm: no part's colour
MIN_VALUE = 0.2  # darker than this is shadow or the belt


@dataclass(frozen=True)
class PartLook:
    """A kind of part (`kind`, the caller's key: a type index, a colour name) by its colour, RGB in 0-1, and its size
    (x, y, z in metres; None: any): a blob of its colour much longer than the part (an arm's link, a station) is not
    one of its parts."""

    kind: int
    rgb: tuple[float, float, float]
    size_m: tuple[float, float, float] | None = None
    hue_tolerance_deg: float = 12.0

    def fits(self, longer_side_m: float, pixel_m: float) -> bool:
        """Whether a blob whose longer side is `longer_side_m`, seen with pixels `pixel_m` wide, can be this part."""
        if self.size_m is None:
            return True
        return longer_side_m <= 1.5 * max(self.size_m[0], self.size_m[1]) + 2.0 * pixel_m

    @property
    def hue_deg(self) -> float:
        return float(hue_deg(np.asarray([[self.rgb]], float))[0, 0])


def hue_deg(rgb: np.ndarray) -> np.ndarray:
    """Hue in degrees (0-360) of an RGB image, uint8 0-255 or float 0-1."""
    image = rgb.astype(np.float32) / (255.0 if rgb.dtype == np.uint8 else 1.0)
    return cv2.cvtColor(image, cv2.COLOR_RGB2HSV)[..., 0]


def hue_distance_deg(a: np.ndarray, b: float) -> np.ndarray:
    d = np.abs(a - b) % 360.0
    return np.minimum(d, 360.0 - d)


def coloured(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(hue in degrees, mask of pixels saturated and bright enough to carry a part's colour) of a uint8 image."""
    hsv = cv2.cvtColor(rgb.astype(np.float32) / 255.0, cv2.COLOR_RGB2HSV)
    return hsv[..., 0], (hsv[..., 1] >= MIN_SATURATION) & (hsv[..., 2] >= MIN_VALUE)
