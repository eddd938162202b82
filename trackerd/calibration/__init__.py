"""Calibration: camera intrinsics, stereo extrinsics, the wall, and the health of the result.

The report assumed its geometry "known or estimated using a camera calibration
technique" (section 3.1) and measured the wall's three points by hand (section
3.7). This package does both from the command line, with error figures:

* board.py       calibration boards (chessboard, ChArUco): definition, detection, quality
* views.py       which views to keep: similarity, coverage of the image, guidance
* intrinsics.py  one camera's lens (cv2.calibrateCamera) with per-view errors and outliers
* stereo.py      camera 2 relative to camera 1 (cv2.stereoCalibrate), baseline, epipolar error
* wall.py        the wall plane and frame: measured points, pointer-tip touches, pointing
* health.py      ray gaps and reprojection errors of tracked pointers: drift detection
* store.py       reading the rig leniently, writing the calibration file atomically with a backup
* tomlwrite.py   a small TOML emitter for the calibration file's simple structure
* live.py        the --live modes on a PairSource, with progress and guidance as text

Everything except live.py and store.py is pure: NumPy arrays in, dataclasses out.
"""

from trackerd.errors import TrackerdError


class CalibrationError(TrackerdError):
    """Calibration input that cannot give a result: no board found, too few views, pairs out of sync."""
