"""The pointer's topics, one of each per camera pair in which it is found: ``hit`` and ``pointer``."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from trackerd.publish.messages.envelope import Message

Vec3M = tuple[float, float, float]

FixStatus = Literal["hit", "off_wall", "away", "parallel"]


class HitMessage(Message):
    """Where the pointer points on the wall: one per camera pair in which it points at the wall's plane."""

    topic: Literal["hit"] = "hit"
    """Always ``hit``."""
    wall_x_m: float
    """Metres from the display's bottom-left corner, to the right along the wall."""
    wall_y_m: float
    """Metres up the wall from the display's bottom edge."""
    display_x_px: float | None = None
    """Display pixels from the left edge (origin top-left); null when the rig gives no display size."""
    display_y_px: float | None = None
    """Display pixels from the top edge (y down); null when the rig gives no display size."""
    on_wall: bool
    """True when the hit lies on the display area; false when it is on the wall's plane outside it."""
    distance_m: float
    """From the pointer's front end to the hit, along the pointer's line."""
    front_m: Vec3M
    """Centre of the pointer's front end (the end nearer the wall), world coordinates in metres."""
    back_m: Vec3M
    """Centre of the pointer's back end, world coordinates in metres."""
    ray_gap_mm: float = Field(ge=0.0)
    """How far the cameras' rays through an end miss each other (the worse end): the quality signal.
    A few mm is normal; large gaps mean a camera saw the wrong blob."""
    uncertainty_mm: float | None = Field(default=None, ge=0.0)
    """Estimated standard error of the hit on the wall (RMS radius) from centroid noise; null when
    it could not be estimated."""
    raw_wall_x_m: float | None = None
    """(1.1) With smoothing on, wall_x_m, wall_y_m, the display pixels and on_wall are smoothed
    (docs/interaction.md) and this is the unsmoothed wall x; null when smoothing is off."""
    raw_wall_y_m: float | None = None
    """(1.1) Unsmoothed wall y; null when smoothing is off."""
    raw_display_x_px: float | None = None
    """(1.1) Unsmoothed display x; null when smoothing is off or the rig gives no display size."""
    raw_display_y_px: float | None = None
    """(1.1) Unsmoothed display y; null when smoothing is off or the rig gives no display size."""
    cursor_id: int | None = Field(default=None, ge=1)
    """(1.1) The pointing session this hit belongs to (see ``enter``); null while the pointer is
    not entered on the display or pointing events are off."""


class PointerMessage(Message):
    """The pointer in 3D whenever both ends are seen and agree, even when it points away from the wall."""

    topic: Literal["pointer"] = "pointer"
    """Always ``pointer``."""
    status: FixStatus
    """hit: points at the display; off_wall: at the wall's plane outside the display; away: away
    from the wall; parallel: along the wall (within half a degree)."""
    front_colour: Literal["red", "blue"]
    """Colour of the front end (the pointing direction runs from the back end to the front end)."""
    front_m: Vec3M
    """Centre of the front end, world coordinates in metres."""
    back_m: Vec3M
    """Centre of the back end, world coordinates in metres."""
    direction: Vec3M
    """Unit vector from the back end to the front end (world frame)."""
    length_m: float = Field(ge=0.0)
    """Distance between the two end centres as triangulated."""
    front_gap_mm: float = Field(ge=0.0)
    """Ray gap at the front end (see hit.ray_gap_mm)."""
    back_gap_mm: float = Field(ge=0.0)
    """Ray gap at the back end."""
    method: Literal["planes", "points", "fit"]
    """How the line was estimated: interpretation planes, the report's two triangulated points (used
    when the planes are ill-conditioned), or (1.3) the pointer fit, both ends fitted to every camera's
    measurements of the balls' outlines with the pointer's known length (docs/geometry.md). Open: treat
    a value you do not know as one more way of estimating the same line."""
