"""Rendered calibration input for the calibration tests: what is rendered, and the on-disk cache.

Every frame is rendered by the simulator through the true lenses of
config/simulated.toml (trackerd/sim/board.py for boards, trackerd/sim/render.py
for the pointer), with sensor noise. Rendering the set takes about half a
minute, so the frames are kept as PNG files under the repository's
.cache/calibration/, in a folder named by a hash of everything that shapes them
(the renderer's sources, the rig file, the poses' parameters); a change to any
of these renders them again.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from trackerd.calibration.board import BoardSpec

REPO = Path(__file__).resolve().parents[2]
CACHE = REPO / ".cache" / "calibration"

INTRINSICS_BOARD = BoardSpec.parse("chessboard:10x7:60")
STEREO_BOARD = BoardSpec.parse("chessboard:10x7:100")
INTRINSICS_VIEWS = 14
STEREO_PAIRS = 10
POINTING_PLACES = 2
CHECK_POSES = 12
PSF_PX = 0.5


def _sources_digest(*extra: object) -> str:
    digest = hashlib.sha256()
    for name in (
        "trackerd/sim/board.py",
        "trackerd/sim/render.py",
        "trackerd/sim/scene.py",
        "trackerd/bench/calibration.py",
        "config/simulated.toml",
    ):
        digest.update((REPO / name).read_bytes())
    digest.update(repr(extra).encode())
    return digest.hexdigest()[:20]


@dataclass(frozen=True)
class FrameSet:
    """Rendered frames on disk: one folder, files named <name>-<camera>.png, plus truth.json."""

    folder: Path
    truth: dict

    def frame(self, name: str, camera_id: str) -> np.ndarray:
        image = cv2.imread(str(self.folder / f"{name}-{camera_id}.png"), cv2.IMREAD_UNCHANGED)
        assert image is not None, f"{name}-{camera_id}.png"
        return image

    def names(self) -> list[str]:
        return list(self.truth["names"])


def _cached(kind: str, key: str, build: Callable[[Path], dict]) -> FrameSet:
    folder = CACHE / f"{kind}-{key}"
    truth_path = folder / "truth.json"
    if truth_path.exists():
        return FrameSet(folder, json.loads(truth_path.read_text()))
    # A work folder of this process's own: the suite's two workers may build the same set at once.
    CACHE.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f".{kind}-{key}.", dir=CACHE))
    try:
        truth = build(work)
        (work / "truth.json").write_text(json.dumps(truth))
        if folder.exists() and not truth_path.exists():
            shutil.rmtree(folder, ignore_errors=True)  # left incomplete by an older version
        try:
            work.rename(folder)
        except OSError:
            if not truth_path.exists():
                raise
            # Another process finished the same set first: theirs is as good.
            return FrameSet(folder, json.loads(truth_path.read_text()))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return FrameSet(folder, truth)


def _write(folder: Path, name: str, image: np.ndarray) -> None:
    assert cv2.imwrite(str(folder / f"{name}.png"), image)


def copy_set(
    frames: FrameSet, destination: Path, names: list[str] | None = None, rename: Callable[[str], str] | None = None
) -> Path:
    """Copy (some of) a frame set's PNG files into a folder for the CLI."""
    destination.mkdir(parents=True, exist_ok=True)
    wanted = set(names) if names is not None else None
    for path in frames.folder.glob("*.png"):
        stem = path.stem
        name = stem.rsplit("-", 1)[0]
        if wanted is not None and name not in wanted:
            continue
        target = rename(path.name) if rename else path.name
        shutil.copy(path, destination / target)
    return destination
