"""Text drawn on exported and snap images: one legible pass on a dark box, nothing drifting beside it."""

from __future__ import annotations

import numpy as np

from trackerd.recording.annotate import annotate

LINE = "hit: wall (3.288, 0.424) m, display (6903, 1030) px; red (981.89, 474.30) px, 243 px^2"


def test_the_text_lies_on_its_background_box_and_nothing_drifts_beside_it() -> None:
    grey = np.full((300, 1920), 128, np.uint8)
    image = annotate(grey, "Mono8", None, ["pair 0  seq 1  left", LINE])
    dark = np.all(image <= 40, axis=2)
    bright = np.all(image >= 200, axis=2)
    dark_rows, dark_cols = np.nonzero(dark)
    text_rows, text_cols = np.nonzero(bright)
    top, bottom, left, right = dark_rows.min(), dark_rows.max(), dark_cols.min(), dark_cols.max()
    # The white text is inside the dark box and spans it but for the padding: a black outline drawn
    # as a thicker pass of the same text ran ~70 px past the white text's end on a line this long
    # (a Hershey font advances further per character when thicker).
    assert top < text_rows.min() and text_rows.max() < bottom
    assert 0 < text_cols.min() - left <= 10 and 0 < right - text_cols.max() <= 10
    # Nothing is drawn outside the box.
    outside = np.ones(dark.shape, bool)
    outside[top : bottom + 1, left : right + 1] = False
    assert np.all(image[outside] == 128)
    # The box is solid: its pixels are darkened or text (an antialiased text edge may pass through 128).
    assert np.mean(image[top : bottom + 1, left : right + 1] == 128) < 0.01
