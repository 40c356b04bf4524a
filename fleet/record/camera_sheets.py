"""What each camera of a recording saw, to look at rather than read: a contact sheet (frames evenly spread over the
run, each with its sim time) and a short animation (GIF) per camera (`fleet report`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.images import decode_image
from fleet.bus.keys import Keys
from fleet.bus.messages import CameraImage
from fleet.record.mcap_file import Recording

SHEET_FRAMES = 12  # on a sheet, in rows of 4
ANIMATION_FRAMES = 200  # at most, evenly taken; played at 10 frames a second
LABEL_PX = 14


def camera_frames(recording: Recording, camera: str) -> list[tuple[float, np.ndarray]]:
    """Every RGB frame a camera's images in the recording hold: (sim time, uint8 HxWx3), in order; frames that do
    not decode are left out."""
    key = Keys(recording.run_id).camera(camera, "rgb")
    if key not in recording.channels:
        return []
    decoder, frames = Decoder(CameraImage, DropCounter()), []
    for raw in recording.raw_messages([key]):
        message = decoder.decode(raw.key, raw.payload)
        if message is None:
            continue
        try:
            frames.append(
                (
                    message.sim_time_s,
                    decode_image("rgb", message.data, message.encoding, message.width_px, message.height_px),
                )
            )
        except ValueError:
            continue
    return frames


def _spread(items: list, n: int) -> list:
    """At most `n` of `items`, evenly spread, first and last kept."""
    if len(items) <= n:
        return items
    return [items[round(i * (len(items) - 1) / (n - 1))] for i in range(n)]


def contact_sheet(frames: list[tuple[float, np.ndarray]], columns: int = 4) -> Image.Image:
    """The frames in a grid, each labelled with its sim time."""
    h, w = frames[0][1].shape[:2]
    rows = -(-len(frames) // columns)
    sheet = Image.new("RGB", (columns * w, rows * (h + LABEL_PX)), "white")
    draw = ImageDraw.Draw(sheet)
    for i, (t, image) in enumerate(frames):
        x, y = (i % columns) * w, (i // columns) * (h + LABEL_PX)
        sheet.paste(Image.fromarray(image), (x, y + LABEL_PX))
        draw.text((x + 2, y + 1), f"{t:.1f} s", fill="black")
    return sheet


def write_camera_sheets(recording: Recording, out_dir: Path) -> list[Path]:
    """`<camera>_sheet.png` and `<camera>.gif` for every camera with frames in the recording."""
    written = []
    for camera in recording.scene.cameras:
        frames = camera_frames(recording, camera.name)
        if not frames:
            continue
        sheet = out_dir / f"{camera.name}_sheet.png"
        contact_sheet(_spread(frames, SHEET_FRAMES)).save(sheet)
        animation = out_dir / f"{camera.name}.gif"
        pictures = [Image.fromarray(image) for _, image in _spread(frames, ANIMATION_FRAMES)]
        pictures[0].save(animation, save_all=True, append_images=pictures[1:], duration=100, loop=0)
        written += [sheet, animation]
    return written
