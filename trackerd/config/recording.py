"""Recording on demand from the running daemon (trackerd/recording).

Placeholder model (the ``[recording]`` table of a rig file); the recording work fills it in.
"""

from __future__ import annotations

from trackerd.config.base import ConfigModel


class RecordingConfig(ConfigModel):
    """Recording on demand from the running daemon (trackerd/recording)."""
