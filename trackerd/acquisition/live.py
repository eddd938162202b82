"""Live cameras through Aravis or pylon, as a :class:`~trackerd.acquisition.source.PairSource`.

Threads: one acquisition thread per camera (:mod:`trackerd.acquisition.worker`),
which also pairs its frames with the others' under one lock (the pairing work is
a few deque operations per frame); in software-trigger mode one trigger thread
per camera connection (:mod:`trackerd.acquisition.firing`); and a short-lived
thread per lost connection (:class:`Releaser`), because Aravis can block for
several seconds giving up on a camera that no longer answers. The consumer's
thread only waits in :meth:`LivePairSource.next_pair`.

Clocks: each camera's device timestamps are mapped to the host's monotonic
clock (:mod:`trackerd.acquisition.rig_clocks`). Without PTP every camera has its
own mapping (pairing by host time, with each camera's offset estimated and
tracked); with PTP enabled and every camera in Master or Slave state, one shared
mapping is used, so pairs are formed by device time.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque

from trackerd.acquisition.clock import NonDecreasing
from trackerd.acquisition.frame import FramePair
from trackerd.acquisition.meters import RateMeter, SkewWindow
from trackerd.acquisition.pairing import Arrival, Pairer, spread_ns
from trackerd.acquisition.rig_clocks import CLOCK_WARMUP_FRAMES as CLOCK_WARMUP_FRAMES  # where it was first
from trackerd.acquisition.rig_clocks import RigClocks
from trackerd.acquisition.session import Session, load_backends
from trackerd.acquisition.source import PairSource
from trackerd.acquisition.status import SourceStatus
from trackerd.acquisition.trigger import TickSchedule, TriggerGate
from trackerd.acquisition.worker import CameraWorker, OpenHook
from trackerd.config.models import RigConfig
from trackerd.errors import CameraError

log = logging.getLogger(__name__)

STOP_BUDGET_S = 1.0
"""stop() joins every thread within this many seconds (see Releaser and firing.py for the exceptions)."""
SEARCH_JOIN_S = 0.1
"""How long stop() waits for the thread of a camera it has not found yet: it may be inside Aravis's
discovery, which takes a second and cannot be interrupted, and it holds nothing to release."""
TRIGGER_LEAD_NS = 50_000_000
"""The first software trigger tick is this far after start, once every camera is open."""


class Releaser:
    """Drops connections to lost cameras, each on a thread of its own.

    Releasing an Aravis GigE Vision device that stopped answering blocks while
    Aravis retries its last GVCP commands (about 2.5 s for the stream and 5 s for
    the device, with Aravis 0.8's fixed retry counts), whereas a connection to a
    camera that still answers goes in milliseconds; one thread each keeps the
    quick ones from queueing behind the slow. A release still running when the
    source stops finishes after stop() returns; ``pending`` says how many remain.
    """

    def __init__(self) -> None:
        self._threads: list[threading.Thread] = []
        self._lock = threading.Lock()

    @property
    def pending(self) -> int:
        with self._lock:
            self._threads = [t for t in self._threads if t.is_alive()]
            return len(self._threads)

    def put(self, session: Session) -> threading.Thread:
        """Release ``session`` on a new thread; returns the thread (alive until released)."""
        thread = threading.Thread(target=_release, args=(session,), name=f"camera-release-{session.camera_id}")
        with self._lock:
            self._threads.append(thread)
        thread.start()
        return thread

    def join(self, timeout_s: float) -> bool:
        """Wait for the releases in progress; True if all finished within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        with self._lock:
            threads = list(self._threads)
        for thread in threads:
            thread.join(max(deadline - time.monotonic(), 0.0))
        return self.pending == 0


def _release(session: Session) -> None:
    try:
        session.abandon()
    except Exception:  # one failed release must not take the process down
        log.exception("releasing camera %s failed", session.camera_id)


class LivePairSource(PairSource):
    """Synchronized frame pairs from the rig's live cameras, each acquired through its backend
    (Aravis or pylon, the camera's ``backend``); one rig may mix them."""

    def __init__(self, rig: RigConfig, *, on_open: OpenHook | None = None, wait_for_cameras: bool = False) -> None:
        """``on_open(camera_id, camera)`` runs after each (re)connection is configured (``camera`` is the
        backend's object: an ``ArvCamera``, a pylon ``InstantCamera``).

        With ``wait_for_cameras`` (the daemon), a camera that is not there at start (not found,
        not answering, not opening) does not fail :meth:`start`: it stays ``connecting`` and its
        thread keeps trying on the reconnection backoff until it opens. Without it (interactive
        commands), start() raises CameraError naming the camera. Either way a configuration the
        camera refuses raises CameraConfigError (exit status 2).
        """
        self.rig = rig
        self.wait_for_cameras = wait_for_cameras
        acq = rig.acquisition
        self._acq = acq
        self._on_open = on_open
        self._n = len(rig.cameras)
        self._tolerance_ns = int(acq.tolerance_us * 1000)
        self._lock = threading.Lock()
        self._ready = threading.Condition(self._lock)
        self._pairs: deque[FramePair] = deque()
        self._pairer = Pairer(self._n, self._tolerance_ns, acq.frame_queue_length, acq.trigger == "software")
        self._workers: list[CameraWorker] = []
        self._clocks = RigClocks(
            self._n, int(acq.clock_window_s * 1e9), acq.ptp, lambda: [w.figures.ptp_state for w in self._workers]
        )
        self.abandoned_threads: list[str] = []
        """Cameras whose thread was still searching for them when stop() returned (see SEARCH_JOIN_S)."""
        self._releaser = Releaser()
        self._running = False
        self._stamp = NonDecreasing()
        self._sequence = 0
        self._delivered = 0
        self._dropped_pairs = 0
        self._skews = SkewWindow()
        self._rate = RateMeter()

    # ------------------------------------------------------------------ PairSource

    def start(self) -> None:
        """Open every camera (in rig order), then start their threads.

        CameraError if one cannot open (unless ``wait_for_cameras``: then it is left to its thread);
        CameraConfigError if one refuses its configuration.
        """
        if self._running:
            return
        # A library that is not installed is not waited for: it raises here, naming what to install.
        load_backends(self.rig.cameras)
        schedule = None
        if self._acq.trigger == "software":
            # Tick 0 is due once every camera has had time to open (the first ticks find
            # the cameras not yet armed and pass).
            period_ns = round(1e9 / self._acq.frame_rate_hz)
            schedule = TickSchedule(time.monotonic_ns() + TRIGGER_LEAD_NS, period_ns)
        with self._lock:
            self._pairs.clear()
            self._pairer = Pairer(
                self._n,
                self._tolerance_ns,
                self._acq.frame_queue_length,
                self._acq.trigger == "software",
            )
        self._clocks.reset_all()
        gate = None
        if schedule is not None:
            # A camera that answers no trigger for a quarter second stops holding the others
            # back (it is about to be declared lost); a first frame may take 0.1 s to come.
            gate = TriggerGate(stall_ticks=max(3, math.ceil(0.25 * self._acq.frame_rate_hz)))
        workers = [
            CameraWorker(i, cam, self._acq, self, schedule, gate, self._on_open)
            for i, cam in enumerate(self.rig.cameras)
        ]
        opened: list[CameraWorker] = []
        absent: list[CameraWorker] = []
        try:
            for worker in workers:
                if worker.open(wait=self.wait_for_cameras):
                    opened.append(worker)
                else:
                    absent.append(worker)
        except BaseException:
            for worker in opened:
                worker.close()
            raise
        with self._lock:
            for worker in absent:
                # Until it opens, the others' frames have no partner: dropped on arrival (partner_lost).
                self._pairer.set_active(worker.index, False)
        self._workers = workers
        self._running = True
        for worker in workers:
            worker.start()

    def stop(self) -> None:
        if not self._workers:
            return
        deadline = time.monotonic() + STOP_BUDGET_S
        # One short wait for all the cameras still being searched for, not one each: with every camera
        # missing, stopping took SEARCH_JOIN_S per camera, one after the other.
        search_deadline = time.monotonic() + SEARCH_JOIN_S
        for worker in self._workers:
            worker.request_stop()
        for worker in self._workers:
            holds = worker.holds_camera
            budget = deadline - time.monotonic() if holds else min(search_deadline, deadline) - time.monotonic()
            if worker.join(budget):
                continue
            if holds:
                log.warning("camera %s: acquisition thread did not stop in time", worker.cam.id)
            else:
                log.info("camera %s: not waiting for the search for it to end (nothing is open)", worker.cam.id)
        self.abandoned_threads = [worker.cam.id for worker in self._workers if worker.alive]
        if not self._releaser.join(deadline - time.monotonic()):
            log.warning("%d lost camera connection(s) still being released", self._releaser.pending)
        with self._ready:
            self._running = False
            self._ready.notify_all()

    def next_pair(self, timeout_s: float) -> FramePair | None:
        """The oldest undelivered pair; waits up to ``timeout_s`` (<= 0: does not wait).

        Raises CameraError if an acquisition thread died of an unexpected error,
        so a consumer never waits forever on a source that cannot deliver.
        """
        with self._ready:
            if not self._pairs and self._running and timeout_s > 0:
                self._ready.wait_for(lambda: bool(self._pairs) or not self._running or self._crashed(), timeout_s)
            crash = self._crashed()
            if crash is not None:
                raise CameraError(crash)
            if not self._pairs:
                return None
            self._delivered += 1
            return self._pairs.popleft()

    def status(self) -> SourceStatus:
        now = time.monotonic_ns()
        cameras = tuple(worker.status(self._clocks.clock_for(i).offset_ns) for i, worker in enumerate(self._workers))
        with self._lock:
            skew = self._skews.percentiles_us()
            return SourceStatus(
                running=self._running,
                trigger=self._acq.trigger,
                pairing=self._pairing_basis(),
                pairs=self._sequence,
                pair_rate_hz=round(self._rate.rate_hz(now), 3),
                delivered=self._delivered,
                dropped_frames=dict(self._pairer.dropped),
                dropped_pairs=self._dropped_pairs,
                skew_p50_us=skew[0] if skew else None,
                skew_p99_us=skew[1] if skew else None,
                skew_max_us=skew[2] if skew else None,
                releasing=self._releaser.pending,
                cameras=cameras,
            )

    @property
    def workers(self) -> list[CameraWorker]:
        """The per-camera workers (for inspection: buffer pools, thread liveness)."""
        return list(self._workers)

    # ------------------------------------------------------------------ FrameSink (worker threads)

    def deliver(self, arrival: Arrival) -> None:
        if self._clocks.settling(arrival):
            with self._lock:
                self._pairer.dropped["clock_warmup"] += 1
            return
        with self._ready:
            groups = self._pairer.add(arrival)
            for group in groups:
                self._queue_pair(group)
            if groups:
                self._ready.notify_all()

    def camera_lost(self, camera_index: int) -> None:
        with self._lock:
            self._pairer.set_active(camera_index, False)

    def camera_back(self, camera_index: int) -> None:
        self._clocks.reset(camera_index)
        with self._lock:
            self._pairer.set_active(camera_index, True)

    def worker_failed(self, camera_index: int) -> None:
        with self._ready:
            self._ready.notify_all()

    def _crashed(self) -> str | None:
        return next((w.crash for w in self._workers if w.crash is not None), None)

    def abandon(self, session: Session) -> threading.Thread:
        return self._releaser.put(session)

    def observe_clock(self, camera_index: int, device_ns: int, host_ns: int) -> int:
        return self._clocks.observe(camera_index, device_ns, host_ns)

    # ------------------------------------------------------------------ internals

    def _pairing_basis(self) -> str:
        if self._acq.trigger == "software":
            return "trigger count"
        return "device time (PTP)" if self._clocks.ptp_locked() else "host time"

    def _queue_pair(self, group: tuple[Arrival, ...]) -> None:
        """Make a pair of ``group`` and queue it for the consumer, dropping the oldest if the queue is full.
        Called with the lock held."""
        times = [a.capture_ns for a in group]
        skew = spread_ns(group)
        self._sequence += 1
        pair = FramePair(
            frames=tuple(a.frame for a in group),
            timestamp_ns=self._stamp(sum(times) // len(times)),
            skew_ns=skew,
            sequence=self._sequence,
        )
        self._skews.add(skew)
        self._rate.tick(time.monotonic_ns())
        if len(self._pairs) >= self._acq.pair_queue_length:
            self._pairs.popleft()
            self._dropped_pairs += 1
        self._pairs.append(pair)


AravisPairSource = LivePairSource
"""The name the live source had while Aravis was its only backend."""
