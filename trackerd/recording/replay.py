"""Replay: a recording as a :class:`~trackerd.acquisition.source.PairSource`, so the pipeline cannot tell.

Pacing: at ``speed`` 1.0 each pair is delivered when it is due by the recorded
capture times (``speed`` 2.0 twice as fast); with ``speed=None`` ("max") every
pair is delivered as soon as the consumer asks. Replay never drops a pair: a
consumer slower than the recorded pace gets every pair late (the lag is in
:attr:`ReplayPairSource.lag_ms`), which keeps a replay deterministic at any speed.

Timestamps: the pipeline publishes ``pair.timestamp_ns + clock_offset_ns`` as
each message's capture time. The source moves every recorded monotonic time by
``shift_ns`` (so pairs look as if captured now, and latency figures mean
something at speed 1), and :meth:`ReplayPairSource.pipeline_clock_offset_ns`
gives the offset that undoes the shift: the capture times published are the
recorded ones, to the nanosecond, in every replay. Frames' host timestamps are
the moment the replay delivered them (the pipeline's processing latency then
measures the pipeline alone).

Damaged pairs (a record or frame checksum that does not match) are skipped,
counted and described in :attr:`ReplayPairSource.problems`; the rest replays.
"""

from __future__ import annotations

import dataclasses
import queue
import threading
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from trackerd.acquisition.frame import FramePair
from trackerd.acquisition.pacing import wait_until_due
from trackerd.acquisition.source import PairSource
from trackerd.acquisition.status import CameraState, CameraStatus, SourceStatus
from trackerd.config.models import RigConfig
from trackerd.errors import RecordingError
from trackerd.locator import PointerFix
from trackerd.recording.ahead import LocateAhead, WorkerFailed, located_pair
from trackerd.recording.format import RecordHeader
from trackerd.recording.reader import Recording, make_pair

RATE_WINDOW_NS = 1_000_000_000
READ_AHEAD_PAIRS = 4
"""Pairs the reader thread checks ahead of the consumer. Raw frames are views into the memory map;
a windowed frame is a canvas of its own while it is in flight, and each new keyframe is copied into
every canvas in use after it, so fewer pairs in flight are fewer 2 MB copies: 4 ahead, in batches
of 2, made 9 copies a keyframe per camera where 8 in batches of 4 made 17 (0.2 ms of CPU a pair
less on the 1 s keyframes of `trackerd bench replay --modes`; docs/recording.md, "Replay speed")."""
BATCH_PAIRS = 2
"""At max speed the reader thread hands pairs over this many at a time: one queue operation (locks,
a wake-up) per batch rather than per pair."""
STOP_TIMEOUT_S = 1.0
THREADED_DECODE_MODES = frozenset({"compressed"})
"""Recording modes whose cameras' frames the reader rebuilds on threads of their own, one a camera:
a compressed pair is two zstd frames of about 1 MB and two additions, 6.5 ms of CPU on one thread,
which held a replay to 55-117 pairs/s. A windowed pair's windows take 0.2 ms (docs/recording.md,
"Replay speed"): there the hand-over to a thread would cost about what it saves."""


MAX_REPLAY_GAP_NS = 10 * 10**9
"""The longest replay at a recorded speed waits between two pairs (at that speed): a longer gap in the
recording is replayed as this long. The published capture times are the recorded ones all the same, so the
latency the status gives for the pairs after such a gap (publish time less capture time) is short by the
time not waited, negative for a gap of minutes or more."""


@dataclass(frozen=True, slots=True)
class _Read:
    """One pair as the reader thread found it: its header and frames, or what is wrong with it."""

    index: int
    loop_pass: int
    header: RecordHeader | None
    images: list[NDArray[np.uint8]] | None
    error: RecordingError | None
    fix: PointerFix | None = None
    """Located ahead (trackerd.recording.ahead): the pixels are read only if looked at."""
    failure: str | None = None
    """The worker locating ahead stopped: the replay cannot go on."""


class ReplayPairSource(PairSource):
    """Serves the pairs of ``recording`` in order; ``first``/``count`` select a range of pairs."""

    def __init__(
        self,
        recording: Recording | str | Path,
        *,
        speed: float | None = 1.0,
        loop: bool = False,
        verify: bool = True,
        start_delay_s: float = 0.0,
        first: int = 0,
        count: int | None = None,
        passes: int | None = None,
        shift_ns: int | None = None,
        batch: bool = True,
        threaded_decode: bool = True,
        locate_with: RigConfig | None = None,
    ) -> None:
        """``speed`` None replays as fast as the consumer takes pairs. ``shift_ns`` moves recorded
        timestamps (default: so that the first pair is due at construction plus ``start_delay_s``).
        ``batch`` False hands pairs over one by one at max speed too (as before batching; benchmarks).
        ``passes``, when looping, ends the replay after that many passes (None: until stopped).
        ``threaded_decode`` False rebuilds every camera's frame on the reader thread in every mode
        (as before :data:`THREADED_DECODE_MODES`; benchmarks). ``locate_with``, at max speed: a
        worker process locates every pair ahead of the pipeline with a locator of this rig (the
        pipeline's) and the pairs come with their fixes (trackerd.recording.ahead)."""
        if speed is not None and speed <= 0:
            raise ValueError("speed must be positive (None: as fast as possible)")
        if passes is not None and passes < 1:
            raise ValueError("passes must be at least 1 (None: until stopped)")
        self.recording = recording if isinstance(recording, Recording) else Recording.open(recording)
        n = len(self.recording)
        self.first = min(max(first, 0), n)
        self.stop_at = n if count is None else min(n, self.first + count)
        if self.first >= self.stop_at:
            raise RecordingError(
                f"{self.recording.path}: no intact pairs to replay" + (f" from pair {first}" if first else "")
            )
        self.speed = speed
        self.every_pair_published = speed is None
        self.loop = loop
        self.passes = passes if loop else 1
        self.verify = verify
        self.start_delay_s = start_delay_s
        self._batch = BATCH_PAIRS if batch and speed is None else 1
        self._decode_threads = (
            len(self.recording.cameras) - 1
            if threaded_decode and self.recording.metadata.mode in THREADED_DECODE_MODES
            else 0
        )
        self._locate_with = locate_with if speed is None else None
        self._worker: LocateAhead | None = None
        self._local: deque[_Read] = deque()
        entries = self.recording.entries
        # The time line of the pairs whose capture times are in it (the others are skipped as damaged).
        timed = self.recording.timed(self.first, self.stop_at)
        if not timed:
            raise RecordingError(
                f"{self.recording.path}: no pair to replay"
                + (f" from pair {first}" if first else "")
                + " has a capture time in the recording's time line"
            )
        self._t0_rec = entries[timed[0]].timestamp_ns
        # One pass lasts from the first pair to one typical period after the last (timestamps of later passes
        # are moved on by it).
        span = entries[timed[-1]].timestamp_ns - self._t0_rec
        pairs = len(timed)
        self._pass_ns = span + (span // (pairs - 1) if pairs > 1 else 16_666_667)
        # When each pair is due, from the first: its recorded time, but a gap longer than MAX_REPLAY_GAP_NS
        # (the cameras away, stills imported from two sessions, a time edited days ahead) waits only that long.
        self._paced_ns: dict[int, int] = {}
        paced = 0
        for previous, index in zip([timed[0], *timed], timed, strict=False):
            paced += min(entries[index].timestamp_ns - entries[previous].timestamp_ns, MAX_REPLAY_GAP_NS)
            self._paced_ns[index] = paced
        self._paced_pass_ns = paced + (paced // (pairs - 1) if pairs > 1 else 16_666_667)
        self._sequence_step = max(entries[self.stop_at - 1].sequence, 0) + 1
        default_shift = time.monotonic_ns() + int(start_delay_s * 1e9) - self._t0_rec
        self.shift_ns = default_shift if shift_ns is None else shift_ns
        self._planned_start_ns: int | None = self._t0_rec + default_shift if shift_ns is None else None
        """When the first pair's moved timestamp says it is due (the default shift's plan), for the first
        :meth:`start`: the pairs are then delivered at the times they carry."""
        self._lock = threading.Lock()
        self._running = False
        self._finished = False
        self._pending: _Read | None = None
        self._reader: threading.Thread | None = None
        self._halt = threading.Event()
        self._ahead: queue.Queue[list[_Read]] = queue.Queue(maxsize=self._queue_batches())
        self._start_ns = 0
        self.delivered = 0
        self.skipped = 0
        """Pairs not delivered because they are damaged."""
        self.problems: list[str] = []
        self.failure: str | None = None
        """Why the replay ended before its last pair (the worker locating ahead stopped), else None."""
        self.lag_ms = 0.0
        """How late the last pair was delivered against the recorded pace (0 at max speed)."""
        self.max_lag_ms = 0.0
        self.first_delivery_ns: int | None = None
        self.last_delivery_ns: int | None = None
        """Monotonic times of the first and the last delivery (the replay's throughput)."""
        self._times: deque[int] = deque()
        self._skews: deque[int] = deque(maxlen=256)
        self._delivered_pass = 0

    # ------------------------------------------------------------------ clocks

    def pipeline_clock_offset_ns(self) -> int:
        """The Pipeline's ``clock_offset_ns`` that makes published capture times the recorded ones."""
        return self.recording.metadata.clock_offset_ns - self.shift_ns

    @property
    def finished(self) -> bool:
        """True once every pair was delivered (when looping, of the last pass; never without ``passes``)."""
        return self._finished

    # ------------------------------------------------------------------ PairSource

    def start(self) -> None:
        self.stop()
        with self._lock:
            self._running = True
            self._finished = False
            self._pending = None
            self._delivered_pass = 0
            now = time.monotonic_ns()
            # Due at the times their timestamps say, so that a pair's latency is the pipeline's own: the
            # pipeline is set up (a publisher bound, a locator made) between construction and here, and
            # due start_delay_s after this call, every pair's latency counted that time too (135-220 ms).
            # A set-up longer than the delay leaves the first pairs overdue: they are delivered at once, late
            # by what lag_ms says, until the replay has caught up with the times they carry.
            planned, self._planned_start_ns = self._planned_start_ns, None
            self._start_ns = planned if planned is not None else now + int(self.start_delay_s * 1e9)
        self._halt = threading.Event()
        self._ahead = queue.Queue(maxsize=self._queue_batches())
        self._local = deque()
        if self._locate_with is not None:
            self._worker = LocateAhead(
                self.recording, self._locate_with, self.first, self.stop_at, self.passes, self.verify
            )
        self._reader = threading.Thread(
            target=self._read_ahead if self._worker is None else self._receive_located,
            args=(self._halt, self._ahead),
            name="trackerd-replay-reader",
            daemon=True,
        )
        self._reader.start()

    def _queue_batches(self) -> int:
        return max(1, READ_AHEAD_PAIRS // self._batch)

    def stop(self) -> None:
        with self._lock:
            self._running = False
        if self._reader is not None:
            self._halt.set()
            self._reader.join(STOP_TIMEOUT_S)
            self._reader = None
        if self._worker is not None:
            self._worker.stop()
            self._worker = None

    def _due_ns(self, index: int, loop_pass: int) -> int:
        if self.speed is None or index in self.recording.out_of_time:
            return self._start_ns  # a pair out of time is skipped as soon as it is reached
        recorded = self._paced_ns[index] + loop_pass * self._paced_pass_ns
        return self._start_ns + int(recorded / self.speed)

    def next_pair(self, timeout_s: float) -> FramePair | None:
        deadline = time.monotonic_ns() + int(max(timeout_s, 0.0) * 1e9)
        while True:
            with self._lock:
                if not self._running or self._finished:
                    return None
            item = self._pending
            if item is None:
                if not self._local:
                    try:
                        wait_s = max(0.0, (deadline - time.monotonic_ns()) / 1e9)
                        self._local.extend(self._ahead.get(timeout=wait_s))
                    except queue.Empty:
                        return None
                item = self._local.popleft()
                self._pending = item
            if not wait_until_due(self._due_ns(item.index, item.loop_pass), deadline):
                return None
            self._pending = None
            last = item.index == self.stop_at - 1 and self._last_pass(item.loop_pass)
            pair = self._deliver(item)
            if last:
                with self._lock:
                    self._finished = True
            if pair is not None:
                return pair
            if time.monotonic_ns() >= deadline:
                return None

    def _deliver(self, item: _Read) -> FramePair | None:
        if item.failure is not None:
            # The replay ends here, as at its last pair: what was published stays, the summary says why.
            with self._lock:
                self.failure = item.failure
                self.problems.append(item.failure)
                self._finished = True
            return None
        if item.error is not None:
            with self._lock:
                self.skipped += 1
                if len(self.problems) < 100:
                    self.problems.append(f"{item.error}; pair skipped")
            return None
        assert item.header is not None
        now = time.monotonic_ns()
        shift = self.shift_ns + item.loop_pass * self._pass_ns
        sequence = item.header.sequence + item.loop_pass * self._sequence_step
        if item.fix is not None:
            pair = located_pair(
                self.recording,
                item.index,
                item.header,
                item.fix,
                verify=self.verify,
                shift_ns=shift,
                host_ns=now,
                sequence=sequence,
            )
        else:
            assert item.images is not None
            pair = make_pair(self.recording, item.header, item.images, shift_ns=shift, host_ns=now, sequence=sequence)
        if item.loop_pass > self._delivered_pass:
            # The jump from the last pair back to the first is no motion of the pointer.
            self._delivered_pass = item.loop_pass
            pair = dataclasses.replace(pair, fresh_start=True)
        self.lag_ms = 0.0 if self.speed is None else max(0.0, (now - self._due_ns(item.index, item.loop_pass)) / 1e6)
        self.max_lag_ms = max(self.max_lag_ms, self.lag_ms)
        with self._lock:
            if self.first_delivery_ns is None:
                self.first_delivery_ns = now
            self.last_delivery_ns = now
            self.delivered += 1
            self._times.append(now)
            self._skews.append(pair.skew_ns)
        return pair

    def _read_ahead(self, halt: threading.Event, ahead: queue.Queue[list[_Read]]) -> None:
        """The reader thread: checks each pair (checksums: zlib releases the GIL, so this runs beside the
        pipeline on another core) and queues it, up to READ_AHEAD_PAIRS ahead of the consumer, in
        batches of ``self._batch`` (the last of a pass may be shorter). In THREADED_DECODE_MODES the
        second camera's frames on are rebuilt on a pool's threads meanwhile."""
        if self._decode_threads == 0:
            self._read_pairs(halt, ahead, None)
            return
        with ThreadPoolExecutor(self._decode_threads, thread_name_prefix="trackerd-replay-decode") as pool:
            self._read_pairs(halt, ahead, pool)

    def _read_pairs(
        self, halt: threading.Event, ahead: queue.Queue[list[_Read]], pool: ThreadPoolExecutor | None
    ) -> None:
        loop_pass = 0
        batch: list[_Read] = []
        while not halt.is_set():
            for index in range(self.first, self.stop_at):
                try:
                    header = self.recording.header(index)
                    images = self.recording.images(index, header, verify=self.verify, pool=pool)
                    item = _Read(index, loop_pass, header, images, None)
                except RecordingError as err:
                    item = _Read(index, loop_pass, None, None, err)
                batch.append(item)
                if len(batch) < self._batch and index < self.stop_at - 1:
                    continue
                self._put(halt, ahead, batch)
                batch = []
                if halt.is_set():
                    return
            if self._last_pass(loop_pass):
                return
            loop_pass += 1

    def _receive_located(self, halt: threading.Event, ahead: queue.Queue[list[_Read]]) -> None:
        """The reader thread when locating ahead: the worker's fixes with each pair's header, queued
        as :meth:`_read_pairs` queues pairs (the pixels are read only if looked at)."""
        worker = self._worker
        assert worker is not None
        batch: list[_Read] = []
        try:
            for located in worker.results(halt):
                if located.fix is None:
                    item = _Read(located.index, located.loop_pass, None, None, RecordingError(located.damaged or ""))
                else:
                    header = self.recording.header(located.index)
                    item = _Read(located.index, located.loop_pass, header, None, None, located.fix)
                batch.append(item)
                if len(batch) >= self._batch or located.index == self.stop_at - 1:
                    self._put(halt, ahead, batch)
                    batch = []
        except (WorkerFailed, RecordingError) as err:
            self._put(halt, ahead, [*batch, _Read(self.first, 0, None, None, None, failure=str(err))])

    @staticmethod
    def _put(halt: threading.Event, ahead: queue.Queue[list[_Read]], batch: list[_Read]) -> None:
        while not halt.is_set():
            try:
                ahead.put(batch, timeout=0.1)
                return
            except queue.Full:
                continue

    def _last_pass(self, loop_pass: int) -> bool:
        return self.passes is not None and loop_pass >= self.passes - 1

    def status(self) -> SourceStatus:
        now = time.monotonic_ns()
        with self._lock:
            while self._times and now - self._times[0] > RATE_WINDOW_NS:
                self._times.popleft()
            rate = len(self._times) / (RATE_WINDOW_NS / 1e9) if self._running else 0.0
            skews = sorted(self._skews)
            state: CameraState = "streaming" if self._running else "stopped"
            delivered = self.delivered
        p50 = skews[len(skews) // 2] / 1e3 if skews else None
        p99 = skews[min(len(skews) - 1, int(0.99 * len(skews)))] / 1e3 if skews else None
        return SourceStatus(
            running=self._running and not self._finished,
            trigger="replay",
            pairing="recorded",
            pairs=delivered,
            pair_rate_hz=round(rate, 3),
            delivered=delivered,
            dropped_frames={"damaged": self.skipped * len(self.recording.cameras)} if self.skipped else {},
            dropped_pairs=0,
            skew_p50_us=p50,
            skew_p99_us=p99,
            skew_max_us=skews[-1] / 1e3 if skews else None,
            cameras=tuple(
                CameraStatus(
                    cam.id, state, f"recording {self.recording.path}", frames=delivered, frame_rate_hz=round(rate, 3)
                )
                for cam in self.recording.cameras
            ),
        )
