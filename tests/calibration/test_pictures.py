"""`--report DIR`: the pictures are written and show what they claim, on the real photos."""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np

from tests.calibration.test_cli import INTRINSICS, trackerd
from tests.calibration.test_cli_photos import BOARD, STEREO, photo_workspace
from trackerd.calibration.pictures import BAR_BGR, COVERED_BGR, DETECTED_BGR, OUTLIER_BGR, UNCOVERED_BGR


def test_report_pictures_show_the_views_coverage_rms_and_the_rectified_pair(tmp_path: Path) -> None:
    photo_workspace(tmp_path)
    run = trackerd(*INTRINSICS, "left", *BOARD, "photos", "--report", "report", "--json", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    report = tmp_path / "report"
    views = [Path(v["name"]).stem for v in result["views"]]
    assert {p.name for p in report.glob("left-view-*.png")} == {f"left-view-{v}.png" for v in views}

    # The coverage map's cells are filled exactly where the report says corners fell.
    image = cv2.imread(str(report / "left-coverage.png"))
    covered = [[c == "#" for c in row] for row in result["coverage"]["covered"]]
    rows, cols = len(covered), len(covered[0])
    h, w = image.shape[:2]
    for r in range(rows):
        for c in range(cols):
            # A cell's corner area, away from the white corner dots and the title band.
            y, x = round((r + 0.5) * h / rows) + round(0.3 * h / rows), round(c * w / cols) + 4
            want = COVERED_BGR if covered[r][c] else UNCOVERED_BGR
            assert tuple(int(v) for v in image[y, x]) == want, (r, c)

    # One bar per view, in view order.
    bars = cv2.imread(str(report / "left-rms.png"))
    row = bars[275]  # just above the axis
    is_bar = np.all(row == BAR_BGR, axis=1) | np.all(row == OUTLIER_BGR, axis=1)
    starts = np.flatnonzero(is_bar[1:] & ~is_bar[:-1])
    assert len(starts) == len(views)

    # Each view's picture circles the detected corners (drawn in the detected colour near them).
    first = cv2.imread(str(report / f"left-view-{views[0]}.png"))
    assert np.count_nonzero(np.all(first == DETECTED_BGR, axis=2)) > 54 * 10

    # Stereo adds the rectified pairs, and the index links every picture, all present.
    assert trackerd(*INTRINSICS, "right", *BOARD, "photos", cwd=tmp_path).returncode == 0
    run = trackerd(*STEREO, *BOARD, "--pairs", "photos", "--report", "report", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert len(list(report.glob("stereo-rectified-*.png"))) == 13
    linked = re.findall(r'<img src="([^"]+)"', (report / "index.html").read_text())
    assert sorted(linked) == sorted(p.name for p in report.glob("*.png"))
    assert "<h2>camera left</h2>" in (report / "index.html").read_text()
    assert "<h2>stereo left -&gt; right</h2>" in (report / "index.html").read_text()
