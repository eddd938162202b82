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

import fcntl
import hashlib
import json
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO

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
    """The frame set ``kind`` rendered by ``build`` into a work folder, from the cache when there.

    The suite's two xdist workers often want the same set at once (on a fresh clone every calibration
    module starts by rendering): one renders it and the other waits for it, instead of both rendering it
    (up to a minute of a core each). While it waits, the waiting worker renders the sets no process has
    started yet (:data:`_PENDING`; tests/calibration/conftest.py registers them all), so that on a cold
    cache the two workers render different sets side by side and each set is rendered once.
    """
    _PENDING.setdefault(kind, (key, build))
    found = _in_cache(kind, key)
    if found is not None:
        return found
    CACHE.mkdir(parents=True, exist_ok=True)
    with open(CACHE / f".{kind}-{key}.lock", "w") as lock:
        if not _try_lock(lock):
            # Another worker renders this set: render the sets nobody has started meanwhile.
            for other, (other_key, other_build) in list(_PENDING.items()):
                if other != kind:
                    _build_unless_busy(other, other_key, other_build)
            fcntl.flock(lock, fcntl.LOCK_EX)
        return _build_locked(kind, key, build)


_PENDING: dict[str, tuple[str, Callable[[Path], dict]]] = {}
"""The sets this process knows, by kind (cache key and builder), from :func:`register` and
:func:`_cached`: what a worker waiting for another's set may render meanwhile."""


def register(kind: str, key: str, build: Callable[[Path], dict]) -> None:
    """Make a set known to this process before it is asked for (conftest registers every set)."""
    _PENDING.setdefault(kind, (key, build))


def _in_cache(kind: str, key: str) -> FrameSet | None:
    truth_path = CACHE / f"{kind}-{key}" / "truth.json"
    return FrameSet(truth_path.parent, json.loads(truth_path.read_text())) if truth_path.exists() else None


def _try_lock(lock: IO[str]) -> bool:
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


def _build_unless_busy(kind: str, key: str, build: Callable[[Path], dict]) -> None:
    """Render a set unless it is cached or another process is rendering it."""
    if _in_cache(kind, key) is not None:
        return
    with open(CACHE / f".{kind}-{key}.lock", "w") as lock:
        if _try_lock(lock):
            _build_locked(kind, key, build)


def _build_locked(kind: str, key: str, build: Callable[[Path], dict]) -> FrameSet:
    """Render a set into the cache; the caller holds its lock (so it may have been finished meanwhile)."""
    folder = CACHE / f"{kind}-{key}"
    truth_path = folder / "truth.json"
    found = _in_cache(kind, key)
    if found is not None:
        return found
    work = Path(tempfile.mkdtemp(prefix=f".{kind}-{key}.", dir=CACHE))
    try:
        truth = build(work)
        (work / "truth.json").write_text(json.dumps(truth))
        if folder.exists() and not truth_path.exists():
            shutil.rmtree(folder, ignore_errors=True)  # left incomplete by an older version
        work.rename(folder)
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
