"""The few exceptions trackerd raises on purpose.

Each one carries a message meant for an operator: one line that says what is
wrong and where. The CLI prints it and exits with the error's ``exit_code``;
anything else that escapes is a bug and exits non-zero with a traceback.
"""

from __future__ import annotations


class TrackerdError(Exception):
    """Base class: a problem the user can act on, reported without a traceback."""

    exit_code = 1


class ConfigError(TrackerdError):
    """A rig or calibration file that cannot be read or does not validate."""

    exit_code = 2

    def in_file(self, path: object) -> ConfigError:
        """This error with the file it is about in front, as the loader's own errors have it (itself
        if it names that file first already)."""
        text = str(self)
        return self if text.startswith(str(path)) else ConfigError(f"{path}: {text}")


class CalibrationPending(ConfigError):
    """A valid rig that cannot track yet: a calibration step is still to run, or its cameras are
    monochrome (a rig used only to calibrate). `trackerd config check` reports it and passes; the
    tracking commands refuse to start with it. ``detail`` is the message without the file."""

    def __init__(self, where: object, detail: str) -> None:
        super().__init__(f"{where}: {detail}")
        self.detail = detail


class GeometryError(TrackerdError):
    """A geometric configuration that has no answer (parallel rays, a line parallel to the wall)."""


class ImageError(TrackerdError):
    """An image file that cannot be read or does not match the camera it is said to come from."""


class CameraError(TrackerdError):
    """A camera that cannot be found, opened, configured or kept streaming."""


class CalibrationError(TrackerdError):
    """Calibration input that cannot give a result: no board found, too few views, pairs out of sync."""


class RecordingError(TrackerdError):
    """A recording that cannot be written or read (corrupt, truncated, wrong version, disk full)."""
