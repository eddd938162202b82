"""Recording on demand from the running daemon: the ``[recording]`` table of a rig file (trackerd/recording).

Setting ``directory`` makes recording available; ``enabled`` switches it on and
off. The daemon applies a change of either on SIGHUP, between two pairs: turning
``enabled`` on starts a new recording (with the pair right after the reload,
when the locator starts afresh, so a replay reproduces the live hits), turning
it off finishes the current one. docs/recording.md describes the format and the
commands that read it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from trackerd.config.base import ConfigModel


class RecordingConfig(ConfigModel):
    """Recording on demand from the running daemon (trackerd/recording, docs/recording.md)."""

    directory: Path | None = None
    """Folder the daemon writes its recordings into (created if missing), one ``<rig>-<time>.trec``
    folder per recording. Omit to leave recording unavailable. A relative path is relative to the
    daemon's working directory; give an absolute path for a service."""
    enabled: bool = False
    """Record while true. Change it and send SIGHUP to start or stop a recording on demand."""
    mode: Literal["raw", "compressed", "windowed"] = "raw"
    """How frames are stored (docs/recording.md, "Modes"). raw: as the cameras sent them (about 4.1 MB a
    pair of two 1080p Bayer frames). compressed: lossless, zstd on each frame's difference to the
    camera's previous one (about 2x smaller on noisy sensor images; about 6 ms of CPU a pair).
    windowed: only the windows the tracker reads around both ends, over a full keyframe every
    keyframe_interval_s and whenever tracking is lost; replays to exactly the live hits, about 50 to
    70x smaller than raw, and costs a second locate per pair on the recording thread."""
    keyframe_interval_s: float = Field(default=1.0, gt=0.0)
    """compressed and windowed: the longest recorded time between two pairs stored whole (where a
    reader can start, and where damage stops spreading)."""
    window_margin_px: int = Field(default=8, ge=0, le=256)
    """windowed: pixels added on every side of the windows kept around the ends."""
    compression: Literal["none", "deflate"] = "none"
    """mode raw: how frames are stored, both lossless: none keeps the raw pixels as the camera sent them
    (of these two, the only one that keeps up with two 1080p cameras at 60 fps); deflate (zlib) costs about
    40 ms of CPU per 1080p frame and saves little on noisy sensor images (1.6x on the simulator's),
    much more on clean ones (imported or rendered images)."""
    compression_level: int = Field(default=1, ge=1, le=9)
    """zlib level for deflate: 1 fastest, 9 smallest."""
    queue_pairs: int = Field(default=32, ge=1, le=1024)
    """Pairs waiting for the writer thread. When the disk falls behind, the oldest waiting pair is
    dropped and counted (the daemon never waits for the disk); each pair of two 1080p Bayer
    frames holds about 4 MB of memory here."""
    min_free_space_mb: int = Field(default=1024, ge=0)
    """Stop recording cleanly when the disk would have less than this much free space left."""
    max_duration_s: float | None = Field(default=None, gt=0.0)
    """Finish each recording after this many seconds of recorded time; omit for no limit."""
    max_pairs: int | None = Field(default=None, gt=0)
    """Finish each recording after this many pairs; omit for no limit."""

    @model_validator(mode="after")
    def _enabled_needs_directory(self) -> RecordingConfig:
        if self.enabled and self.directory is None:
            raise ValueError("enabled = true needs a directory to write recordings into")
        return self
