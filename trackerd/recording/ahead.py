"""Locating ahead: a replay at max speed locates its pairs in a worker process beside the pipeline.

A replay as fast as possible is bound by the interpreter lock, not by the cores:
reading a pair, locating the pointer in it, the extensions, the wire messages
and publishing are each a few tenths of a millisecond of Python, and the
pipeline's threads take turns at one interpreter (docs/recording.md, "Replay
speed"). Here a second interpreter reads the recording and runs the locator over
every pair, in order, and sends the fixes; the replay's source hands the
pipeline each pair with its fix (``FramePair.located``), and the pipeline
publishes it without locating again. The frames' pixels are not sent: each frame
is read from the recording again only if something in the pipeline looks at it
(the colour watch, the console's frames, hand poses), so a pair that nobody
looks at costs the pipeline its header alone.

The published hits are the same as locating in the pipeline: the worker's locator
is built from the same rig, sees the same pairs in the same order (damaged pairs
skipped on both sides, as the same checksums say), and is reset where the
processing stage resets its own, at the first pair of every pass after the first
and after every pair where the pointer was not found. A replay reloads no
configuration and records nothing, so nothing else resets the pipeline's
locator (trackerd.recording.replay_rig).
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
import traceback
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackerd.acquisition.frame import Frame, FramePair
from trackerd.config.models import RigConfig
from trackerd.errors import RecordingError
from trackerd.locator import Locator, PointerFix
from trackerd.recording.format import RecordHeader
from trackerd.recording.reader import Recording

SEND_PAIRS = 8
"""The worker sends fixes this many at a time: one pickle and one pipe write per batch. The pipe's
buffer (64 KiB on Linux, fixes of 1-2 kB) then holds a few batches, which is how far ahead the
worker runs before it waits for the pipeline."""
POLL_S = 0.1
"""How often the receiving side checks whether the replay was stopped while it waits for fixes."""
JOIN_S = 2.0


@dataclass(frozen=True, slots=True)
class WorkerResult:
    """What the worker says about one pair: its fix, or why the pair was skipped (a damaged frame)."""

    index: int
    loop_pass: int
    fix: PointerFix | None
    damaged: str | None


class WorkerFailed(RuntimeError):
    """The worker process stopped before the end of the replay (its traceback, or how it died)."""


def _work(
    connection: Connection, path: str, rig: RigConfig, first: int, stop_at: int, passes: int | None, verify: bool
) -> None:
    """The worker's loop: every pair of ``first``..``stop_at`` (pass after pass) located in order."""
    from trackerd.recording.replay import THREADED_DECODE_MODES

    recording = Recording.open(path)
    locator = Locator(rig)
    # As the replay's reader thread does in these modes: each camera's frame on a thread of its own.
    threads = len(recording.cameras) - 1 if recording.metadata.mode in THREADED_DECODE_MODES else 0
    with ThreadPoolExecutor(threads) if threads else contextlib.nullcontext() as pool:
        _locate_all(connection, recording, locator, first, stop_at, passes, verify, pool)


def _locate_all(
    connection: Connection,
    recording: Recording,
    locator: Locator,
    first: int,
    stop_at: int,
    passes: int | None,
    verify: bool,
    pool: ThreadPoolExecutor | None,
) -> None:
    batch: list[WorkerResult] = []
    loop_pass, located_pass = 0, 0
    while True:
        for index in range(first, stop_at):
            try:
                images = recording.images(index, recording.header(index), verify=verify, pool=pool)
            except RecordingError as err:
                batch.append(WorkerResult(index, loop_pass, None, str(err)))
            else:
                if loop_pass > located_pass:
                    # The source marks this pair fresh_start; the processing stage resets its locator.
                    located_pass = loop_pass
                    locator.reset()
                fix = locator.locate(images)
                batch.append(WorkerResult(index, loop_pass, fix, None))
            if len(batch) >= SEND_PAIRS or index == stop_at - 1:
                connection.send(batch)
                batch = []
        if passes is not None and loop_pass >= passes - 1:
            break
        loop_pass += 1
    connection.send(None)


def worker_main(parameters_fd: int, results_fd: int) -> None:
    """The worker process's entry (``python -c``, see :class:`LocateAhead`): its parameters from one
    pipe, its results to the other."""
    # Its own session: a Ctrl-C at the terminal is the replay's to handle, which stops the worker.
    results = Connection(results_fd, readable=False)
    try:
        with Connection(parameters_fd, writable=False) as parameters:
            path, rig, first, stop_at, passes, verify = parameters.recv()
        _work(results, path, rig, first, stop_at, passes, verify)
    except (BrokenPipeError, EOFError):
        pass  # the replay is gone or stopped: nothing to tell
    except BaseException:  # noqa: BLE001 - the replay reports it, with the worker's traceback
        with contextlib.suppress(OSError):
            results.send(traceback.format_exc())
    finally:
        results.close()


class LocateAhead:
    """The worker process and the receiving end of its fixes; one per start of a replay."""

    def __init__(
        self, recording: Recording, rig: RigConfig, first: int, stop_at: int, passes: int | None, verify: bool
    ) -> None:
        # A new interpreter, not a fork: the replay's process already runs threads (ZeroMQ's, the
        # pipeline's) and a fork copies their locks in whatever state they are; and not
        # multiprocessing's spawn, which runs the parent's main script again in the child.
        parameters_read, parameters_write = os.pipe()
        results_read, results_write = os.pipe()
        # The worker imports this trackerd, however the replay's process found it: the folder holding
        # the package goes first on its path unless its path has it already (an installed trackerd's
        # site-packages stays where it is, behind the standard library).
        package_root = str(Path(__file__).resolve().parents[2])
        try:
            self._process = subprocess.Popen(
                [
                    sys.executable,
                    "-c",
                    "import sys; root = sys.argv[3]; root in sys.path or sys.path.insert(0, root);"
                    " from trackerd.recording.ahead import worker_main;"
                    " worker_main(int(sys.argv[1]), int(sys.argv[2]))",
                    str(parameters_read),
                    str(results_write),
                    package_root,
                ],
                pass_fds=(parameters_read, results_write),
                stdin=subprocess.DEVNULL,
                start_new_session=True,
            )
        finally:
            os.close(parameters_read)
            os.close(results_write)
        self._connection = Connection(results_read, writable=False)
        with Connection(parameters_write, readable=False) as parameters:
            parameters.send((str(recording.path), rig, first, stop_at, passes, verify))

    def results(self, halt: threading.Event) -> Iterator[WorkerResult]:
        """The worker's results in order until its last pair (WorkerFailed if it stops before);
        returns early once ``halt`` is set."""
        while not halt.is_set():
            if not self._connection.poll(POLL_S):
                continue
            try:
                message: Any = self._connection.recv()
            except (EOFError, OSError) as err:
                how = self._how_it_ended(err)
                raise WorkerFailed(f"the replay's locating process ended unexpectedly ({how})") from err
            if message is None:
                return
            if isinstance(message, str):
                raise WorkerFailed(f"the replay's locating process failed:\n{message}")
            yield from message

    def _how_it_ended(self, err: BaseException) -> str:
        try:
            code = self._process.wait(JOIN_S)
        except subprocess.TimeoutExpired:
            return type(err).__name__
        return f"killed by signal {-code}" if code < 0 else f"exit status {code}"

    def stop(self) -> None:
        """Ends the worker (wherever it is) and closes the pipe."""
        if self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(JOIN_S)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()
        self._connection.close()


class _PairPixels:
    """One pair's frames, read from the recording the first time any of them is looked at."""

    __slots__ = ("_header", "_images", "_index", "_lock", "_recording", "_verify")

    def __init__(self, recording: Recording, index: int, header: RecordHeader, verify: bool) -> None:
        self._recording, self._index, self._header, self._verify = recording, index, header, verify
        self._images: list[NDArray[np.uint8]] | None = None
        self._lock = threading.Lock()

    def image(self, k: int) -> NDArray[np.uint8]:
        with self._lock:  # the processing thread and a recorder or look thread may ask at once
            if self._images is None:
                self._images = self._recording.images(self._index, self._header, verify=self._verify)
            return self._images[k]


class LazyFrame(Frame):
    """A Frame whose pixels are read from the recording when first looked at (see the module's docstring)."""

    def __init__(
        self,
        camera_id: str,
        frame_id: int,
        device_timestamp_ns: int,
        host_timestamp_ns: int,
        pixel_format: str,
        pixels: _PairPixels,
        k: int,
    ) -> None:
        # Frame is frozen: its fields are set as its own generated __init__ sets them.
        for name, value in (
            ("camera_id", camera_id),
            ("frame_id", frame_id),
            ("device_timestamp_ns", device_timestamp_ns),
            ("host_timestamp_ns", host_timestamp_ns),
            ("pixel_format", pixel_format),
        ):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_pixels", pixels)
        object.__setattr__(self, "_k", k)

    @property  # read-only here: the pixels come from the recording
    def image(self) -> NDArray[np.uint8]:
        pixels: _PairPixels = self.__dict__["_pixels"]
        return pixels.image(self.__dict__["_k"])


def located_pair(
    recording: Recording,
    index: int,
    header: RecordHeader,
    fix: PointerFix,
    *,
    verify: bool,
    shift_ns: int,
    host_ns: int,
    sequence: int,
) -> FramePair:
    """The pair of record ``index`` as :func:`trackerd.recording.reader.make_pair` makes it, with ``fix``
    as its ``located`` and frames that read their pixels only when looked at."""
    pixels = _PairPixels(recording, index, header, verify)
    frames = tuple(
        LazyFrame(cam.id, entry.frame_id, entry.device_timestamp_ns, host_ns, cam.pixel_format, pixels, k)
        for k, (cam, entry) in enumerate(zip(recording.cameras, header.frames, strict=True))
    )
    return FramePair(frames, header.timestamp_ns + shift_ns, header.skew_ns, sequence, located=fix)
