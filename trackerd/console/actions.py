"""What the console's buttons (and `trackerd ctl`) do to the running daemon, beside the snapshot:
recording on demand, a calibration check on the live pointer, and the answers to ``/healthz``."""

from __future__ import annotations

import threading
import time
from typing import Any

from trackerd.calibration.health import MIN_FIXES, CalibrationHealth
from trackerd.calibration.report import health_text
from trackerd.pipeline.tap import ConsoleTap

MIN_CHECK_FIXES = MIN_FIXES
"""A check of fewer fixes than its verdict needs (calibration.health.MIN_FIXES) could only say "undecided"."""
CHECK_MAX_FIXES = 5000
HEALTHY_STATES = ("running",)
"""States /healthz answers 200 for; starting, degraded (a camera not streaming), reloading and
stopping answer 503 so a load balancer or watchdog looks elsewhere."""


class Actions:
    """The daemon's side of the console's actions (called on the web server's thread)."""

    def __init__(self, pipeline: Any, tap: ConsoleTap, frames: Any) -> None:
        self.pipeline = pipeline
        self.tap = tap
        self.frames = frames
        self._lock = threading.Lock()
        self._check_wanted = 0
        self._check_started = 0.0
        self._check_result: dict[str, Any] | None = None

    def info(self) -> dict[str, Any]:
        """The rig as the page draws it: cameras, the wall's size, what is available."""
        rig = self.pipeline.rig
        wall = self.pipeline.locator.wall
        return {
            "rig": rig.name,
            "cameras": [
                {
                    "id": c.id,
                    "width_px": c.width_px,
                    "height_px": c.height_px,
                    "address": c.address,
                    "device_id": c.device_id,
                    "serial": c.serial,
                }
                for c in rig.cameras
            ],
            "wall": {
                "width_m": wall.width_m,
                "height_m": wall.height_m,
                "display_width_px": wall.display_width_px,
                "display_height_px": wall.display_height_px,
            },
            "recording_available": self._recording() is not None,
            "frame_rate_hz": rig.console.frame_rate_hz,
        }

    # ------------------------------------------------------------------ recording

    def _recording(self) -> Any:
        """The recording extension while the rig makes recording available (a reload may add or take
        ``[recording] directory``), else None."""
        for extension in self.pipeline.extensions:
            if extension.name == "recording" and extension.available:
                return extension
        return None

    def recording_state(self) -> dict[str, Any] | None:
        extension = self._recording()
        return None if extension is None else extension.status()

    def recording(self, action: str) -> tuple[bool, str]:
        extension = self._recording()
        if extension is None:
            return False, (
                "recording is not available: the rig in use sets no [recording] directory (docs/recording.md;"
                " a replay never records)"
            )
        return True, extension.start_now() if action == "start" else extension.stop_now()

    # ------------------------------------------------------------------ calibration check

    def start_check(self, fixes: int) -> tuple[bool, str]:
        """Begin a check over the next ``fixes`` fixes of the live pointer (as `calibrate check --live`);
        (False, why) when it cannot begin now. ValueError for a number of fixes no check takes (a bad request,
        not a conflict with the daemon's state)."""
        if not MIN_CHECK_FIXES <= fixes <= CHECK_MAX_FIXES:
            raise ValueError(f"fixes must be from {MIN_CHECK_FIXES} to {CHECK_MAX_FIXES}")
        rig = self.pipeline.rig
        if rig.pointer is None:
            return False, "the rig has no [pointer]: nothing to check with"
        with self._lock:
            if self.tap.check is not None:
                return False, "a check is already running"
            self._check_wanted = fixes
            self._check_started = time.monotonic()
            self._check_result = None
            record = CalibrationHealth.for_rig(rig, self.pipeline.locator.cameras, window=fixes)
            with self.tap.check_lock:
                self.tap.check = record
        return True, f"checking over the next {fixes} fixes: wave the pointer around in view of both cameras"

    def check_progress(self) -> dict[str, Any]:
        """The running check's progress, or the last one's result ({'state': 'none'} before any)."""
        with self._lock, self.tap.check_lock:
            record = self.tap.check
            if record is None:
                return self._check_result or {"state": "none"}
            done = record.total >= self._check_wanted
            figures = record.figures()
            progress = {
                "state": "done" if done else "running",
                "fixes": record.total,
                "wanted": self._check_wanted,
                "seconds": round(time.monotonic() - self._check_started, 1),
                "figures": figures.to_json(),
            }
            if done:
                progress["text"] = health_text(figures, record.total)
                self._check_result = progress
                self.tap.check = None
            return progress

    def cancel_check(self) -> None:
        with self._lock, self.tap.check_lock:
            self.tap.check = None

    # ------------------------------------------------------------------ health

    def health(self) -> tuple[bool, dict[str, Any]]:
        status = self.tap.status
        if status is None:
            return False, {"state": "starting", "detail": "no status yet"}
        cameras = {c.id: c.state for c in status.cameras}
        detail = {
            "state": status.state,
            "detail": status.detail,
            "cameras": cameras,
            "pair_rate_hz": status.pairing.pair_rate_hz,
            "failure": self.pipeline.failure is not None,
        }
        return status.state in HEALTHY_STATES and self.pipeline.failure is None, detail
