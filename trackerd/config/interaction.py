"""Smoothing, events, gestures, hand poses and TUIO output (trackerd/interaction).

Placeholder model (the ``[interaction]`` table of a rig file); the interaction work fills it in.
"""

from __future__ import annotations

from trackerd.config.base import ConfigModel


class InteractionConfig(ConfigModel):
    """Smoothing, events, gestures, hand poses and TUIO output (trackerd/interaction)."""
