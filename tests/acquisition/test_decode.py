"""From a finished buffer to a frame's image (trackerd/acquisition/decode.py, pixelformat.image_from_payload).

Payloads are laid out as GigE Vision cameras send them: rows top to bottom, pixels left to
right, one byte per Bayer or Mono8 pixel, three per RGB8 (R, G, B) or BGR8 (B, G, R) pixel.
"""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.acquisition.decode import decode_grab
from trackerd.acquisition.session import Grab
from trackerd.pixelformat import from_rgb, image_from_payload, to_rgb


class Payload:
    """A backend's ``pixels(nbytes)``: a copy of the payload's first ``nbytes``, counting the copies."""

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.asked: list[int] = []

    def __call__(self, nbytes: int) -> bytes:
        self.asked.append(nbytes)
        return bytes(self.data[:nbytes])


def grab(
    payload: Payload, pixel_format: str = "BayerRG8", width_px: int = 4, height_px: int = 2, failure: str | None = None
) -> Grab:
    return Grab(
        failure=failure,
        frame_id=7,
        pixel_format=pixel_format,
        width_px=width_px,
        height_px=height_px,
        device_timestamp_ns=0,
        host_timestamp_ns=0,
        pixels=payload,
    )


def test_a_bayer_payload_is_rows_of_one_byte_per_pixel() -> None:
    payload = Payload(bytes(range(1, 9)))  # 4 x 2: row 0 is 1 2 3 4, row 1 is 5 6 7 8
    image = decode_grab(grab(payload), "BayerRG8", 4, 2)
    assert isinstance(image, np.ndarray)
    assert image.dtype == np.uint8 and image.shape == (2, 4)
    assert image.tolist() == [[1, 2, 3, 4], [5, 6, 7, 8]]
    assert payload.asked == [8]  # the one copy, of the image's bytes only


def test_rgb8_and_bgr8_payloads_are_byte_triplets_in_their_order() -> None:
    # Two pixels by one row: (R, G, B) = (10, 20, 30), then (40, 50, 60).
    rgb = decode_grab(grab(Payload(bytes([10, 20, 30, 40, 50, 60])), "RGB8", 2, 1), "RGB8", 2, 1)
    bgr = decode_grab(grab(Payload(bytes([30, 20, 10, 60, 50, 40])), "BGR8", 2, 1), "BGR8", 2, 1)
    assert isinstance(rgb, np.ndarray) and isinstance(bgr, np.ndarray)
    assert rgb.shape == bgr.shape == (1, 2, 3)
    assert rgb.tolist() == [[[10, 20, 30], [40, 50, 60]]]
    assert to_rgb(bgr, "BGR8").tolist() == rgb.tolist()


def test_a_rendered_mosaic_sent_as_bytes_comes_back_pixel_for_pixel() -> None:
    rng = np.random.default_rng(16)
    scene = rng.integers(0, 256, (6, 8, 3), dtype=np.uint8)
    mosaic = from_rgb(scene, "BayerGB8")
    image = decode_grab(grab(Payload(mosaic.tobytes()), "BayerGB8", 8, 6), "BayerGB8", 8, 6)
    assert isinstance(image, np.ndarray)
    np.testing.assert_array_equal(image, mosaic)
    # Green at (0, 0) of a GB pattern, blue at (0, 1), red at (1, 0).
    assert (image[0, 0], image[0, 1], image[1, 0]) == (scene[0, 0, 1], scene[0, 1, 2], scene[1, 0, 0])


def test_the_image_is_read_only_and_a_view_of_the_copied_payload() -> None:
    copied = np.arange(12, dtype=np.uint8).reshape(4, 3)  # a GenTL backend hands over an array copy
    image = image_from_payload(copied, "RGB8", 2, 2)
    assert image is not None and np.shares_memory(image, copied)
    assert image[1, 0].tolist() == [6, 7, 8]
    with pytest.raises(ValueError, match="read-only"):
        image[0, 0, 0] = 1


def test_bytes_past_the_image_are_ignored() -> None:
    image = image_from_payload(bytes(range(10)), "Mono8", 3, 3)
    assert image is not None and image.tolist() == [[0, 1, 2], [3, 4, 5], [6, 7, 8]]


@pytest.mark.parametrize(
    "as_backend_hands_it",
    [bytes, bytearray, memoryview, lambda data: np.frombuffer(data, np.uint8)],
    ids=["aravis-bytes", "pylon-bytearray", "memoryview", "gentl-array"],
)
def test_every_backends_kind_of_payload_reads_the_same(as_backend_hands_it) -> None:
    image = image_from_payload(as_backend_hands_it(bytes(range(10))), "Mono8", 3, 3)
    assert image is not None and image.tolist() == [[0, 1, 2], [3, 4, 5], [6, 7, 8]]
    assert image_from_payload(as_backend_hands_it(bytes(8)), "Mono8", 3, 3) is None


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        (dict(failure="missing-packets"), "missing-packets"),
        (dict(pixel_format="BayerGR8"), "wrong-format"),
        (dict(width_px=2, height_px=4), "wrong-size"),  # the same byte count, another shape
    ],
)
def test_a_buffer_that_is_not_the_configured_frame_is_counted_and_never_copied(case, expected) -> None:
    payload = Payload(bytes(8))
    assert decode_grab(grab(payload, **case), "BayerRG8", 4, 2) == expected
    assert payload.asked == []


def test_a_payload_shorter_than_its_announced_size_is_the_wrong_size() -> None:
    payload = Payload(bytes(7))  # 4 x 2 announced, a byte short
    assert decode_grab(grab(payload), "BayerRG8", 4, 2) == "wrong-size"
    assert image_from_payload(bytes(7), "BayerRG8", 4, 2) is None
