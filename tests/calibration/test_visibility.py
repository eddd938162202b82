"""Which wall targets both simulated DataWall cameras see: only a strip of the display, not its corners."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from trackerd.calibration.inputs import default_targets
from trackerd.calibration.visibility import common_view_rectangle, touch_seen, view_targets
from trackerd.config.loader import load_rig
from trackerd.config.rig_geometry import camera_model, wall_frame

CONFIG = Path(__file__).resolve().parents[2] / "config"


def _rig(name: str):
    rig = load_rig(CONFIG / name).config
    return [camera_model(c) for c in rig.cameras], wall_frame(rig.wall), rig.pointer


def test_the_display_corners_are_each_seen_by_one_camera_only() -> None:
    cameras, wall, pointer = _rig("simulated.toml")
    targets = default_targets(wall.width_m, wall.height_m)
    labels = ["bl", "br", "tr", "tl", "centre"]
    seen = touch_seen(cameras, wall, np.array([targets[k].wall_xy_m for k in labels]), pointer.end_diameter_m / 2)
    # Left is at x = -1.3 m looking across to the right half, right the other way round.
    assert seen.tolist() == [[False, True], [True, False], [True, False], [False, True], [True, True]]


def test_the_common_view_rectangle_lies_in_the_strip_both_see_and_its_targets_are_seen() -> None:
    for name in ("simulated.toml", "datawall.toml"):
        cameras, wall, pointer = _rig(name)
        rectangle = common_view_rectangle(cameras, wall, pointer.end_diameter_m / 2)
        assert rectangle is not None
        x0, y0, x1, y1 = rectangle
        # docs/calibration.md: both cameras see the wall only at x from about 1.5 to 2.2 m.
        assert 1.4 < x0 < 1.6 and 2.1 < x1 < 2.3 and y0 >= 0.05 and y1 <= wall.height_m - 0.05
        assert y1 - y0 > 0.5
        targets = view_targets(rectangle)
        assert list(targets) == ["view-bl", "view-br", "view-tr", "view-tl", "view-centre"]
        xy = np.array([t.wall_xy_m for t in targets.values()])
        assert touch_seen(cameras, wall, xy, pointer.end_diameter_m / 2).all()
        # Just outside the rectangle's sides (beyond its inset) a camera loses the tip.
        outside = np.array([[x0 - 0.15, (y0 + y1) / 2], [x1 + 0.15, (y0 + y1) / 2]])
        assert not touch_seen(cameras, wall, outside, pointer.end_diameter_m / 2).all(axis=1).any()
