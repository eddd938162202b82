"""`trackerd calibrate`: camera intrinsics, stereo extrinsics, the wall, and a health check.

The steps of docs/calibration.md, each writing its result into the rig's
calibration file (with a timestamped backup of the previous one) only when it
succeeded, and each printing the figures that say how far to trust it:

  trackerd calibrate intrinsics --config RIG --camera ID --board SPEC (IMAGE... | --live | --recording R)
  trackerd calibrate stereo     --config RIG --board SPEC (--pairs DIR | --live | --recording R)
  trackerd calibrate wall       --config RIG --points FILE
  trackerd calibrate wall       --config RIG (--touch | --point) (--pairs DIR | --live | --recording R)
  trackerd calibrate pointer    --config RIG (--pairs DIR | --live | --recording R)
  trackerd calibrate check      --config RIG (--pairs DIR | --live | --recording R)

Boards: chessboard:COLSxROWS:SQUARE_MM or charuco:COLSxROWS:SQUARE_MM:MARKER_MM[:DICT],
counting squares (chessboard:10x7:60 has 9 x 6 inner corners).
"""

from __future__ import annotations

import argparse

from trackerd.calibration.board import BoardSpec
from trackerd.calibration.detection import MAX_SHARPNESS_PX
from trackerd.calibration.intrinsics import DISTORTION_TERMS, MIN_VIEWS, MIN_VIEWS_FLOOR
from trackerd.calibration.pointer_sessions import SKIP_AFTER_FRAMES
from trackerd.calibration.stereo import MIN_PAIRS, MIN_PAIRS_FLOOR
from trackerd.calibration.views import MIN_VIEW_CHANGE
from trackerd.calibration.wall import DEFAULT_MAX_RMS_MM
from trackerd.cli._args import positive_int, positive_seconds
from trackerd.cli.calibrate.check import check_command
from trackerd.cli.calibrate.intrinsics import intrinsics_command
from trackerd.cli.calibrate.pointer import pointer_command
from trackerd.cli.calibrate.stereo import stereo_command
from trackerd.cli.calibrate.wall import wall_command


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "calibrate",
        help="calibrate cameras, the stereo pair and the wall; check a calibration",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    steps = parser.add_subparsers(dest="calibrate_command", metavar="STEP", required=True)

    p = steps.add_parser(
        "intrinsics",
        help="one camera's lens from views of a board",
        description="Calibrate one camera's focal length, principal point and distortion.",
    )
    _common(p)
    p.add_argument("--camera", required=True, help="camera id, as in the rig file")
    p.add_argument("--board", required=True, type=_board, help="chessboard:10x7:60 or charuco:10x7:60:45[:5X5_100]")
    p.add_argument("images", nargs="*", metavar="IMAGE", help="images of the board from this camera")
    _sources(p)
    p.add_argument("--views", type=int, default=20, help="views to collect in --live mode (default 20)")
    p.add_argument(
        "--min-views",
        type=int,
        default=MIN_VIEWS,
        help=f"fewest views to calibrate from (default {MIN_VIEWS}; under {MIN_VIEWS_FLOOR} only with --force)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help=f"calibrate from fewer than {MIN_VIEWS_FLOOR} views (the result is written with a warning)",
    )
    _report(p)
    p.add_argument(
        "--distortion",
        type=int,
        choices=DISTORTION_TERMS,
        default=None,
        help="distortion coefficients: 4 (k1 k2 p1 p2), 5 (and k3), 8 (rational); default 5, or 4 where k3"
        " would make the lens fold over near the image's edge while lowering the RMS by under 5 %%",
    )
    p.add_argument("--drop-outliers", action="store_true", help="drop views whose error stands out, and recalibrate")
    _quality(p)
    p.set_defaults(handler=intrinsics_command)

    p = steps.add_parser(
        "stereo",
        help="camera 2's pose relative to camera 1 from synchronized pairs",
        description="Calibrate the stereo pair (the rig's first two cameras).",
    )
    _common(p)
    p.add_argument("--board", required=True, type=_board, help="chessboard:10x7:100 or charuco:10x7:100:75[:DICT]")
    p.add_argument(
        "--pairs",
        metavar="DIR",
        help="folder of pairs: <name>-<camera>.<ext>, <camera><name>.<ext>, or a subfolder per camera",
    )
    _sources(p)
    p.add_argument("--views", type=int, default=15, help="pairs to collect in --live mode (default 15)")
    p.add_argument(
        "--min-pairs",
        type=int,
        default=MIN_PAIRS,
        help=f"fewest pairs (default {MIN_PAIRS}; at least {MIN_PAIRS_FLOOR}, which telling a pair out of sync needs)",
    )
    _report(p)
    p.add_argument(
        "--refine-intrinsics",
        action="store_true",
        help="let the stereo solve adjust both cameras' intrinsics (default: keep them fixed)",
    )
    p.add_argument(
        "--world",
        choices=("keep", "camera1"),
        default="keep",
        help="keep: camera 1 stays where the rig has it, so the rig's frame is kept (default);"
        " camera1: the world becomes camera 1's frame, as in the report",
    )
    p.add_argument(
        "--max-skew-ms",
        type=float,
        default=2.0,
        help="--live: pairs whose frames are further apart in time are out of sync (default 2)",
    )
    _quality(p)
    p.set_defaults(handler=stereo_command)

    p = steps.add_parser(
        "wall",
        help="the wall plane and frame: measured points, touches or pointing",
        description="Calibrate the wall and re-express the cameras in its frame.",
    )
    _common(p)
    method = p.add_mutually_exclusive_group(required=True)
    method.add_argument(
        "--points",
        metavar="FILE",
        help="a TOML file with a [wall] table measured in the cameras' frame (the report's way)",
    )
    method.add_argument("--touch", action="store_true", help="touch targets on the wall with the pointer's tip")
    method.add_argument("--point", action="store_true", help="aim the pointer at targets from several places")
    p.add_argument("--pairs", metavar="DIR", help="folder of images named <target>[-<n>]-<camera>.<ext>")
    _sources(p)
    p.add_argument("--targets", metavar="FILE", help="TOML [targets] table adding marks to the default targets")
    p.add_argument(
        "--use", metavar="LABELS", help="--live: comma-separated targets to visit (default bl,br,tr,tl,centre)"
    )
    p.add_argument(
        "--places", type=int, default=2, help="--point --live: places to aim at each target from (default 2)"
    )
    p.add_argument(
        "--fixed-size", action="store_true", help="keep the configured display size instead of solving for it"
    )
    p.add_argument(
        "--max-rms-mm",
        type=float,
        default=DEFAULT_MAX_RMS_MM,
        help=f"refuse to write a wall whose RMS residual exceeds this (mm, default {DEFAULT_MAX_RMS_MM:g};"
        " a good fit gives a few mm)",
    )
    p.add_argument(
        "--skip-after",
        type=int,
        default=SKIP_AFTER_FRAMES,
        metavar="FRAMES",
        help=f"--live: skip a target (and say so) after this many frames on it without a capture"
        f" (default {SKIP_AFTER_FRAMES}, about 20 s; 0: never)",
    )
    p.set_defaults(handler=wall_command)

    p = steps.add_parser(
        "pointer",
        help="the pointer's colours in this room, and the detector's thresholds from them",
        description="Learn the ends' colours, and the margin to everything else the cameras see, from the"
        " pointer waved in view; the thresholds go into the calibration file ([pointer_colours]), and"
        " [detector.red] / [detector.blue] in the rig file stay overrides.",
    )
    _common(p, snapshots=False)
    p.add_argument("--pairs", metavar="DIR", help="folder of pointer images named <name>-<camera>.<ext>")
    _sources(p, snapshots=False)
    p.add_argument(
        "--frames",
        type=positive_int,
        default=None,
        help="--live: pairs with the pointer located to learn from (default 60)",
    )
    p.set_defaults(handler=pointer_command)

    p = steps.add_parser(
        "check",
        help="ray gaps and reprojection errors of the waved pointer",
        description="Check a calibration: wave the pointer around in view of both cameras.",
    )
    p.add_argument("--config", required=True, help="rig TOML file")
    p.add_argument("--pairs", metavar="DIR", help="folder of pointer images named <name>-<camera>.<ext>")
    _sources(p, snapshots=False)
    p.add_argument("--fixes", type=int, default=300, help="--live: fixes to collect (default 300)")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    p.set_defaults(handler=check_command)


def _board(text: str) -> BoardSpec:
    try:
        return BoardSpec.parse(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from err


def _report(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--report",
        metavar="DIR",
        help="write pictures of the result (views with residuals, coverage, per-view RMS; for stereo a"
        " rectified pair) and an index.html into DIR, also with --dry-run",
    )


def _common(p: argparse.ArgumentParser, snapshots: bool = True) -> None:
    p.add_argument("--config", required=True, help="rig TOML file")
    p.add_argument("--output", metavar="FILE", help="calibration file to update (default: the one the rig names)")
    p.add_argument(
        "--dry-run",
        action="store_true",
        help="report, but write nothing: no calibration file"
        + (", and no snapshots unless --snapshots DIR is given" if snapshots else ""),
    )
    p.add_argument("--json", action="store_true", help="print the result as one JSON object (progress on stderr)")


def _sources(p: argparse.ArgumentParser, snapshots: bool = True) -> None:
    p.add_argument(
        "--live", action="store_true", help="use the rig's cameras (the daemon's source) and guide the operator"
    )
    p.add_argument(
        "--recording", metavar="R", help="read the pairs of a recording (trackerd record), as --live reads the cameras"
    )
    p.add_argument(
        "--source",
        choices=("cameras", "simulated"),
        default="cameras",
        help="--live: the rig's cameras (default), or frames the simulator renders from the rig's"
        " own (inline) geometry, to try the procedure without cameras",
    )
    p.add_argument("--duration", type=positive_seconds, help="--live: stop after this many seconds")
    if snapshots:
        p.add_argument(
            "--snapshots",
            metavar="DIR",
            help="--live: save accepted frames here (default calibration-snapshots/<step>-<time>)",
        )


def _quality(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--max-blur",
        type=float,
        default=MAX_SHARPNESS_PX,
        help=f"reject views whose edges rise over more pixels (default {MAX_SHARPNESS_PX})",
    )
    p.add_argument(
        "--min-change",
        type=float,
        default=None,
        help=f"reject views whose corners moved less than this fraction of the image diagonal"
        f" from an accepted view (default {MIN_VIEW_CHANGE} live, where the board is held still between"
        " views; 0 for image files, which were chosen)",
    )
    p.add_argument(
        "--max-rms",
        type=float,
        default=1.0,
        help="refuse to write a result whose RMS reprojection error exceeds this (px, default 1.0)",
    )
