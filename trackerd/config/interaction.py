"""The ``[interaction]`` table of a rig file: smoothing, pointing events, gestures, commands, hand poses, TUIO.

Everything here acts on the wall hits the locator produces (trackerd/interaction,
docs/interaction.md). Smoothing, enter/leave, dwell and gestures are on by
default; hand poses and the TUIO output are off until asked for. Times are
capture times of the camera pairs, so a replayed recording gives the same
events as the live run did.
"""

from __future__ import annotations

import re
from pathlib import Path

from pydantic import Field, field_validator, model_validator

from trackerd.config.base import ConfigModel

RESERVED_TRIGGERS = ("enter", "leave", "dwell", *(f"hand_{n}" for n in range(6)))
"""Trigger names of the ``commands`` table that are not gestures: pointing events and hand poses
(``hand_3``: the hand shows three extended fingers)."""

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,63}$")


class SmoothingConfig(ConfigModel):
    """The One Euro filter on wall hits (Casiez, Roussel and Vogel, CHI 2012): a low-pass filter whose
    cut-off rises with the pointer's speed, so a still pointer is steady and a moving one does not lag."""

    enabled: bool = True
    """Publish smoothed positions in ``hit`` (the raw ones go alongside, as ``raw_*``)."""
    min_cutoff_hz: float = Field(default=0.3, gt=0.0, le=100.0)
    """Cut-off frequency for a still pointer: lower is steadier, but slow drifts lag more."""
    beta_per_m: float = Field(default=15.0, ge=0.0, le=1000.0)
    """How fast the cut-off rises with speed: hertz of cut-off added per m/s of the hit's speed on
    the wall. Higher means less lag when moving."""
    derivative_cutoff_hz: float = Field(default=1.0, gt=0.0, le=100.0)
    """Cut-off frequency of the low-pass filter on the speed estimate that drives the cut-off."""
    reset_after_ms: float = Field(default=150.0, gt=0.0, le=10_000.0)
    """When no hit came for this long the pointer counts as lost and the filter starts afresh
    (no smoothing across a gap)."""


class PointingConfig(ConfigModel):
    """``enter`` and ``leave``: when the pointer starts and stops pointing at the display."""

    enabled: bool = True
    """Publish ``enter`` and ``leave`` (dwell, gestures and the TUIO cursor live between them)."""
    enter_after_ms: float = Field(default=30.0, ge=0.0, le=5_000.0)
    """The (smoothed) hit must stay on the display this long before ``enter``: one stray fix
    does not make a pointer."""
    leave_after_ms: float = Field(default=120.0, ge=0.0, le=10_000.0)
    """The hit must stay off the display (beyond the margin) or be missing this long before
    ``leave``: a dropped pair or two is not a departure."""
    edge_margin_mm: float = Field(default=25.0, ge=0.0, le=1_000.0)
    """Hysteresis at the display's edge: once entered, the hit may stray this far outside the
    display before it counts as off it, so a pointer held at the edge does not flicker."""


class DwellConfig(ConfigModel):
    """``dwell``: the select or click gesture of a pointer held still."""

    enabled: bool = True
    """Publish ``dwell``."""
    radius_mm: float = Field(default=20.0, gt=0.0, le=1_000.0)
    """The hit must stay within this distance of where the dwell began."""
    time_ms: float = Field(default=800.0, gt=0.0, le=60_000.0)
    """For this long. One event per dwell: the next needs the hit to move out of the radius first."""


class GesturesConfig(ConfigModel):
    """``gesture``: strokes of the wall hit matched against templates (swipes, circles, recorded ones)."""

    enabled: bool = True
    """Recognise gestures and publish ``gesture``."""
    template_dir: Path | None = None
    """A directory of extra templates (``NAME.json`` from ``trackerd gesture record NAME``); a
    template there replaces a built-in one of the same name. A relative path is relative to the rig file."""
    builtin: bool = True
    """Load the templates shipped with trackerd (swipes in four directions, circles both ways)."""
    only: tuple[str, ...] = ()
    """Recognise only these gestures (by name); empty: every loaded template."""
    min_score_ratio: float = Field(default=0.80, gt=0.0, lt=1.0)
    """Smallest match score (0 to 1) for a stroke to count as a gesture."""
    min_margin_ratio: float = Field(default=0.04, ge=0.0, lt=1.0)
    """The best gesture's score must beat the best other gesture's by this much; ambiguous strokes
    are no gesture."""
    start_speed_m_s: float = Field(default=0.35, gt=0.0, le=100.0)
    """A stroke begins when the (smoothed) hit moves faster than this."""
    stop_speed_m_s: float = Field(default=0.2, gt=0.0, le=100.0)
    """It ends when the hit has moved slower than this for ``pause_ms``."""
    pause_ms: float = Field(default=100.0, gt=0.0, le=5_000.0)
    """How long the hit must be slow to end a stroke."""
    min_path_m: float = Field(default=0.15, gt=0.0, le=100.0)
    """Strokes shorter than this along their path are no gesture (and not matched at all)."""
    max_stroke_ms: float = Field(default=3_000.0, gt=0.0, le=60_000.0)
    """Strokes longer than this are no gesture (the pointer is being moved about, not gesturing)."""

    @field_validator("only")
    @classmethod
    def _names(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        for name in value:
            if not _NAME.match(name):
                raise ValueError(f"'{name}' is not a gesture name (letters, digits, _ and -, from a letter)")
        return value

    @model_validator(mode="after")
    def _speeds(self) -> GesturesConfig:
        if self.stop_speed_m_s > self.start_speed_m_s:
            raise ValueError("stop_speed_m_s must not exceed start_speed_m_s")
        return self


class HandConfig(ConfigModel):
    """Hand poses (the report's section 3.9): extended fingers counted in one camera's image."""

    enabled: bool = False
    """Look for a hand and publish ``hand``; costs a pass over a half-resolution image every
    ``every_n_pairs`` pairs."""
    camera: str | None = None
    """The id of the camera to look in; default: the rig's first camera."""
    every_n_pairs: int = Field(default=4, ge=1, le=1_000)
    """Look on one pair in this many (4: 15 times a second at 60 pairs/s)."""
    hue_range_deg: tuple[float, float] = (0.0, 40.0)
    """Hue of the hand's colour, degrees on the colour wheel (0 red, 60 yellow, 120 green, 240
    blue); a range whose first value is larger wraps through red (``[340, 30]``). The default
    is skin; a coloured glove is far more reliable (docs/interaction.md)."""
    saturation_range_ratio: tuple[float, float] = (0.18, 0.75)
    """Saturation range (0 grey to 1 pure colour)."""
    min_value_ratio: float = Field(default=0.25, ge=0.0, le=1.0)
    """Smallest brightness (0 to 1) of a hand pixel."""
    background_difference_ratio: float = Field(default=0.1, ge=0.0, le=1.0)
    """A hand pixel must also differ from the learnt empty scene by this much (0 to 1 of full
    scale, largest channel): skin-coloured things that never move are not hands. 0 turns the
    background model off."""
    min_area_px: float = Field(default=1200.0, gt=0.0)
    """Smallest hand, in full-resolution pixels of area."""
    debounce_pairs: int = Field(default=3, ge=1, le=100)
    """A finger count is published only once seen on this many consecutive looks."""

    @field_validator("hue_range_deg")
    @classmethod
    def _hues(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not all(0.0 <= v <= 360.0 for v in value):
            raise ValueError("hues are degrees from 0 to 360")
        return value

    @field_validator("saturation_range_ratio")
    @classmethod
    def _saturation(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not 0.0 <= value[0] < value[1] <= 1.0:
            raise ValueError("needs 0 <= low < high <= 1")
        return value


class TuioConfig(ConfigModel):
    """TUIO 1.1 cursor output (``/tuio/2Dcur`` over OSC/UDP), for multi-touch and large-display software."""

    enabled: bool = False
    """Send the pointer as a TUIO cursor while it points at the display."""
    host: str = "127.0.0.1"
    """Where the TUIO client listens (an address or host name)."""
    port: int = Field(default=3333, ge=1, le=65535)
    """Its UDP port (3333 is TUIO's default)."""
    source: str = "trackerd"
    """Sent in the ``source`` message, so a client can tell trackerd's cursors from others."""


class InteractionConfig(ConfigModel):
    """Smoothing, events, gestures, hand poses and TUIO output (trackerd/interaction)."""

    smoothing: SmoothingConfig = SmoothingConfig()
    """Speed-adaptive smoothing of wall hits."""
    pointing: PointingConfig = PointingConfig()
    """``enter`` and ``leave`` events."""
    dwell: DwellConfig = DwellConfig()
    """``dwell`` (select) events."""
    gestures: GesturesConfig = GesturesConfig()
    """``gesture`` events from the hit's trajectory."""
    commands: dict[str, str] = Field(default_factory=dict)
    """The grammar: trigger name to command name, published as ``command`` messages. Triggers are
    gesture names (``swipe_left = "previous_slide"``), ``enter``, ``leave``, ``dwell``, and
    ``hand_0`` to ``hand_5`` (a hand showing that many fingers)."""
    hand: HandConfig = HandConfig()
    """``hand`` messages: finger counts."""
    tuio: TuioConfig = TuioConfig()
    """TUIO 1.1 cursor output."""

    @field_validator("commands")
    @classmethod
    def _commands(cls, value: dict[str, str]) -> dict[str, str]:
        for trigger, command in value.items():
            if not _NAME.match(trigger):
                raise ValueError(
                    f"'{trigger}' is not a trigger name (a gesture name, or one of {', '.join(RESERVED_TRIGGERS)})"
                )
            if not command.strip():
                raise ValueError(f"'{trigger}' maps to an empty command")
        return value

    @model_validator(mode="after")
    def _dependencies(self) -> InteractionConfig:
        if not self.pointing.enabled and (self.dwell.enabled or self.gestures.enabled or self.tuio.enabled):
            raise ValueError(
                "pointing.enabled = false also needs dwell, gestures and tuio off"
                " (they act while the pointer is on the display)"
            )
        return self

    @property
    def any_enabled(self) -> bool:
        """Whether anything here needs the interaction stage at all."""
        return (
            self.smoothing.enabled
            or self.pointing.enabled
            or self.hand.enabled
            or self.tuio.enabled
            or bool(self.commands)
        )
