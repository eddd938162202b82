"""A motion rendered once for every camera of a rig, as a loop the simulated cameras serve.

Rendering a 1920x1080 view takes 0.05-0.3 s in Python, far from 60 frames per
second, so a motion is rendered once as a loop of one period at
``content_fps`` loop frames per second (in worker processes, each started as
``python -m trackerd.sim.loops``) and cached on disk
(``~/.cache/trackerd/simrig/<hash of rig, motion, renderer>``, the four most
recently used loops kept).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import trackerd
from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import wall_frame
from trackerd.errors import TrackerdError
from trackerd.sim.backgrounds import user_cache_dir
from trackerd.sim.motion import DEFAULT_PERIOD_S, make_motion
from trackerd.sim.scene import scene_wall, true_wall_hit

LOOP_VERSION = 1
"""Bump when the loop format changes, so cached loops are not reused."""
KEEP_LOOPS = 4
"""Rendered loops kept in the cache; older ones are deleted when a new one is rendered."""
RENDERER_SOURCES = (
    "render.py",
    "backgrounds.py",
    "display.py",
    "lens_rays.py",
    "pointer_render.py",
    "pointer_shading.py",
    "raycast.py",
    "room_shading.py",
    "sensor.py",
    "appearance.py",
    "scene.py",
    "motion.py",
)
"""The modules of trackerd/sim a rendered loop depends on: their source is part of its cache key."""


def default_cache_dir() -> Path:
    """$TRACKERD_SIMRIG_CACHE, else $XDG_CACHE_HOME/trackerd/simrig, else ~/.cache/trackerd/simrig."""
    return user_cache_dir("TRACKERD_SIMRIG_CACHE", "simrig")


@dataclass(frozen=True)
class RenderedLoop:
    """A motion rendered for every camera of a rig, on disk."""

    directory: Path
    frame_paths: tuple[Path, ...]
    """Per camera: an (N, H, W) uint8 .npy file."""
    truth_path: Path
    """JSON: the motion, loop frame rate and per-frame truth."""
    n_frames: int
    content_fps: float
    rendered_s: float
    """Seconds spent rendering now (0.0 when the loop came from the cache)."""

    def truth(self) -> list[dict[str, Any]]:
        frames: list[dict[str, Any]] = json.loads(self.truth_path.read_text())["frames"]
        return frames


def loop_key(rig: RigConfig, motion: str, period_s: float, content_fps: float) -> str:
    """A hash of everything a rendered loop depends on, renderer source included."""
    digest = hashlib.sha256()
    # The console serves what is rendered and changes nothing in it (and keys made before it existed stay valid).
    digest.update(rig.model_dump_json(exclude={"console"}).encode())
    digest.update(f"{motion}|{period_s!r}|{content_fps!r}|{LOOP_VERSION}".encode())
    sim_dir = Path(__file__).parent
    for name in RENDERER_SOURCES:
        digest.update((sim_dir / name).read_bytes())
    return digest.hexdigest()[:20]


def loop_truth(rig: RigConfig, motion: str, period_s: float, content_fps: float) -> list[dict[str, Any]]:
    """Per loop frame: scene time, whether the pointer is there, its true ends and true wall hit."""
    moving = make_motion(motion, rig, period_s)
    wall = wall_frame(scene_wall(rig))
    n_frames = max(1, round(period_s * content_fps))
    frames = []
    for index in range(n_frames):
        time_s = index / content_fps
        pose = moving(time_s)
        record: dict[str, Any] = {
            "loop_index": index,
            "motion_time_s": time_s,
            "present": pose is not None,
        }
        if pose is not None:
            hit = true_wall_hit(pose, wall)
            record.update(
                front_m=pose.front_m.tolist(),
                back_m=pose.back_m.tolist(),
                wall_xy_m=None if hit.wall_xy_m is None else hit.wall_xy_m.tolist(),
                on_wall=hit.on_wall,
            )
        frames.append(record)
    return frames


def render_loop(
    rig: RigConfig,
    motion: str,
    *,
    period_s: float = DEFAULT_PERIOD_S,
    content_fps: float = 30.0,
    cache_dir: Path | None = None,
    processes: int | None = None,
) -> RenderedLoop:
    """The loop of ``motion`` for every camera of ``rig``, from the cache or rendered now.

    Rendering runs in ``processes`` worker processes (default: one per CPU), each
    started as ``python -m trackerd.sim.loops`` and writing its frames straight
    into the loop's memory-mapped files.
    """
    cache = (cache_dir or default_cache_dir()) / loop_key(rig, motion, period_s, content_fps)
    frame_paths = tuple(cache / f"cam{i}.npy" for i in range(len(rig.cameras)))
    truth_path = cache / "truth.json"
    n_frames = max(1, round(period_s * content_fps))
    if truth_path.exists() and all(p.exists() for p in frame_paths):
        os.utime(cache)  # most recently used: the last to be pruned
        return RenderedLoop(cache, frame_paths, truth_path, n_frames, content_fps, 0.0)
    for cam in rig.cameras:
        if cam.pixel_format not in ("BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8"):
            raise TrackerdError(
                f"camera '{cam.id}': the simulated camera serves 8-bit Bayer only, not {cam.pixel_format}"
            )
    started = time.monotonic()
    cache.parent.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=".partial-", dir=cache.parent))
    try:
        truth = loop_truth(rig, motion, period_s, content_fps)
        for i, cam in enumerate(rig.cameras):
            shape = (n_frames, cam.height_px, cam.width_px)
            np.lib.format.open_memmap(work / f"cam{i}.npy", mode="w+", dtype=np.uint8, shape=shape).flush()
        (work / "rig.json").write_text(rig.model_dump_json())
        n_jobs = n_frames * len(rig.cameras)
        workers = max(1, min(processes or os.cpu_count() or 1, n_jobs))
        procs = [
            subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "trackerd.sim.loops",
                    str(work),
                    motion,
                    repr(period_s),
                    repr(content_fps),
                    str(k),
                    str(workers),
                ],
                env=child_env(),
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                text=True,
            )
            for k in range(workers)
        ]
        try:
            errors = [p.communicate()[1] for p in procs]
        except BaseException:
            for p in procs:
                p.kill()
                p.wait()
            raise
        bad = [e.strip() for p, e in zip(procs, errors, strict=True) if p.returncode != 0]
        if bad:
            detail = bad[0].splitlines()[-1] if bad[0] else "a render worker failed"
            raise TrackerdError(f"rendering the '{motion}' loop failed: {detail}")
        for k in range(workers):
            for (camera_id, index), centres in json.loads((work / f"centres-{k}.json").read_text()):
                truth[index].setdefault("centroid_px", {})[camera_id] = centres
        meta = {"motion": motion, "period_s": period_s, "content_fps": content_fps, "frames": truth}
        (work / "truth.json").write_text(json.dumps(meta))
        os.rename(work, cache)
        prune_loops(cache.parent, keep=KEEP_LOOPS)
    except FileExistsError:
        pass  # another process finished the same loop first
    except OSError as err:
        if not (truth_path.exists() and all(p.exists() for p in frame_paths)):
            raise TrackerdError(f"cannot write the rendered loop under {cache.parent}: {err}") from err
    finally:
        if work.exists():
            shutil.rmtree(work, ignore_errors=True)
    return RenderedLoop(cache, frame_paths, truth_path, n_frames, content_fps, time.monotonic() - started)


def prune_loops(root: Path, keep: int) -> None:
    """Delete all but the ``keep`` most recently used loops under ``root`` (each is hundreds of MB)."""
    loops = sorted(
        (p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")),
        key=lambda p: p.stat().st_mtime,
        reverse=True,
    )
    for old in loops[keep:]:
        shutil.rmtree(old, ignore_errors=True)


def _render_worker(work: Path, motion: str, period_s: float, content_fps: float, k: int, workers: int) -> None:
    """Render every ``workers``-th (camera, frame) job from ``k`` into the loop files in ``work``."""
    from trackerd.sim.render import SceneRenderer

    rig = RigConfig.model_validate_json((work / "rig.json").read_text())
    renderer = SceneRenderer(rig)
    moving = make_motion(motion, rig, period_s)
    frames = [np.load(work / f"cam{i}.npy", mmap_mode="r+") for i in range(len(rig.cameras))]
    n_frames = frames[0].shape[0]
    centres = []
    jobs = [(index, camera) for index in range(n_frames) for camera in range(len(rig.cameras))]
    for index, camera in jobs[k::workers]:
        rng = np.random.default_rng([rig.simulation.seed, camera, index])
        view = renderer.render(camera, moving(index / content_fps), rng)
        frames[camera][index] = view.image
        centroid = {c: view.truth.centroid_px[c].tolist() for c in ("red", "blue")}
        centres.append(((rig.cameras[camera].id, index), centroid))
    for array in frames:
        array.flush()
    (work / f"centres-{k}.json").write_text(json.dumps(centres))


def child_env() -> dict[str, str]:
    """The environment for child processes, with this trackerd importable."""
    env = dict(os.environ)
    package_root = str(Path(trackerd.__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [package_root, env.get("PYTHONPATH")]))
    return env


if __name__ == "__main__":
    # A render worker of render_loop(): WORKDIR MOTION PERIOD_S CONTENT_FPS K WORKERS
    _render_worker(
        Path(sys.argv[1]),
        sys.argv[2],
        float(sys.argv[3]),
        float(sys.argv[4]),
        int(sys.argv[5]),
        int(sys.argv[6]),
    )
