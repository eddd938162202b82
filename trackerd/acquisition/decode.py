"""From a finished buffer to a frame's image, or the reason it is none (a failure cause to count).

A buffer becomes an image only if the backend calls it complete and it has the
pixel format and size the camera was configured for: a camera that was
reconfigured behind trackerd's back, or a payload cut short, must not reach
the detector as a frame of the wrong shape. The payload is copied once (the
frame's own pixels, docs/acquisition.md "Buffer ownership") and only once
those checks pass.
"""

from __future__ import annotations

from trackerd.acquisition.session import Grab
from trackerd.pixelformat import Image, frame_nbytes, image_from_payload


def decode_grab(grab: Grab, pixel_format: str, width_px: int, height_px: int) -> Image | str:
    """The read-only image of ``grab`` if it is a complete ``pixel_format`` frame of ``width_px`` x
    ``height_px``, else the failure cause: the backend's (``missing-packets``, ...), ``wrong-format``
    or ``wrong-size`` (the size announced, or a payload shorter than it)."""
    if grab.failure is not None:
        return grab.failure
    if grab.pixel_format != pixel_format:
        return "wrong-format"
    if (grab.width_px, grab.height_px) != (width_px, height_px):
        return "wrong-size"
    image = image_from_payload(
        grab.pixels(frame_nbytes(pixel_format, width_px, height_px)), pixel_format, width_px, height_px
    )
    return "wrong-size" if image is None else image
