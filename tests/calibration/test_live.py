"""The --live sessions on a PairSource: progress, guidance, snapshots, and the sources' failures.

The source here is :class:`trackerd.sim.board.RenderedPairSource` serving rendered
frames (the cached sets of conftest.py); the CLI gives the same sessions the
daemon's Aravis source. The virtual rig serves pointer scenes only, so board
frames come this way.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
from calibration_frames import INTRINSICS_BOARD, STEREO_BOARD, FrameSet

from trackerd.calibration import CalibrationError
from trackerd.calibration.board import grey_for_calibration
from trackerd.calibration.collect import collect_views
from trackerd.calibration.inputs import camera_frames
from trackerd.calibration.live import IntrinsicsSession, StereoSession, run_session
from trackerd.calibration.views import ViewSelector
from trackerd.sim.board import RenderedPairSource

IDS = ["left", "right"]
FORMATS = ["BayerRG8", "BayerRG8"]


def source_of(pairs: list[list[np.ndarray]], **kwargs) -> RenderedPairSource:
    return RenderedPairSource(IDS, FORMATS, lambda k: pairs[k], len(pairs), **kwargs)


def test_intrinsics_session_guides_accepts_and_saves_snapshots(
    intrinsics_frames: FrameSet, pointer_frames: FrameSet, simulated_rig, tmp_path: Path
) -> None:
    names = [n for n in intrinsics_frames.names() if n.startswith("left-")]
    empty = pointer_frames.frame(pointer_frames.names()[0], "right")
    pairs = []
    for k, name in enumerate(names):
        view = intrinsics_frames.frame(name, "left")
        pairs.append([view, empty])
        if k == 2:
            pairs.append([view, empty])  # held still: the same view again
            pairs.append([pointer_frames.frame(pointer_frames.names()[0], "left"), empty])  # board out of view
    cam = simulated_rig.cameras[0]
    session = IntrinsicsSession(
        INTRINSICS_BOARD,
        0,
        "left",
        cam.width_px,
        cam.height_px,
        wanted_views=len(names),
        snapshots=tmp_path / "snapshots",
    )
    lines: list[str] = []
    with source_of(pairs) as source:
        fed = run_session(source, session, IDS, say=lines.append, newest=False)
    assert fed == len(pairs)
    assert len(session.views) == len(names)
    accepted = [line for line in lines if "accepted" in line]
    assert accepted[0].startswith(f"[  1/{len(names)} views] accepted left-001: 54 corners, coverage")
    assert "; next: cover the" in accepted[0]
    assert ", RMS 0.0" in accepted[-1]  # a running RMS once enough views are in
    # One numbering: frame 4 (the third view again) is named left-004, and the view it repeats
    # is named as its snapshot is saved, so the message can be traced to the image.
    assert any(line.startswith("  left-004: too similar to 'left-003' (") for line in lines), lines
    assert "  left-005: no whole board found by any detector" in lines
    assert accepted[-1].startswith(f"[ {len(names)}/{len(names)} views] accepted left-{len(pairs):03d}: ")
    assert session.done
    # The snapshots are the accepted frames, under the names the report lists them by.
    snapshots = sorted((tmp_path / "snapshots").glob("left-*.png"))
    assert tuple(p.stem for p in snapshots) == session.result().view_names == tuple(v.name for v in session.views)
    assert (tmp_path / "snapshots" / "left-003.png").exists() and not (tmp_path / "snapshots" / "left-004.png").exists()
    # Calibrating from them offline gives the same views.
    assert len(snapshots) == len(names)
    again = collect_views(camera_frames(snapshots, cam), INTRINSICS_BOARD, ViewSelector(cam.width_px, cam.height_px))
    assert len(again.views) == len(names)
    assert np.allclose(again.views[0].image_points_px, session.views[0].image_points_px)
    assert session.result().rms_px < 0.15


def test_stereo_session_refuses_pairs_too_far_apart_in_time(
    stereo_frames: FrameSet, simulated_rig, tmp_path: Path
) -> None:
    pairs = [[stereo_frames.frame(n, c) for c in IDS] for n in stereo_frames.names()[:3]]
    cam = simulated_rig.cameras[0]
    session = StereoSession(
        STEREO_BOARD, ("left", "right"), cam.width_px, cam.height_px, wanted_pairs=3, max_skew_ns=2_000_000
    )
    lines: list[str] = []
    with source_of(pairs, skew_ns=5_000_000) as source:
        run_session(source, session, IDS, say=lines.append, newest=False)
    assert session.pairs == []
    assert lines[0] == "  001: out of sync: the two frames are 5.0 ms apart (limit 2.0 ms)"
    assert lines[-1] == "the source has no more frames"
    # In sync, with the first pair shown twice (held still): one numbering for messages, pairs and snapshots.
    session = StereoSession(
        STEREO_BOARD, ("left", "right"), cam.width_px, cam.height_px, wanted_pairs=3, snapshots=tmp_path
    )
    lines = []
    with source_of([pairs[0], *pairs], skew_ns=300_000) as source:
        run_session(source, session, IDS, say=lines.append, newest=False)
    assert len(session.pairs) == 3 and session.done
    assert [p.name for p in session.pairs] == ["001", "003", "004"]
    assert lines[0].startswith("[  1/3 pairs] accepted 001: ")
    assert lines[1].startswith("  002: too similar to '001-left' (")
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [
        f"{n}-{c}.png" for n in ("001", "003", "004") for c in IDS
    ]


class _Silent(RenderedPairSource):
    """A source that starts but never delivers (the cameras stream nothing)."""

    def next_pair(self, timeout_s: float):
        return None


def test_a_source_that_delivers_nothing_is_a_clear_error(simulated_rig) -> None:
    cam = simulated_rig.cameras[0]
    session = IntrinsicsSession(INTRINSICS_BOARD, 0, "left", cam.width_px, cam.height_px)
    stopped = _Silent(IDS, FORMATS, lambda k: [], 0)
    with pytest.raises(CalibrationError, match="the cameras delivered no frames"):
        run_session(stopped, session, IDS, say=print, poll_s=0.01)
    # A stop request ends the session at once.
    stop = threading.Event()
    stop.set()
    with _Silent(IDS, FORMATS, lambda k: [], 0) as running:
        assert run_session(running, session, IDS, say=print, stop=stop) == 0


def test_grey_image_of_a_snapshot_round_trip(intrinsics_frames: FrameSet, tmp_path: Path) -> None:
    from trackerd.calibration.live import save_frame
    from trackerd.images import read_frame

    name = intrinsics_frames.names()[0]
    frame = intrinsics_frames.frame(name, "left")
    cam_cfg = (
        __import__("trackerd.config.loader", fromlist=["load_rig"])
        .load_rig(Path(__file__).resolve().parents[2] / "config" / "simulated.toml")
        .config.cameras[0]
    )
    path = save_frame(tmp_path, "snap", frame, "BayerRG8")
    back, fmt = read_frame(path, cam_cfg)
    assert fmt == "BayerRG8" and np.array_equal(back, frame)
    assert grey_for_calibration(back, fmt).shape == frame.shape
