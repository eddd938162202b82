"""Shared pieces for the interaction tests: the simulated wall's size and the engine run over a track."""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.config.interaction import InteractionConfig
from trackerd.interaction.engine import Event, InteractionEngine
from trackerd.interaction.scripted import Track
from trackerd.interaction.templates import load_templates

WIDTH_M = 3.6576
HEIGHT_M = 0.9144


def run_track(
    track: Track, config: InteractionConfig | None = None, templates=None
) -> tuple[InteractionEngine, list[Event]]:
    """Feed a whole track to a fresh engine; every event, in order."""
    engine = InteractionEngine(
        config or InteractionConfig(), WIDTH_M, HEIGHT_M, load_templates() if templates is None else templates
    )
    events: list[Event] = []
    for time_ns, point in zip(track.times_ns, track.points_m, strict=True):
        events += engine.step(int(time_ns), None if np.isnan(point[0]) else point).events
    return engine, events


@pytest.fixture(scope="session")
def templates():
    return load_templates()
