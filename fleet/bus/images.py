"""Images on the bus: how a camera's RGB, depth and segmentation images are packed into `CameraImage.data`.

| kind | encoding | data |
|---|---|---|
| rgb | `png`, `jpeg` (quality 90), `raw` (a run on its own bus, by default) | the image file, or rgb8 bytes by row |
| depth | `png16` (with png or jpeg RGB), `raw` | a 16-bit PNG of millimetres (0: nothing), ROS's 16UC1; or float32 m |
| segmentation | `zlib` (with png or jpeg RGB), `raw` | int32 ids (`fleet.sim.cameras.labels`), zlib-compressed or not |

Every encoding decodes back to the camera frame's array exactly, but JPEG (lossy) and png16 (to the millimetre).
"""

from __future__ import annotations

import io
import zlib

import numpy as np
from PIL import Image

RGB_ENCODINGS = ("png", "jpeg", "raw")
JPEG_QUALITY = 90


def encodings_for(rgb_encoding: str) -> dict[str, str]:
    """The encoding of each kind of image for a line's choice of RGB encoding (`fleet run --camera-encoding`)."""
    if rgb_encoding not in RGB_ENCODINGS:
        raise ValueError(f"camera encoding {rgb_encoding!r}: valid are {', '.join(RGB_ENCODINGS)}")
    packed = rgb_encoding != "raw"
    return {"rgb": rgb_encoding, "depth": "png16" if packed else "raw", "segmentation": "zlib" if packed else "raw"}


def _file(image: Image.Image, fmt: str, **options) -> bytes:
    out = io.BytesIO()
    image.save(out, format=fmt, **options)
    return out.getvalue()


def encode_image(kind: str, image: np.ndarray, encoding: str) -> bytes:
    """`image` (a camera frame's array of `kind`) packed as `encoding`."""
    if encoding == "raw":
        dtype = {"rgb": np.uint8, "depth": "<f4", "segmentation": "<i4"}[kind]
        return np.ascontiguousarray(image, dtype=dtype).tobytes()
    if kind == "rgb" and encoding in ("png", "jpeg"):
        options = {"quality": JPEG_QUALITY} if encoding == "jpeg" else {"compress_level": 1}
        return _file(Image.fromarray(image, "RGB"), encoding.upper(), **options)
    if kind == "depth" and encoding == "png16":
        millimetres = np.clip(np.rint(np.asarray(image, dtype=np.float64) * 1000.0), 0, 65535).astype(np.uint16)
        return _file(Image.fromarray(millimetres), "PNG", compress_level=1)
    if kind == "segmentation" and encoding == "zlib":
        return zlib.compress(np.ascontiguousarray(image, dtype="<i4").tobytes(), 1)
    raise ValueError(f"no encoding {encoding!r} for {kind} images")


def _inflate(data: bytes, size: int) -> bytes:
    """zlib data that inflates to exactly `size` bytes; more or less is an error (never a bomb's gigabytes)."""
    inflater = zlib.decompressobj()
    out = inflater.decompress(data, size)
    if len(out) != size or inflater.unconsumed_tail or not inflater.eof:
        raise ValueError(f"zlib data that is not {size} bytes")
    return out


def _opened(data: bytes, width_px: int, height_px: int) -> Image.Image:
    """An image file of the size the message says (its header read first: a lying size is refused unread)."""
    image = Image.open(io.BytesIO(data))
    if image.size != (width_px, height_px):
        raise ValueError(f"an image file of {image.size[0]}x{image.size[1]}, not {width_px}x{height_px}")
    return image


def decode_image(kind: str, data: bytes, encoding: str, width_px: int, height_px: int) -> np.ndarray:
    """The array an image message carries: uint8 HxWx3 (rgb), float32 HxW metres (depth), int32 HxW (segmentation).
    A payload that is not what it says raises ValueError."""
    shape = (height_px, width_px, 3) if kind == "rgb" else (height_px, width_px)
    try:
        if encoding == "raw":
            dtype = {"rgb": np.uint8, "depth": "<f4", "segmentation": "<i4"}[kind]
            array = np.frombuffer(data, dtype=dtype).reshape(shape)
        elif encoding in ("png", "jpeg") and kind == "rgb":
            array = np.asarray(_opened(data, width_px, height_px).convert("RGB"))
        elif encoding == "png16" and kind == "depth":
            array = np.asarray(_opened(data, width_px, height_px), dtype=np.float32) / 1000.0
        elif encoding == "zlib" and kind == "segmentation":
            array = np.frombuffer(_inflate(data, 4 * width_px * height_px), dtype="<i4").reshape(shape)
        else:
            raise ValueError(f"no encoding {encoding!r} for {kind} images")
    except (OSError, KeyError, zlib.error, Image.DecompressionBombError) as exc:
        raise ValueError(f"a {kind} image that is not {encoding}: {exc}") from None
    if array.shape != shape:
        raise ValueError(f"a {kind} image of {array.shape}, not {shape}")
    return array
