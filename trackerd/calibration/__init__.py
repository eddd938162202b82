"""Calibration: camera intrinsics, stereo extrinsics, the wall, and the health of the result.

The report assumed its geometry "known or estimated using a camera calibration
technique" (section 3.1) and measured the wall's three points by hand (section
3.7). This package does both from the command line, with error figures:

* board.py       calibration boards (chessboard, ChArUco): definition, detection, quality
* views.py       which views to keep: similarity, coverage of the image, guidance
* collect.py     frames in, accepted views or matched pairs out, every rejection with its reason
* intrinsics.py  one camera's lens (cv2.calibrateCamera) with per-view errors and outliers
* stereo.py      camera 2 relative to camera 1 (cv2.stereoCalibrate), baseline, epipolar error, sync
* wall.py        the wall plane and frame: pointer-tip touches and pointing, robust least squares
* visibility.py  which wall targets both cameras see, for touching
* health.py      ray gaps and reprojection errors of tracked pointers: drift detection
* update.py      results into calibration-file entries; the world frame
* store.py       reading the rig leniently, writing the calibration file atomically with a backup
* inputs.py      image files, folders of pairs, wall targets and measured walls
* report.py      results as text and JSON
* live.py        the --live modes on a PairSource, with progress and guidance as text

Everything except live.py, store.py and inputs.py is pure: NumPy arrays in, dataclasses out.
The steps and the figures to expect are in docs/calibration.md.
"""

from trackerd.errors import CalibrationError

__all__ = ["CalibrationError"]
