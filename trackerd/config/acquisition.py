"""Acquisition settings: how trackerd drives the cameras and pairs their frames (trackerd/acquisition).

Placeholder models; the acquisition work fills them in.
"""

from __future__ import annotations

from trackerd.config.base import ConfigModel


class CameraAcquisition(ConfigModel):
    """Per-camera acquisition settings (the ``acquisition`` table of a ``[[cameras]]`` entry)."""


class RigAcquisition(ConfigModel):
    """Settings shared by all cameras: trigger, pairing, loss detection (the top-level ``[acquisition]`` table)."""
