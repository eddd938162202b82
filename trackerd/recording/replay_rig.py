"""The rig a replay runs with: the recorded one or another, fitted to the recording's frames.

`trackerd replay`, `trackerd recording export` and the replay benchmarks run a
recording with the rig returned here, so all three see the same frames through
the same configuration.
"""

from __future__ import annotations

from typing import Any

from trackerd.config.loader import check_ready_to_track, load_rig, with_endpoints
from trackerd.config.models import RigConfig
from trackerd.config.recording import RecordingConfig
from trackerd.detect.colour import sample_grid
from trackerd.errors import CalibrationPending, ConfigError, ImageError, RecordingError
from trackerd.recording.format import METADATA_FILE
from trackerd.recording.reader import Recording


def replay_rig(recording: Recording, config: str | None, endpoints: list[str] | None) -> tuple[RigConfig, list[str]]:
    """The rig a replay runs with, and one note per thing changed from what was asked for.

    Cameras take the recording's pixel formats and sizes; recording is switched off
    (a replay must not record itself); ``endpoints`` (replay's --endpoint) replace the publishing
    endpoints.
    """
    notes: list[str] = []
    if config is None:
        rig = recording.rig()
        try:
            # A board recorded for calibration may carry a rig that cannot track (no wall yet, Mono8).
            check_ready_to_track(rig, recording.path / METADATA_FILE)
        except CalibrationPending as pending:
            raise ConfigError(
                f"{recording.path}: the recorded rig cannot track ({pending.detail}); give one that can with --config"
            ) from None
        notes.append(f"configuration: the recorded rig '{rig.name}'")
    else:
        rig = load_rig(config).config
        recorded = recording.metadata.rig.get("name", "?")
        notes.append(f"configuration: OVERRIDDEN by {config} (rig '{rig.name}'; the recording's rig was '{recorded}')")
    ids = [c.id for c in rig.cameras]
    recorded_ids = [c.id for c in recording.cameras]
    if ids[: len(recorded_ids)] != recorded_ids or len(ids) != len(recorded_ids):
        raise ConfigError(
            f"{config or recording.path}: cameras {', '.join(ids)} do not match the recording's"
            f" {', '.join(recorded_ids)} (same ids, same order)"
        )
    cameras = []
    for cam, meta in zip(rig.cameras, recording.cameras, strict=True):
        if (cam.width_px, cam.height_px) != (meta.width_px, meta.height_px):
            raise ConfigError(
                f"{config or recording.path}: camera '{cam.id}' is configured for {cam.width_px}x{cam.height_px}"
                f" but the recording's frames are {meta.width_px}x{meta.height_px}"
            )
        try:
            # The frames must show the pointer's colours whatever the rig says (recording.json edited, a
            # recording of something else): one line here, not a crashed pipeline thread per pair.
            sample_grid(meta.pixel_format, meta.width_px, meta.height_px)
        except ImageError as err:
            raise RecordingError(f"{recording.path}: camera '{cam.id}': its recorded frames' {err}") from None
        if cam.pixel_format != meta.pixel_format:
            notes.append(f"camera '{cam.id}': frames are {meta.pixel_format} (the rig says {cam.pixel_format})")
            cam = cam.model_copy(update={"pixel_format": meta.pixel_format})
        cameras.append(cam)
    update: dict[str, Any] = {"cameras": tuple(cameras)}
    if rig.recording.enabled:
        notes.append("recording on demand: switched off for the replay")
    update["recording"] = RecordingConfig()
    rig = rig.model_copy(update=update)
    return (with_endpoints(rig, endpoints) if endpoints else rig), notes
