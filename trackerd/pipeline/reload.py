"""A new configuration, applied in two phases between pairs.

The CLI hands over a validated rig (SIGHUP) from its own thread. The processing
thread takes it before its next pair and rebuilds what locates (the locator, and
the cameras if their settings changed; trackerd.pipeline.processing); once that
succeeded, the publishing thread takes the same rig and rebinds the publisher
if the outputs changed (trackerd.pipeline.publishing). Each thread thus changes
only what it owns, and a reload that fails keeps the previous configuration.
"""

from __future__ import annotations

import threading

from trackerd.config.models import RigConfig


class ReloadRequests:
    """The hand-over of a new rig between the CLI, the processing and the publishing thread."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pending_rig: RigConfig | None = None
        self._pending_outputs: RigConfig | None = None
        self.in_progress = False
        """The processing thread is applying a rig (the status says ``reloading``)."""

    def request(self, rig: RigConfig) -> None:
        """A new, validated configuration to apply (the latest request wins)."""
        with self._lock:
            self._pending_rig = rig

    def take_rig(self) -> RigConfig | None:
        """Processing thread: the rig to apply now, if one was requested."""
        with self._lock:
            rig, self._pending_rig = self._pending_rig, None
        return rig

    def applied(self, rig: RigConfig) -> None:
        """Processing thread: ``rig`` is in place; the publishing thread's turn."""
        with self._lock:
            self._pending_outputs = rig

    def take_outputs(self) -> RigConfig | None:
        """Publishing thread: the rig whose outputs to apply now, if one was applied."""
        with self._lock:
            rig, self._pending_outputs = self._pending_outputs, None
        return rig

    @property
    def pending(self) -> bool:
        """A requested rig that either thread has yet to take."""
        with self._lock:
            return self._pending_rig is not None or self._pending_outputs is not None


def source_settings(rig: RigConfig) -> object:
    """What a change of which requires reopening the cameras (not their calibration)."""
    cameras = tuple(c.model_copy(update={"intrinsics": None, "extrinsics": None}) for c in rig.cameras)
    return (cameras, rig.acquisition)


def changes_calibration(rig: RigConfig, old: RigConfig) -> bool:
    """A new calibration: it starts a new health record."""
    return rig.cameras != old.cameras or rig.wall != old.wall


def changes_colours(rig: RigConfig, old: RigConfig) -> bool:
    """What the colour watch compares against changed: it starts afresh."""
    return (rig.cameras, rig.pointer, rig.detector, rig.pointer_colours) != (
        old.cameras,
        old.pointer,
        old.detector,
        old.pointer_colours,
    )
