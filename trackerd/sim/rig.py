"""The virtual rig: one simulated GigE Vision camera per camera of a rig, serving a rendered motion.

Rendering a 1920x1080 view takes 0.05-0.3 s in Python, far from 60 frames per
second, so a motion is rendered once as a loop of one period at
``content_fps`` loop frames per second (in worker processes) and cached on disk
(``~/.cache/trackerd/simrig/<hash of rig, motion, renderer>``, the four most
recently used loops kept). The cameras
then serve the loop at whatever frame rate the client configures: each frame
shows the loop frame of the current instant, so at 60 fps and 30 loop frames
per second every scene is sent twice.

Networking (:mod:`trackerd.sim.netns`): as root, each camera process runs in
its own network namespace, reachable at its own address over a veth pair, and
the returned :attr:`VirtualRig.daemon_rig` names those addresses. Without root
(``network="loopback"``), the first camera is a GigE Vision camera on
127.0.0.1 and the second is Aravis's in-process Fake camera, whose images this
process supplies: pass :meth:`VirtualRig.on_open` to the pair source.

Ground truth goes to ``<out_dir>/truth-<camera id>.jsonl``, one line per frame
served (see :mod:`trackerd.sim.gvcamera`).
"""

from __future__ import annotations

import hashlib
import json
import os
import selectors
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Literal

import numpy as np

import trackerd
from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import wall_frame
from trackerd.errors import CameraError, TrackerdError
from trackerd.sim import netns
from trackerd.sim.motion import DEFAULT_PERIOD_S, make_motion

LOOP_VERSION = 1
"""Bump when the loop format changes, so cached loops are not reused."""
READY_TIMEOUT_S = 15.0
KEEP_LOOPS = 4
"""Rendered loops kept in the cache; older ones are deleted when a new one is rendered."""
FAKE_DEVICE_ID = "Fake_1"
Network = Literal["auto", "netns", "loopback"]


def default_cache_dir() -> Path:
    """$TRACKERD_SIMRIG_CACHE, else $XDG_CACHE_HOME/trackerd/simrig, else ~/.cache/trackerd/simrig."""
    explicit = os.environ.get("TRACKERD_SIMRIG_CACHE")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "trackerd" / "simrig"


# ----------------------------------------------------------------------------- loops


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
        return json.loads(self.truth_path.read_text())["frames"]


def loop_key(rig: RigConfig, motion: str, period_s: float, content_fps: float) -> str:
    """A hash of everything a rendered loop depends on, renderer source included."""
    digest = hashlib.sha256()
    # The console serves what is rendered and changes nothing in it (and keys made before it existed stay valid).
    digest.update(rig.model_dump_json(exclude={"console"}).encode())
    digest.update(f"{motion}|{period_s!r}|{content_fps!r}|{LOOP_VERSION}".encode())
    sim_dir = Path(__file__).parent
    for name in ("render.py", "scene.py", "motion.py"):
        digest.update((sim_dir / name).read_bytes())
    return digest.hexdigest()[:20]


def loop_truth(rig: RigConfig, motion: str, period_s: float, content_fps: float) -> list[dict[str, Any]]:
    """Per loop frame: scene time, whether the pointer is there, its true ends and true wall hit."""
    from trackerd.sim.scene import true_wall_hit

    moving = make_motion(motion, rig, period_s)
    wall = wall_frame(rig.wall)
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
    started as ``python -m trackerd.sim.rig`` and writing its frames straight
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
                    "trackerd.sim.rig",
                    str(work),
                    motion,
                    repr(period_s),
                    repr(content_fps),
                    str(k),
                    str(workers),
                ],
                env=_child_env(),
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
        _prune(cache.parent, keep=KEEP_LOOPS)
    except FileExistsError:
        pass  # another process finished the same loop first
    except OSError as err:
        if not (truth_path.exists() and all(p.exists() for p in frame_paths)):
            raise TrackerdError(f"cannot write the rendered loop under {cache.parent}: {err}") from err
    finally:
        if work.exists():
            shutil.rmtree(work, ignore_errors=True)
    return RenderedLoop(cache, frame_paths, truth_path, n_frames, content_fps, time.monotonic() - started)


def _prune(root: Path, keep: int) -> None:
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


def _child_env() -> dict[str, str]:
    """The environment for child processes, with this trackerd importable."""
    env = dict(os.environ)
    package_root = str(Path(trackerd.__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [package_root, env.get("PYTHONPATH")]))
    return env


# ----------------------------------------------------------------------------- the rig


@dataclass
class _CameraProcess:
    index: int
    command: list[str]
    process: subprocess.Popen[str] | None = None
    log: IO[str] | None = None


class VirtualRig:
    """Simulated cameras for every camera of ``rig``; a context manager (start on entry, stop on exit)."""

    def __init__(
        self,
        rig: RigConfig,
        *,
        motion: str = "sweep",
        period_s: float = DEFAULT_PERIOD_S,
        content_fps: float = 30.0,
        network: Network = "auto",
        prefix: str = netns.DEFAULT_PREFIX,
        subnet: str = netns.DEFAULT_SUBNET,
        mtu: int | None = netns.DEFAULT_MTU,
        out_dir: Path | None = None,
        cache_dir: Path | None = None,
        synthetic: bool = False,
        clock_offsets: bool = True,
        phases: bool = True,
    ) -> None:
        """``synthetic`` serves a cheap moving square instead of a rendered motion (no ground truth).

        ``prefix`` and ``subnet`` name the namespaces and address the links (netns network);
        ``mtu`` is the links' MTU, jumbo frames by default (None: the kernel's 1500).
        """
        if network == "auto":
            network = "netns" if netns.netns_missing_reason() is None else "loopback"
        if network == "netns" and (reason := netns.netns_missing_reason()):
            raise TrackerdError(f"cannot build the virtual rig's network: {reason}")
        if network == "loopback" and len(rig.cameras) > 2:
            raise TrackerdError("without network namespaces the virtual rig serves at most two cameras")
        if network == "loopback" and rig.acquisition.trigger == "software":
            # Aravis 0.8's in-process Fake stream does not wait for TriggerSoftware: in trigger
            # mode it delivers frames at its own trigger frequency.
            raise TrackerdError(
                "software triggering needs network namespaces (root): the in-process Fake camera"
                " used without them ignores software triggers"
            )
        self.rig = rig
        self.motion = motion
        self.period_s = period_s
        self.content_fps = content_fps
        self.network: Literal["netns", "loopback"] = network
        self.prefix = prefix
        try:
            self.nets = netns.plan(len(rig.cameras), prefix, subnet) if network == "netns" else []
        except ValueError as err:
            raise TrackerdError(f"cannot plan the virtual rig's network: {err}") from err
        self.mtu = mtu
        self.out_dir = Path(out_dir) if out_dir else Path(tempfile.mkdtemp(prefix="trackerd-simrig-"))
        self.cache_dir = cache_dir
        self.synthetic = synthetic
        self.clock_offsets = clock_offsets
        self.phases = phases
        self.loop: RenderedLoop | None = None
        self.start_ns = 0
        self._lock: netns.PrefixLock | None = None
        self._procs: list[_CameraProcess] = []
        self._fill_servers: dict[str, Any] = {}
        self._truth_files: list[IO[str]] = []
        self._started = False

    # ------------------------------------------------------------------ addresses

    def serial(self, index: int) -> str:
        return self.rig.cameras[index].serial or f"SIM-{self.rig.cameras[index].id.upper()}"

    @property
    def daemon_rig(self) -> RigConfig:
        """The rig as the daemon should open it.

        Each camera is addressed as the simulated camera it now is. Two acquisition
        settings are adapted to the simulated cameras: with jumbo frames (``mtu`` of
        9000) the stream packet size is 8000 bytes (Aravis cannot negotiate it with
        the fake camera), and software triggers are lock-step
        (``max_outstanding_triggers = 1``), because the fake camera reads a trigger
        command only between two frames it sends.
        """
        cameras = []
        for index, cam in enumerate(self.rig.cameras):
            if self.network == "netns":
                update: dict[str, Any] = {
                    "address": self.nets[index].camera_address,
                    "device_id": None,
                    "serial": self.serial(index),
                }
            elif index == 0:
                update = {"address": "127.0.0.1", "device_id": None, "serial": self.serial(index)}
            else:
                update = {"address": None, "device_id": FAKE_DEVICE_ID, "serial": None}
            if self.network == "netns" and self.mtu is not None and self.mtu >= 9000:
                update["acquisition"] = cam.acquisition.model_copy(update={"packet_size_bytes": 8000})
            cameras.append(cam.model_copy(update=update))
        acquisition = self.rig.acquisition.model_copy(update={"max_outstanding_triggers": 1})
        return self.rig.model_copy(update={"cameras": tuple(cameras), "acquisition": acquisition})

    def truth_path(self, index: int) -> Path:
        return self.out_dir / f"truth-{self.rig.cameras[index].id}.jsonl"

    def clock(self, index: int) -> tuple[int, float]:
        """(offset ns, drift ppm) of camera ``index``'s simulated clock."""
        if not self.clock_offsets:
            return 0, 0.0
        return 7_300_000_000 * (index + 1) + 123_456 * index, (25.0, -18.0, 9.0, -4.0)[index % 4]

    def phase_us(self, index: int) -> float:
        """Capture delay of camera ``index`` when free running (a share of the frame period)."""
        if not self.phases:
            return 0.0
        return (0.0, 0.31, 0.57, 0.83)[index % 4] * 1e6 / self.rig.acquisition.frame_rate_hz

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> None:
        if self._started:
            return
        try:
            if self.network == "netns":
                # The prefix is taken first: a rig turned away must not render a loop for
                # nothing, truncate the running rig's truth files, or touch its namespaces.
                # Only a rig holding the lock ever removes namespaces (stop() checks _lock).
                lock = netns.PrefixLock(self.prefix)
                lock.acquire()
                self._lock = lock
                netns.remove_stale(self.prefix)
            if not self.synthetic:
                self.loop = render_loop(
                    self.rig,
                    self.motion,
                    period_s=self.period_s,
                    content_fps=self.content_fps,
                    cache_dir=self.cache_dir,
                )
            self.out_dir.mkdir(parents=True, exist_ok=True)
            for index in range(len(self.rig.cameras)):
                self.truth_path(index).write_text("")  # restarted cameras append; a new run starts afresh
            self.start_ns = time.monotonic_ns()
            if self.network == "netns":
                for net in self.nets:
                    netns.create(net, self.mtu)
            gige = range(len(self.rig.cameras)) if self.network == "netns" else range(1)
            self._procs = [_CameraProcess(i, self._command(i)) for i in gige]
            for proc in self._procs:
                self._spawn(proc)
            if self.network == "loopback":
                from trackerd.acquisition.arv import load_aravis

                aravis, _ = load_aravis()
                aravis.enable_interface("Fake")
            self._started = True
        except BaseException:
            self.stop()
            raise

    def stop(self) -> None:
        for proc in self._procs:
            self._terminate(proc)
        for server in self._fill_servers.values():
            server.uninstall()
        self._fill_servers.clear()
        for handle in self._truth_files:
            handle.close()
        self._truth_files.clear()
        if self.network == "netns" and self._lock is not None:
            for net in self.nets:
                netns.remove(net)
            self._lock.release()
            self._lock = None
        self._started = False

    def __enter__(self) -> VirtualRig:
        self.start()
        return self

    def __exit__(self, *_exc: object) -> None:
        self.stop()

    # ------------------------------------------------------------------ camera processes

    def kill_camera(self, index: int) -> None:
        """Kill camera ``index``'s process at once (SIGKILL), as a crash or a pulled cable would."""
        proc = self._process(index)
        if proc.process is not None and proc.process.poll() is None:
            proc.process.kill()
            proc.process.wait(5)

    def restart_camera(self, index: int) -> None:
        """Start camera ``index`` again (a fresh simulated camera at the same address)."""
        proc = self._process(index)
        self._terminate(proc)
        self._spawn(proc)

    def camera_running(self, index: int) -> bool:
        proc = self._process(index)
        return proc.process is not None and proc.process.poll() is None

    def on_open(self, camera_id: str, camera: Any) -> None:
        """Pair-source hook: supplies the images of the in-process Fake camera (loopback network)."""
        if self.network != "loopback" or camera_id == self.rig.cameras[0].id:
            return
        from trackerd.sim.gvcamera import FillServer, FrameLoop, SimClock

        index = next(i for i, c in enumerate(self.rig.cameras) if c.id == camera_id)
        old = self._fill_servers.pop(camera_id, None)
        if old is not None:
            old.uninstall()
        cam = self.rig.cameras[index]
        if self.loop is None:
            frames = FrameLoop.synthetic(cam.width_px, cam.height_px, self.start_ns)
        else:
            frames = FrameLoop.load(
                self.loop.frame_paths[index],
                self.loop.truth_path,
                self.loop.content_fps,
                self.start_ns,
            )
        if not self._truth_files:
            self._truth_files.append(self.truth_path(index).open("a", buffering=1 << 16))
        offset, drift = self.clock(index)
        server = FillServer(
            camera.get_device().get_fake_camera(),
            frames,
            label=camera_id,
            clock=SimClock(offset, drift, self.start_ns),
            phase_us=self.phase_us(index),
            truth_out=self._truth_files[0],
        )
        server.install()
        self._fill_servers[camera_id] = server

    def _process(self, index: int) -> _CameraProcess:
        for proc in self._procs:
            if proc.index == index:
                return proc
        raise CameraError(f"camera {index} is not a separate simulated GigE Vision camera in this rig")

    def _command(self, index: int) -> list[str]:
        cam = self.rig.cameras[index]
        offset, drift = self.clock(index)
        if self.network == "netns":
            prefix, interface = netns.exec_prefix(self.nets[index]), self.nets[index].camera_link
        else:
            prefix, interface = [], "lo"
        command = [
            *prefix,
            sys.executable,
            "-m",
            "trackerd.sim.gvcamera",
            "--interface",
            interface,
            "--serial",
            self.serial(index),
            "--label",
            cam.id,
            "--start-ns",
            str(self.start_ns),
            "--clock-offset-ns",
            str(offset),
            "--clock-drift-ppm",
            str(drift),
            "--phase-us",
            f"{self.phase_us(index):.1f}",
            "--parent-pid",
            str(os.getpid()),
        ]
        command += ["--truth-out", str(self.truth_path(index))]
        if self.loop is None:
            command += ["--synthetic", f"{cam.width_px}x{cam.height_px}"]
        else:
            loop = self.loop
            command += ["--loop", str(loop.frame_paths[index]), "--loop-truth", str(loop.truth_path)]
            command += ["--content-fps", str(loop.content_fps)]
        return command

    def _spawn(self, proc: _CameraProcess) -> None:
        env = _child_env()
        log_path = self.out_dir / f"camera-{self.rig.cameras[proc.index].id}.log"
        proc.log = log_path.open("a")
        # Its own process group: a Ctrl-C in the terminal then reaches the daemon and not the cameras,
        # which are stopped after it. Sharing the group, they vanished under a daemon still streaming
        # from them, and its acquisition threads were reported as not stopping in time.
        proc.process = subprocess.Popen(
            proc.command, stdout=subprocess.PIPE, stderr=proc.log, text=True, env=env, process_group=0
        )
        line = _read_line(proc.process, READY_TIMEOUT_S)
        if not line.startswith("ready"):
            self._terminate(proc)
            detail = line.strip() or f"no answer in {READY_TIMEOUT_S:g} s; see {log_path}"
            raise CameraError(f"simulated camera '{self.rig.cameras[proc.index].id}' did not start: {detail}")

    def _terminate(self, proc: _CameraProcess) -> None:
        process = proc.process
        if process is not None:
            if process.poll() is None:
                process.terminate()
                try:
                    process.wait(3)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait(3)
            if process.stdout is not None:
                process.stdout.close()
            proc.process = None
        if proc.log is not None:
            proc.log.close()
            proc.log = None


def _read_line(process: subprocess.Popen[str], timeout_s: float) -> str:
    """One line of the process's stdout, or '' if it exits or says nothing within ``timeout_s``."""
    assert process.stdout is not None
    with selectors.DefaultSelector() as selector:
        selector.register(process.stdout, selectors.EVENT_READ)
        if not selector.select(timeout_s):
            return ""
    return process.stdout.readline()


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
