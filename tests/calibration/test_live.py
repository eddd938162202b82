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
from trackerd.calibration.pointer_sessions import Steadiness, WallSession
from trackerd.calibration.views import ViewSelector
from trackerd.calibration.wall import fit_wall
from trackerd.locator import Locator
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


def test_wall_session_captures_each_target_when_the_pointer_is_held_still(
    pointing_frames: FrameSet, simulated_rig, renderer
) -> None:
    from trackerd.bench.calibration import wall_targets

    wall = renderer.wall
    targets = {t.label: t for t in wall_targets(wall.width_m, wall.height_m)}
    plan = ["br", "tr", "centre"]  # targets whose rendered frames the detector gets right
    steadiness = Steadiness(frames=3, tolerance_m=0.002)
    pairs = []
    for label in plan:
        for place in (1, 2):
            frames = [pointing_frames.frame(f"{label}-{place}", c) for c in IDS]
            pairs += [frames] * 4  # held still for four frames
    session = WallSession(
        Locator(simulated_rig), [targets[label] for label in plan], "point", places=2, steadiness=steadiness
    )
    assert session.prompt() == "aim at 'br' from place 1 of 2 and hold still"
    lines: list[str] = []
    with source_of(pairs) as source:
        run_session(source, session, IDS, say=lines.append, newest=False)
    captured = [line for line in lines if "captured" in line]
    assert len(captured) == len(session.pointings) == 6 and session.done
    assert captured[0].startswith("[ 1/6] captured 'br'")
    assert "next: aim at 'br' from place 2 of 2 (move to a new place first)" in captured[0]
    assert captured[-1].endswith("next: all targets done")
    # Three targets from two places each are enough for a first wall.
    fit = fit_wall([], session.pointings, (wall.width_m, wall.height_m), 0.02, fit_size=False)
    assert np.degrees(np.arccos(fit.rotation[:, 2] @ wall.normal)) < 1.0


def _misses_mm(session: WallSession, wall) -> dict[str, float]:
    """How far each captured pointing's line passes from the true place of the target it was filed under."""
    out = {}
    for k, p in enumerate(session.pointings):
        rel = wall.from_wall_m(p.target.wall_xy_m) - p.tip_m
        out[f"{k}:{p.target.label}"] = float(np.linalg.norm(rel - (rel @ p.direction) * p.direction)) * 1000
    return out


def test_wall_session_retries_a_target_it_cannot_locate_and_never_files_a_capture_under_another(
    pointing_frames: FrameSet, stereo_frames: FrameSet, simulated_rig, renderer
) -> None:
    """Frames without the pointer (the board scenes) keep the session on the same target; the
    pointer still held where the last capture was is not captured again for the next target;
    a target never located is skipped after skip_after frames, and named as skipped."""
    from trackerd.bench.calibration import wall_targets

    wall = renderer.wall
    targets = {t.label: t for t in wall_targets(wall.width_m, wall.height_m)}
    nothing = [stereo_frames.frame(stereo_frames.names()[0], c) for c in IDS]  # no pointer in view

    def held(label: str, place: int, frames: int = 4) -> list:
        return [[pointing_frames.frame(f"{label}-{place}", c) for c in IDS]] * frames

    pairs = (
        [nothing] * 6  # br asked for, the pointer not in view yet
        + held("br", 1)  # captured on the third frame held still
        + held("br", 1, 5)  # still held there after the capture: not br from place 2
        + [nothing]
        + held("br", 2)
        + [nothing] * 25  # tr is never located: both its places skipped after 12 frames each
        + held("centre", 1)
        + held("centre", 2)
    )
    session = WallSession(
        Locator(simulated_rig),
        [targets[label] for label in ("br", "tr", "centre")],
        "point",
        places=2,
        steadiness=Steadiness(frames=3, tolerance_m=0.002),
        skip_after=12,
    )
    lines: list[str] = []
    with source_of(pairs) as source:
        run_session(source, session, IDS, say=lines.append, newest=False)
    text = "\n".join(lines)
    captured = [line for line in lines if "captured" in line]
    assert [line.split("'")[1] for line in captured] == ["br", "br", "centre", "centre"], text
    assert lines[0].startswith("  'br': pointer not located ("), text
    assert "  still where the last capture was: aim at 'br' from place 2 of 2" in text
    assert session.skipped == ["tr from place 1", "tr from place 2"], text
    assert "  skipped 'tr from place 1': no capture in 12 frames (the pointer was located in 1 of them;" in text
    assert session.done
    # Every capture is filed under the target it was aimed at: its line passes within millimetres of it.
    misses = _misses_mm(session, wall)
    assert max(misses.values()) < 10.0, misses


def test_steadiness_waits_for_the_pointer_to_stop() -> None:
    steady = Steadiness(frames=3, tolerance_m=0.002)
    front, back = np.zeros(3), np.array([0.0, 0.0, 0.45])
    assert steady.add(front, back) is None
    assert steady.add(front + np.array([0.01, 0.0, 0.0]), back) is None  # still moving
    assert steady.add(front, back) is None
    assert steady.add(front, back) is None
    got = steady.add(front, back)
    assert got is not None and np.allclose(got[0], front)


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
