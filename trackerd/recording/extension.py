"""Recording on demand from the running daemon: the pipeline extension behind the rig's ``[recording]``.

Available when ``[recording] directory`` is set; ``enabled`` switches it. The
daemon applies a changed rig file on SIGHUP, and every reload while recording
closes the current recording: each recording then holds one configuration
(the one in its metadata) and one unbroken run of the locator, which starts
afresh at a reload, so replaying it reproduces the hits the daemon published.
If the rig still says ``enabled = true``, the next recording starts with the
first pair after the reload. A recording's first pair asks every stage to start
afresh (``on_pair`` returns True; trackerd.pipeline.extensions), so the
interaction stage's smoothing and strokes begin with the recording too.

``on_pair`` only queues the pair (the writer thread does the I/O), so the
processing thread never waits for the disk; a full queue drops its oldest pair
and the drop is counted in the status message's ``recording`` object.
"""

from __future__ import annotations

import datetime as dt
import logging
import threading
from pathlib import Path
from typing import Any

from trackerd.acquisition.frame import FramePair
from trackerd.config.models import RigConfig
from trackerd.pipeline.events import NOTHING, Event, PairEvents
from trackerd.pipeline.extensions import ExtensionContext, Located
from trackerd.recording.recorder import Recorder

log = logging.getLogger(__name__)

STOP_TIMEOUT_S = 2.0


def create(rig: RigConfig, context: ExtensionContext | None = None) -> RecordingExtension | None:
    """The extension when the rig makes recording available (``[recording] directory``), else None.

    ``context`` gives the rig file and what the cameras say about themselves, for each
    recording's metadata (without it those are null there)."""
    if rig.recording.directory is None:
        return None
    return RecordingExtension(rig, context)


def recording_path(directory: Path, rig_name: str) -> Path:
    """A new ``<rig>-<local time>.trec`` folder name under ``directory`` (suffixed -2, -3... if taken)."""
    stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in rig_name) or "rig"
    path = directory / f"{safe}-{stamp}.trec"
    n = 2
    while path.exists():
        path = directory / f"{safe}-{stamp}-{n}.trec"
        n += 1
    return path


class RecordingExtension:
    """Implements trackerd.pipeline.extensions.PipelineExtension."""

    name = "recording"

    def __init__(self, rig: RigConfig, context: ExtensionContext | None = None) -> None:
        self._rig = rig
        self._context = context or ExtensionContext()
        self._armed = rig.recording.enabled
        self._recorder: Recorder | None = None
        """The recording being written; one that ended by itself (a limit, a full disk) is dropped from
        here by the next pair or console request (:meth:`_writing`), and stays ``_last``."""
        self._finishing: list[Recorder] = []
        self._last: Recorder | None = None
        self._failure: str | None = None
        """Why the last recording could not be started (its folder could not be made), until one starts."""
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ processing thread

    def on_pair(self, pair: FramePair) -> bool:
        """Queue the pair for the current recording; True when a recording starts with it."""
        recorder = self._recorder
        if recorder is not None and not recorder.done:
            recorder.put(pair)
            return False
        if recorder is not None:
            with self._lock:
                self._writing()
        if not self._armed or not self.available:
            return False
        self._armed = False
        recorder = self._start()
        if recorder is None:
            return False
        recorder.put(pair)
        return True

    def reset(self) -> None:
        """Nothing carried over between pairs but the recording itself, which goes on."""

    def finish(self) -> list[Event]:
        return []

    def on_quiet(self, now_ns: int) -> list[Event]:
        """Nothing: the recording goes on with the next pair."""
        return []

    def on_located(self, located: Located) -> PairEvents:
        """Nothing to add: the pair was queued before the locator."""
        return NOTHING

    def reload(self, rig: RigConfig) -> None:
        """A reload closes the current recording (without waiting); enabled starts the next one."""
        with self._lock:
            recorder = self._writing()
            if recorder is not None:
                log.info("recording: closing %s (configuration reloaded)", recorder.path)
                recorder.finish()
                self._finishing.append(recorder)
                self._recorder = None
            self._rig = rig
            self._armed = rig.recording.enabled and rig.recording.directory is not None
            self._failure = None  # a new configuration: its own start says whether it fails

    # ------------------------------------------------------------------ the console (any thread)

    @property
    def available(self) -> bool:
        return self._rig.recording.directory is not None

    def start_now(self) -> str:
        """Start a recording with the next pair (as a reload with ``enabled`` does); what happens, in words."""
        with self._lock:
            if not self.available:  # a reload took the directory away since the console looked
                return "recording is not available: the rig sets no [recording] directory"
            recorder = self._writing()
            if recorder is not None:
                return f"already recording into {recorder.path}"
            self._armed = True
            failure = self._failure
        if failure is not None:
            return f"a recording is tried again with the next pair (the last one failed: {failure})"
        return "a recording starts with the next pair"

    def stop_now(self) -> str:
        """Finish the current recording (without waiting for the disk); what happens, in words."""
        with self._lock:
            self._armed = False
            recorder, self._recorder = self._writing(), None
            if recorder is None:
                return "not recording"
            recorder.finish()
            self._finishing.append(recorder)
        log.info("recording: finishing %s (asked from the console)", recorder.path)
        return f"finishing {recorder.path}"

    def _writing(self) -> Recorder | None:
        """The recording being written, or None; one that has ended by itself (at a limit, on a full disk) is
        let go here, kept as the last one for the status. Called with the lock held."""
        recorder = self._recorder
        if recorder is not None and recorder.done:
            self._recorder = recorder = None
        return recorder

    def _start(self) -> Recorder | None:
        cfg = self._rig.recording
        assert cfg.directory is not None
        try:
            cfg.directory.mkdir(parents=True, exist_ok=True)
            path = recording_path(cfg.directory, self._rig.name)
        except OSError as err:
            failure = f"cannot create {cfg.directory}: {err.strerror}"
            log.error("recording: %s", failure)
            with self._lock:
                self._failure = failure
            return None
        recorder = Recorder(
            path,
            self._rig,
            producer="trackerd run (recording on demand)",
            config=cfg,
            camera_info=self._context.camera_info,
            rig_file=self._context.rig_file,
            clock_offset_ns=self._context.clock_offset_ns,
        ).start()
        log.info("recording: started %s", path)
        with self._lock:
            self._recorder = recorder
            self._last = recorder
            self._failure = None
        return recorder

    # ------------------------------------------------------------------ publishing thread

    def status(self) -> dict[str, Any] | None:
        """The status message's ``recording`` object; None once a reload has taken ``directory`` away (and
        the recording it closed is written)."""
        with self._lock:
            if not self.available and not any(not r.done for r in self._finishing):
                return None
            recorder = self._recorder or self._last
            armed = self._armed
            failure = self._failure
            self._finishing = [r for r in self._finishing if not r.done]
        if failure is not None:
            # The last start failed: that, not the recording before it, is what the operator must see.
            detail = "; ".join(filter(None, [failure, "tried again with the next pair" if armed else None]))
            return {"state": "failed", "path": None, "detail": detail}
        if recorder is None:
            detail = "starts with the next pair" if armed else "enabled = false"
            return {"state": "idle", "detail": detail}
        figures = recorder.status().to_dict()
        if armed:
            upcoming = "the next recording starts with the next pair"
            figures["detail"] = "; ".join(filter(None, [figures["detail"], upcoming]))
        return figures

    # ------------------------------------------------------------------ stop

    def close(self) -> None:
        with self._lock:
            recorders = [*self._finishing, *([self._recorder] if self._recorder else [])]
            self._recorder = None
            self._finishing = []
        for recorder in recorders:
            if not recorder.stop(STOP_TIMEOUT_S):
                log.warning("recording: %s is still being written after %.0f s", recorder.path, STOP_TIMEOUT_S)
