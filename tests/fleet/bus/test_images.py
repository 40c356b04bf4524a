"""Images on the bus: every encoding gives back the camera's array (JPEG close, png16 to the millimetre), and a
payload that lies about itself is a ValueError, never a crash or a bomb."""

import zlib

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from fleet.bus.images import decode_image, encode_image, encodings_for

SIZES = st.tuples(st.integers(1, 24), st.integers(1, 24))


@settings(max_examples=60, deadline=None)
@given(SIZES.flatmap(lambda hw: hnp.arrays(np.uint8, (*hw, 3))), st.sampled_from(["png", "raw"]))
def test_rgb_comes_back_exactly(image, encoding):
    data = encode_image("rgb", image, encoding)
    assert np.array_equal(decode_image("rgb", data, encoding, image.shape[1], image.shape[0]), image)


@settings(max_examples=60, deadline=None)
@given(SIZES.flatmap(lambda hw: hnp.arrays(np.float32, hw, elements=st.floats(0, 60, width=32))))
@example(np.array([[4.5625, 0.0005, 59.9995]], dtype=np.float32))  # a tie, and float32 just past half a millimetre
def test_depth_comes_back_to_the_millimetre_or_exactly(depth):
    h, w = depth.shape
    decoded = decode_image("depth", encode_image("depth", depth, "png16"), "png16", w, h)
    millimetres = np.rint(decoded.astype(np.float64) * 1000.0)  # whole millimetres, read back from float32 metres
    assert np.abs(millimetres - depth.astype(np.float64) * 1000.0).max() <= 0.5, "the nearest millimetre"
    assert np.array_equal(decode_image("depth", encode_image("depth", depth, "raw"), "raw", w, h), depth)


@settings(max_examples=60, deadline=None)
@given(SIZES.flatmap(lambda hw: hnp.arrays(np.int32, hw, elements=st.integers(0, 2**31 - 1))))
def test_segmentation_comes_back_exactly(ids):
    h, w = ids.shape
    for encoding in ("zlib", "raw"):
        assert np.array_equal(
            decode_image("segmentation", encode_image("segmentation", ids, encoding), encoding, w, h), ids
        )


@settings(max_examples=200, deadline=None)
@given(
    st.sampled_from(["rgb", "depth", "segmentation"]),
    st.sampled_from(["png", "jpeg", "raw", "png16", "zlib", "webp"]),
    st.binary(max_size=200),
    st.integers(1, 64),
    st.integers(1, 64),
)
def test_any_payload_decodes_or_is_a_value_error(kind, encoding, data, width, height):
    try:
        image = decode_image(kind, data, encoding, width, height)
    except ValueError:
        return
    assert image.shape[:2] == (height, width)


def test_a_zlib_bomb_is_refused_without_inflating_it():
    bomb = zlib.compress(bytes(200_000_000))  # 200 MB of zeros in about 200 kB
    with pytest.raises(ValueError, match="zlib data that is not 64 bytes"):
        decode_image("segmentation", bomb, "zlib", 4, 4)


def test_an_image_file_of_another_size_is_refused_from_its_header():
    data = encode_image("rgb", np.zeros((40, 30, 3), np.uint8), "png")
    with pytest.raises(ValueError, match="an image file of 30x40, not 3x4"):
        decode_image("rgb", data, "png", 3, 4)


def test_a_line_chooses_one_rgb_encoding_and_the_rest_follows():
    assert encodings_for("jpeg") == {"rgb": "jpeg", "depth": "png16", "segmentation": "zlib"}
    assert encodings_for("raw") == {"rgb": "raw", "depth": "raw", "segmentation": "raw"}
    with pytest.raises(ValueError, match="valid are png, jpeg, raw"):
        encodings_for("gif")
