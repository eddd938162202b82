"""The recorder: a writer thread fed through a bounded drop-oldest queue, so producers never wait for the disk.

`trackerd record` and the daemon's recording extension both hand pairs to
:meth:`Recorder.put`, which never blocks: when the disk falls behind, the oldest
waiting pair is dropped and counted, as everywhere else in trackerd. The writer
thread creates the recording when the first pair arrives (its frames give the
pixel formats and sizes), writes every pair it takes, and closes the recording
when asked, when a limit is reached, or when the disk is full.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

from trackerd.acquisition.frame import FramePair
from trackerd.config.models import RigConfig
from trackerd.config.recording import RecordingConfig
from trackerd.errors import RecordingError
from trackerd.pipeline.queues import DropOldestQueue
from trackerd.recording.writer import DiskFullError, RecordingWriter, build_metadata, free_space_bytes

log = logging.getLogger(__name__)

RecorderState = Literal["recording", "finishing", "stopped", "failed"]
RATE_WINDOW_S = 2.0
GET_TIMEOUT_S = 0.1


@dataclass(frozen=True)
class RecorderStatus:
    """A snapshot of a recorder, the fields of the status message's ``recording`` object."""

    state: RecorderState
    path: str
    pairs: int
    """Pairs written."""
    written_mb: float
    """Bytes written to the recording, in MB (10^6 bytes)."""
    write_rate_mb_s: float
    """Over the last two seconds."""
    pair_rate_hz: float
    dropped_pairs: int
    """Pairs dropped because the writer fell behind (the queue was full)."""
    queued_pairs: int
    recorded_s: float
    """Recorded time from the first pair to the last written."""
    free_space_mb: float | None
    detail: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class Recorder:
    """Records the pairs put into it at ``path`` (a new folder) on a thread of its own."""

    def __init__(
        self,
        path: str | Path,
        rig: RigConfig,
        *,
        producer: str,
        config: RecordingConfig | None = None,
        clock_offset_ns: int | None = None,
        camera_info: Mapping[str, Mapping[str, str | None]] | None = None,
        rig_file: str | Path | None = None,
        calibration_file: str | Path | None = None,
        log_failure: bool = True,
    ) -> None:
        """``config`` gives compression, queue length and limits (default: the rig's [recording]).
        ``camera_info`` (by camera id: vendor, model, serial, device) is read when the first pair
        arrives, so a hook filling it while the cameras open is in time (a
        :class:`trackerd.recording.cameras.CameraInfo` given to the source as its ``on_open``).
        ``rig_file`` is the rig TOML the configuration was read from; ``calibration_file`` defaults
        to the rig's ``calibration`` relative to it. Without them the metadata has nulls there. ``log_failure`` logs a
        full disk or an error as it happens (the daemon); a command that reports :attr:`error`
        itself turns it off, so the failure is said once."""
        self.path = Path(path)
        self.rig = rig
        self.config = config or rig.recording
        self._producer = producer
        self._clock_offset_ns = time.time_ns() - time.monotonic_ns() if clock_offset_ns is None else clock_offset_ns
        self._camera_info = camera_info
        self._rig_file = rig_file
        self._calibration_file = calibration_file
        self._log_failure = log_failure
        self._queue: DropOldestQueue[tuple[FramePair, int]] = DropOldestQueue(self.config.queue_pairs)
        self._puts = 0
        self._closing = threading.Event()
        self._done = threading.Event()
        self._lock = threading.Lock()
        self._writer: RecordingWriter | None = None
        self._state: RecorderState = "recording"
        self._detail: str | None = None
        self._first_ns: int | None = None
        self._last_ns: int | None = None
        self._rate: deque[tuple[float, int, int]] = deque()
        self.peak_queued = 0
        """The most pairs that were waiting for the writer at once (benchmarks: how close to a drop)."""
        self.error: RecordingError | None = None
        """What stopped the recording, when it was not asked to stop (disk full, a bad frame)."""
        self._thread = threading.Thread(target=self._run, name="trackerd-recorder", daemon=True)

    # ------------------------------------------------------------------ producer side

    def start(self) -> Recorder:
        self._thread.start()
        return self

    def put(self, pair: FramePair) -> None:
        """Queue a pair for writing; never blocks (a full queue drops its oldest pair)."""
        if self._closing.is_set() or self._done.is_set():
            return
        self._puts += 1
        self._queue.put((pair, self._puts))

    @property
    def done(self) -> bool:
        """The writer thread has finished (asked to, a limit, the disk full, or an error)."""
        return self._done.is_set()

    def finish(self) -> None:
        """Ask the writer to write what is queued, close the recording and end; does not wait."""
        self._closing.set()

    def stop(self, timeout_s: float = 2.0) -> bool:
        """finish() and wait for the writer; True if it ended within ``timeout_s``."""
        self.finish()
        if self._thread.is_alive():
            self._thread.join(timeout_s)
        elif not self._thread.ident:
            self._done.set()  # never started
        return not self._thread.is_alive()

    def wait(self, timeout_s: float | None = None) -> bool:
        return self._done.wait(timeout_s)

    # ------------------------------------------------------------------ writer thread

    def _run(self) -> None:
        reason = "stopped"
        last_put = 0
        try:
            while True:
                item = self._queue.get(GET_TIMEOUT_S)
                if item is None:
                    if self._closing.is_set():
                        break
                    continue
                pair, put_index = item
                self.peak_queued = max(self.peak_queued, len(self._queue) + 1)
                limit = self._limit_reached(pair)
                if limit is not None:
                    reason = limit
                    break
                if self._writer is None:
                    self._writer = self._create(pair)
                dropped_before = put_index - last_put - 1
                last_put = put_index
                written = self._writer.write(pair, dropped_before)
                with self._lock:
                    if self._first_ns is None:
                        self._first_ns = pair.timestamp_ns
                    self._last_ns = pair.timestamp_ns
                    self._rate.append((time.monotonic(), written, self._writer.pairs))
                    while self._rate and self._rate[-1][0] - self._rate[0][0] > RATE_WINDOW_S:
                        self._rate.popleft()
                if self.config.max_pairs is not None and self._writer.pairs >= self.config.max_pairs:
                    reason = "pair limit"
                    break
        except DiskFullError as err:
            reason = f"disk full: {err}"
            self._fail(err, "stopped cleanly: disk full")
        except RecordingError as err:
            reason = f"error: {err}"
            self._fail(err, "stopped by an error")
        except BaseException as err:
            log.exception("the recorder crashed")
            reason = f"error: {err!r}"
            self._fail(RecordingError(f"{self.path}: the recorder crashed ({err!r})"), "crashed")
        finally:
            with self._lock:
                if self._state == "recording" or self._state == "finishing":
                    self._state = "stopped"
                    self._detail = None if reason == "stopped" else reason
            if self._writer is not None:
                self._writer.close(reason, dropped_pairs=self._queue.dropped)
                self._writer.discard_if_empty()
            self._done.set()

    def _create(self, pair: FramePair) -> RecordingWriter:
        metadata = build_metadata(
            self.rig,
            pair,
            producer=self._producer,
            clock_offset_ns=self._clock_offset_ns,
            camera_info=self._camera_info,
            rig_file=self._rig_file,
            calibration_file=self._calibration_file,
        )
        return RecordingWriter(
            self.path,
            metadata,
            compression=self.config.compression,
            compression_level=self.config.compression_level,
            min_free_space_mb=self.config.min_free_space_mb,
            mode=self.config.mode,
            keyframe_interval_s=self.config.keyframe_interval_s,
            window_margin_px=self.config.window_margin_px,
        )

    def _limit_reached(self, pair: FramePair) -> str | None:
        limit = self.config.max_duration_s
        if limit is not None and self._first_ns is not None and (pair.timestamp_ns - self._first_ns) / 1e9 >= limit:
            return "time limit"
        return None

    def _fail(self, err: RecordingError, what: str) -> None:
        self.error = err
        with self._lock:
            self._state = "failed"
            self._detail = f"{what}: {err}"
        if self._log_failure:
            log.error("recording %s: %s", what, err)

    # ------------------------------------------------------------------ status

    def status(self) -> RecorderStatus:
        with self._lock:
            writer = self._writer
            state = self._state
            if state == "recording" and self._closing.is_set():
                state = "finishing"
            samples = list(self._rate)
            first, last = self._first_ns, self._last_ns
            recorded = 0.0 if first is None or last is None else (last - first) / 1e9
            detail = self._detail
        rate_mb = pair_rate = 0.0
        if len(samples) >= 2 and samples[-1][0] > samples[0][0]:
            span = samples[-1][0] - samples[0][0]
            rate_mb = sum(b for _, b, _ in samples[1:]) / span / 1e6
            pair_rate = (samples[-1][2] - samples[0][2]) / span
        try:
            where = self.path if self.path.exists() else self.path.parent
            free = free_space_bytes(where) / 1e6 if where.exists() else None
        except OSError:
            free = None
        return RecorderStatus(
            state=state,
            path=str(self.path),
            pairs=writer.pairs if writer else 0,
            written_mb=round((writer.data_bytes if writer else 0) / 1e6, 3),
            write_rate_mb_s=round(rate_mb, 2),
            pair_rate_hz=round(pair_rate, 2),
            dropped_pairs=self._queue.dropped,
            queued_pairs=len(self._queue),
            recorded_s=round(recorded, 3),
            free_space_mb=None if free is None else round(free, 1),
            detail=detail,
        )
