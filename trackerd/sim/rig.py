"""The virtual rig: one simulated GigE Vision camera per camera of a rig, serving a rendered motion.

The motion is rendered once as a loop (:mod:`trackerd.sim.loops`), and the
cameras serve it at whatever frame rate the client configures: each frame
shows the loop frame of the current instant, so at 60 fps and 30 loop frames
per second every scene is sent twice.

Networking (:mod:`trackerd.sim.rig_network`): as root, each camera process runs
in its own network namespace, reachable at its own address over a veth pair,
and the returned :attr:`VirtualRig.daemon_rig` names those addresses. Without
root (``network="loopback"``), the first camera is a GigE Vision camera on
127.0.0.1 and the second is Aravis's in-process Fake camera, whose images this
process supplies: pass :meth:`VirtualRig.on_open` to the pair source. Each
camera process is a :class:`~trackerd.sim.camera_process.CameraProcess`.

Ground truth goes to ``<out_dir>/truth-<camera id>.jsonl``, one line per frame
served (see :mod:`trackerd.sim.gvcamera`).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import IO, Any, Literal

from trackerd.config.models import RigConfig
from trackerd.errors import CameraError
from trackerd.sim import netns
from trackerd.sim.camera_process import CameraProcess, gvcamera_command
from trackerd.sim.gvcamera import FillServer, FrameLoop, SimClock
from trackerd.sim.loops import (
    KEEP_LOOPS,
    LOOP_VERSION,
    RenderedLoop,
    child_env,
    default_cache_dir,
    loop_key,
    loop_truth,
    render_loop,
)
from trackerd.sim.motion import DEFAULT_PERIOD_S
from trackerd.sim.rig_network import FAKE_DEVICE_ID, Network, RigNetwork, choose_network

__all__ = [
    "FAKE_DEVICE_ID",
    "KEEP_LOOPS",
    "LOOP_VERSION",
    "Network",
    "RenderedLoop",
    "VirtualRig",
    "default_cache_dir",
    "loop_key",
    "loop_truth",
    "render_loop",
]
"""The rig, and the loop names this module held before the loops got their own (importers use them here)."""


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
        self.rig = rig
        self.motion = motion
        self.period_s = period_s
        self.content_fps = content_fps
        self.net = RigNetwork(len(rig.cameras), choose_network(rig, network), prefix, subnet, mtu)
        self.out_dir = Path(out_dir) if out_dir else Path(tempfile.mkdtemp(prefix="trackerd-simrig-"))
        self.cache_dir = cache_dir
        self.synthetic = synthetic
        self.clock_offsets = clock_offsets
        self.phases = phases
        self.loop: RenderedLoop | None = None
        self.start_ns = 0
        self._procs: list[CameraProcess] = []
        self._fill_servers: dict[str, FillServer] = {}
        self._truth_files: list[IO[str]] = []
        self._started = False

    # ------------------------------------------------------------------ addresses

    @property
    def network(self) -> Literal["netns", "loopback"]:
        return self.net.kind

    @property
    def nets(self) -> list[netns.CameraNet]:
        """Each camera's namespace and link (netns network; empty on loopback)."""
        return self.net.nets

    @property
    def prefix(self) -> str:
        return self.net.prefix

    @property
    def mtu(self) -> int | None:
        return self.net.mtu

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
            update = self.net.camera_update(index, self.serial(index))
            if self.net.jumbo_frames:
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
            self.net.claim()
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
            self.net.create_links()
            self._procs = [CameraProcess(i, self.rig.cameras[i].id, self._command(i)) for i in self.net.gige_cameras]
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
            proc.terminate()
        for server in self._fill_servers.values():
            server.uninstall()
        self._fill_servers.clear()
        for handle in self._truth_files:
            handle.close()
        self._truth_files.clear()
        self.net.release()
        self._started = False

    def __enter__(self) -> VirtualRig:
        self.start()
        return self

    def __exit__(self, *_exc: object) -> None:
        self.stop()

    # ------------------------------------------------------------------ camera processes

    def kill_camera(self, index: int) -> None:
        """Kill camera ``index``'s process at once (SIGKILL), as a crash or a pulled cable would."""
        self._process(index).kill()

    def restart_camera(self, index: int) -> None:
        """Start camera ``index`` again (a fresh simulated camera at the same address)."""
        proc = self._process(index)
        proc.terminate()
        self._spawn(proc)

    def camera_running(self, index: int) -> bool:
        return self._process(index).running

    def on_open(self, camera_id: str, camera: Any) -> None:
        """Pair-source hook: supplies the images of the in-process Fake camera (loopback network)."""
        if self.network != "loopback" or camera_id == self.rig.cameras[0].id:
            return
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

    def _process(self, index: int) -> CameraProcess:
        for proc in self._procs:
            if proc.index == index:
                return proc
        raise CameraError(f"camera {index} is not a separate simulated GigE Vision camera in this rig")

    def _command(self, index: int) -> list[str]:
        cam = self.rig.cameras[index]
        prefix, interface = self.net.exec_prefix(index)
        loop = self.loop
        served = None if loop is None else (loop.frame_paths[index], loop.truth_path, loop.content_fps)
        return gvcamera_command(
            exec_prefix=prefix,
            interface=interface,
            serial=self.serial(index),
            label=cam.id,
            start_ns=self.start_ns,
            clock=self.clock(index),
            phase_us=self.phase_us(index),
            truth_out=self.truth_path(index),
            loop=served,
            size_px=(cam.width_px, cam.height_px),
        )

    def _spawn(self, proc: CameraProcess) -> None:
        proc.spawn(child_env(), self.out_dir / f"camera-{self.rig.cameras[proc.index].id}.log")
